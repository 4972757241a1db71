"""Install ibvs_testing as an ament_python package (a test dependency of the others)."""

from setuptools import find_packages, setup

package_name = 'ibvs_testing'

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
    description='Test-only helpers of the IBVS packages: a ROS domain per test process, '
                'rclpy contexts and executors, /proc inspection.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
        ],
    },
)
