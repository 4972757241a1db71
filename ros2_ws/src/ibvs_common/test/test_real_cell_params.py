"""The real cell's shared parameters, without rclpy: joints, modes, hand-eye camera pose."""

from ibvs_common.params import check_declared, check_retired, ParameterError, RETIRED
from ibvs_common.shared_params import camera_pose_from, JOINTS, lockstep
import numpy as np
import pytest


def test_joints_is_an_array_of_six_strings():
    assert JOINTS.check(['a'] * 6) == ['a'] * 6
    for bad, why in ((['a'] * 5, 'has 5 values'), ([1.0] * 6, 'not an array of strings'),
                     ('joint_1', 'not an array of strings')):
        with pytest.raises(ParameterError, match=f"parameter 'joints'.*{why}"):
            JOINTS.check(bad)
    assert JOINTS.allowed() == '6 strings'


@pytest.mark.parametrize('values, runs_in_lockstep', [
    ({}, True), ({'command_interface': 'effort'}, True),
    ({'command_interface': 'position'}, False)])
def test_the_time_mode_follows_from_the_command_interface(values, runs_in_lockstep):
    assert lockstep(values) is runs_in_lockstep


@pytest.mark.parametrize('name, replacement', [
    ('lockstep', "the time mode follows from command_interface ('effort': lockstep, "
                 "'position': free-running)"),
    ('renderer', 'the simulator renders with OpenGL (ibvs_sim.gl_renderer)')])
def test_a_retired_parameter_is_refused_naming_what_replaces_it(name, replacement):
    message = f"parameter '{name}' is retired: {replacement}"
    assert RETIRED[name] == replacement
    with pytest.raises(ParameterError) as info:
        check_retired(['command_interface', name])
    assert str(info.value) == message and info.value.param == name
    with pytest.raises(ParameterError) as info:  # before 'no node declares it'
        check_declared([name], ['command_interface'], '-p')
    assert str(info.value) == f'-p: {message}'
    check_retired(['command_interface', 'lockstepp'])


def test_camera_pose_parameter_is_a_hand_eye_result_or_unset():
    assert camera_pose_from({}) is None
    assert camera_pose_from({'camera_pose': [0.0] * 7}) is None
    half = np.sqrt(0.5)
    tf = camera_pose_from({'camera_pose': [1.0, 2.0, 3.0, 0.0, 0.0, half, half]})
    np.testing.assert_allclose(tf[:3, 3], [1.0, 2.0, 3.0])
    np.testing.assert_allclose(tf[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
    with pytest.raises(ParameterError, match="parameter 'camera_pose'.*length"):
        camera_pose_from({'camera_pose': [1.0, 2.0, 3.0, 0.0, 0.0, 0.5, 0.5]})
