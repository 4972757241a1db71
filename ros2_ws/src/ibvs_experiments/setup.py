"""Install ibvs_experiments as an ament_python package (found by ament_index and ros2 run)."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'ibvs_experiments'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/studies', glob('studies/*.yaml')),
        ('share/' + package_name + '/benchmarks', glob('benchmarks/*.json')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='IBVS stack maintainers',
    maintainer_email='maintainers@ibvs-stack.dev',
    description='Runner, studies, report, benchmarks, cell, teach, calibrate and the ibvs CLI.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'ibvs = ibvs_experiments.cli:main',
        ],
    },
)
