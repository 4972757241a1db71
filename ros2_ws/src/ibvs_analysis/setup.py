"""Install ibvs_analysis as an ament_python package (found by ament_index and ros2 run)."""

from setuptools import find_packages, setup

package_name = 'ibvs_analysis'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='IBVS stack maintainers',
    maintainer_email='maintainers@ibvs-stack.dev',
    description="What a run's bag says: metrics, success, figures, the film, the results.",
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
)
