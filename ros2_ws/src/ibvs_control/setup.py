"""Install ibvs_control as an ament_python package (found by ament_index and ros2 run)."""

from setuptools import find_packages, setup

package_name = 'ibvs_control'

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
    description='Inner joint loop, feedforward and adaptive Youla feedback controllers.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'joint_controller_node = ibvs_control.joint_controller_node:main',
            'feedforward_node = ibvs_control.feedforward_node:main',
            'adaptive_feedback_node = ibvs_control.adaptive_feedback_node:main',
        ],
    },
)
