"""
The arm's joint_limits file is the one source of its limits for every part that moves it.

The joint controller's shaper (position interface), the simulated EGM drive and the model
loop's joint loop take their speed, acceleration and jerk limits, and the shaper its joint
ranges, from ``ibvs_model.joint_limits.IRB4600_60_205``; the file is installed in share/ for
a MoveIt config or a controller's parameters to load.
"""

from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from ibvs_control.closed_loop import LoopConfig, simulate
from ibvs_control.position_interface import PositionShaper
from ibvs_model.joint_limits import FILE, IRB4600_60_205 as LIMITS
from ibvs_sim.position_servo import PositionServo
import numpy as np


def test_the_shaper_and_the_simulated_drive_take_the_files_limits():
    shaper = PositionShaper(250.0)
    np.testing.assert_array_equal(shaper.speed_limits, LIMITS.max_velocity)
    np.testing.assert_array_equal(shaper.acceleration_limits, LIMITS.max_acceleration)
    np.testing.assert_array_equal(shaper.jerk_limits, LIMITS.max_jerk)
    np.testing.assert_array_equal(shaper.low - 0.02, LIMITS.min_position)
    np.testing.assert_array_equal(shaper.high + 0.02, LIMITS.max_position)
    servo = PositionServo(1e-3, np.zeros(6))
    np.testing.assert_array_equal(servo.v_max, LIMITS.max_velocity)
    np.testing.assert_array_equal(servo.a_max, LIMITS.max_acceleration)


def test_the_model_loops_joint_speeds_are_the_files():
    run = simulate(LoopConfig(scenario=1), duration_s=0.05)
    np.testing.assert_array_equal(run.model.params.qd_max, LIMITS.max_velocity)


def test_the_file_is_installed_for_moveit_and_ros2_control():
    installed = (Path(get_package_share_directory('ibvs_model')) / 'config'
                 / 'irb4600_60_205_joint_limits.yaml')
    assert installed.read_text() == FILE.read_text()
