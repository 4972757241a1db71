"""Install ibvs_sim as an ament_python package (found by ament_index and ros2 run)."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'ibvs_sim'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/urdf', glob('urdf/*')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='IBVS stack maintainers',
    maintainer_email='maintainers@ibvs-stack.dev',
    description='PyBullet simulator node of the IRB 4600 and the ZED 2.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'sim_node = ibvs_sim.sim_node:main',
            'robot_state_node = ibvs_sim.robot_state_node:main',
        ],
    },
)
