"""The real cell's shared parameters, without rclpy: joints, modes, hand-eye camera pose."""

from ibvs_common.params import ParameterError
from ibvs_common.shared_params import (camera_pose_from, check_command_interface, JOINTS)
import numpy as np
import pytest


def test_joints_is_an_array_of_six_strings():
    assert JOINTS.check(['a'] * 6) == ['a'] * 6
    for bad, why in ((['a'] * 5, 'has 5 values'), ([1.0] * 6, 'not an array of strings'),
                     ('joint_1', 'not an array of strings')):
        with pytest.raises(ParameterError, match=f"parameter 'joints'.*{why}"):
            JOINTS.check(bad)
    assert JOINTS.allowed() == '6 strings'


@pytest.mark.parametrize('interface, lockstep, ok', [
    ('effort', True, True), ('position', False, True),
    ('effort', False, False), ('position', True, False)])
def test_command_interface_and_lockstep_go_together(interface, lockstep, ok):
    values = {'command_interface': interface, 'lockstep': lockstep}
    if ok:
        check_command_interface(values)
    else:
        with pytest.raises(ParameterError, match="parameter 'lockstep'"):
            check_command_interface(values)


def test_camera_pose_parameter_is_a_hand_eye_result_or_unset():
    assert camera_pose_from({}) is None
    assert camera_pose_from({'camera_pose': [0.0] * 7}) is None
    half = np.sqrt(0.5)
    tf = camera_pose_from({'camera_pose': [1.0, 2.0, 3.0, 0.0, 0.0, half, half]})
    np.testing.assert_allclose(tf[:3, 3], [1.0, 2.0, 3.0])
    np.testing.assert_allclose(tf[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
    with pytest.raises(ParameterError, match="parameter 'camera_pose'.*length"):
        camera_pose_from({'camera_pose': [1.0, 2.0, 3.0, 0.0, 0.0, 0.5, 0.5]})
