#!/bin/bash
# Source ROS 2 Jazzy and the workspace, then run the command (ros2 run ..., colcon test, bash).
set -e
source /opt/ros/jazzy/setup.bash
source /ws/install/setup.bash
exec "$@"
