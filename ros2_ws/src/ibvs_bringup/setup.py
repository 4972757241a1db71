"""Install ibvs_bringup as an ament_python package (found by ament_index and ros2 run)."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'ibvs_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='IBVS stack maintainers',
    maintainer_email='maintainers@ibvs-stack.dev',
    description='Scenarios, the graph, compose, process supervision, recorder, domains.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'compose = ibvs_bringup.compose:main',
        ],
    },
)
