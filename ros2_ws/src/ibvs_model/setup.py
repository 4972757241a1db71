"""Install ibvs_model as an ament_python package (found by ament_index and ros2 run)."""

from setuptools import find_packages, setup

package_name = 'ibvs_model'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    # The arm's joint_limits file: read by the package (ibvs_model.joint_limits), and in
    # share/ for a MoveIt config or a controller's parameters to load.
    package_data={package_name: ['data/*.yaml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config',
         ['ibvs_model/data/irb4600_60_205_joint_limits.yaml']),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='IBVS stack maintainers',
    maintainer_email='maintainers@ibvs-stack.dev',
    description='IRB 4600 and ZED 2 model: kinematics, stereo camera, camera-and-robot model.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
        ],
    },
)
