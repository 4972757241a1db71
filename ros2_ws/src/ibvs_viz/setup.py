"""Install ibvs_viz as an ament_python package (found by ament_index and ros2 run)."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'ibvs_viz'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config',
         sorted(glob('config/*.json') + glob('config/*.rviz'))),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='IBVS stack maintainers',
    maintainer_email='maintainers@ibvs-stack.dev',
    description='What RViz and Foxglove show: robot description, tf, markers; the video.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'viz_node = ibvs_viz.viz_node:main',
        ],
    },
)
