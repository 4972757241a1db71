"""The arm's joint_limits file (ibvs_model.joint_limits): its sources, and refusals."""

from ibvs_model import IRB4600
from ibvs_model.drive import JERK_RISE_S
from ibvs_model.joint_limits import IRB4600_60_205, JOINTS, load
import numpy as np
import pytest
import yaml

#: abb_ros2's IRB 4600-60/2.05 (robot_specific_config/abb_irb4600_support/urdf/
#: irb4600_60_205_macro.xacro L113-148 at 0705714): <limit lower upper velocity> per joint.
ABB_ROS2 = {'joint_1': (-3.141, 3.141, 3.054), 'joint_2': (-1.570, 2.617, 3.054),
            'joint_3': (-3.141, 1.308, 3.054), 'joint_4': (-6.981, 6.981, 4.363),
            'joint_5': (-2.181, 2.094, 4.363), 'joint_6': (-6.981, 6.981, 6.283)}


def test_ranges_and_speeds_are_abb_ros2s_to_its_three_decimals():
    limits = IRB4600_60_205
    assert limits.joints == tuple(ABB_ROS2)
    for j, (lower, upper, velocity) in enumerate(ABB_ROS2.values()):
        # the xacro cuts the specification's values after three decimals
        for ours, theirs in ((limits.min_position[j], lower),
                             (limits.max_position[j], upper),
                             (limits.max_velocity[j], velocity)):
            assert abs(ours) >= abs(theirs) and abs(ours - theirs) < 1e-3


def test_the_model_of_the_arm_takes_the_files_ranges_and_speeds():
    assert IRB4600.q_min == IRB4600_60_205.min_position
    assert IRB4600.q_max == IRB4600_60_205.max_position
    assert IRB4600.qd_max == IRB4600_60_205.max_velocity
    # the specification in degrees (the paper's Table 2)
    np.testing.assert_allclose(np.degrees(IRB4600.qd_max), [175, 175, 175, 250, 250, 360])


def test_every_jerk_is_its_acceleration_over_the_rise_time():
    np.testing.assert_allclose(np.array(IRB4600_60_205.max_acceleration) / JERK_RISE_S,
                               IRB4600_60_205.max_jerk, rtol=1e-15)


def write(tmp_path, table):
    path = tmp_path / 'limits.yaml'
    path.write_text(yaml.safe_dump({'joint_limits': table}))
    return path


def full():
    return {name: {'has_position_limits': True, 'min_position': -1.0, 'max_position': 1.0,
                   'has_velocity_limits': True, 'max_velocity': 2.0,
                   'has_acceleration_limits': True, 'max_acceleration': 3.0,
                   'has_jerk_limits': True, 'max_jerk': 30.0} for name in JOINTS}


def test_a_complete_file_is_read_in_the_joints_order(tmp_path):
    table = full()
    table['joint_3']['max_velocity'] = 5
    limits = load(write(tmp_path, table))
    assert limits.max_velocity == (2.0, 2.0, 5.0, 2.0, 2.0, 2.0)
    assert load(write(tmp_path, table), joints=('joint_3',)).max_velocity == (5.0,)


@pytest.mark.parametrize('joint, key, value, words', [
    ('joint_2', None, None, 'no joint_limits.joint_2'),
    ('joint_4', 'has_jerk_limits', False, 'joint_4.has_jerk_limits must be true'),
    ('joint_1', 'max_acceleration', None, 'joint_1.max_acceleration must be a finite'),
    ('joint_1', 'max_velocity', float('nan'), 'joint_1.max_velocity must be a finite'),
    ('joint_6', 'max_velocity', True, 'joint_6.max_velocity must be a finite'),
    ('joint_5', 'max_jerk', 0.0, 'joint_5.max_jerk must be > 0'),
    ('joint_3', 'min_position', 2.0, 'joint_3.min_position must be below'),
])
def test_an_incomplete_or_impossible_file_is_refused_naming_joint_and_key(
        tmp_path, joint, key, value, words):
    table = full()
    if key is None:
        del table[joint]
    elif value is None:
        del table[joint][key]
    else:
        table[joint][key] = value
    with pytest.raises(ValueError, match=words):
        load(write(tmp_path, table))
    path = tmp_path / 'other.yaml'
    path.write_text('joints: {}\n')
    with pytest.raises(ValueError, match='no joint_limits mapping'):
        load(path)
