"""
sim_node: one class per time mode, picked from a typed config checked before any topic.

:class:`ibvs_sim.node_params.SimNodeConfig` is pure Python: its rules across parameters
are checked without a node. The node starts the class of the time mode that its
``command_interface`` gives and opens the command topic of that mode only; ``lockstep`` and
``renderer`` are retired, refused at start.
"""

from ibvs_common import contract
from ibvs_common.kit import opened, SUBSCRIBES
from ibvs_common.params import ParameterError
from ibvs_sim.free_running_sim import FreeRunningSim
from ibvs_sim.lockstep_sim import LockstepSim
from ibvs_sim.node_params import SimNodeConfig
from ibvs_sim.sim_node import PARAMS, SimNode
import pytest
from rclpy.parameter import Parameter

FREE = {'command_interface': 'position'}
LIGHT = [Parameter('publish_images', value=False), Parameter('resolution', value='VGA')]


def test_config_checks_the_rules_across_parameters():
    assert [p.name for p in PARAMS] == [p.name for p in SimNodeConfig.params()]
    assert SimNodeConfig.make(**FREE).interface.lockstep is False
    assert SimNodeConfig.make().interface.lockstep is True
    assert not {'lockstep', 'renderer'} & {p.name for p in PARAMS}
    for params, match in (
            ({'target_features_source': 'taught', 'publish_images': False},
             "'target_features_source' = 'taught' is invalid"),
            ({'camera_outage_s': [1.0, 0.5]},
             "'camera_outage_s' = \\[1.0, 0.5\\] is invalid in lockstep"),
            ({'extra_joints': ['track', 'track']}, "'extra_joints'"),
            ({'extra_joints': ['joint_2']}, "'extra_joints'"),
            ({'clock_rate_hz': 0.0}, "'clock_rate_hz'"),
            ({'image_stamp_offset_s': 0.01}, "'image_stamp_offset_s' = 0.01 is invalid in "
             'lockstep'),
            ({**FREE, 'image_stamp_offset_s': 0.05, 'feedback_latency_s': 0.04},
             "'image_stamp_offset_s' = 0.05 is invalid with feedback_latency_s"),
            # Free-running only, checked before any node starts (ibvs run's configs):
            ({**FREE, 'joints': ['joint_1'] * 6}, "'joints'")):
        with pytest.raises(ParameterError, match=match):
            SimNodeConfig.make(**params)
    assert SimNodeConfig.make(camera_outage_s=[1.0, 0.5], **FREE).camera_outage_s == (1.0, 0.5)
    assert SimNodeConfig.make(image_stamp_offset_s=-0.02, **FREE).image_stamp_offset_s == -0.02
    assert SimNodeConfig.make(joint_state_rate_hz=100.0).off_default(
        ('joint_state_rate_hz', 'real_time_factor')) == [('joint_state_rate_hz', 100.0)]


@pytest.mark.parametrize('name, value, replacement', [
    ('lockstep', False, 'the time mode follows from command_interface'),
    ('renderer', 'opengl', 'the simulator renders with OpenGL')])
def test_a_retired_parameter_stops_the_node_naming_what_replaces_it(
        context, name, value, replacement):
    with pytest.raises(ParameterError, match=f"parameter '{name}' is retired: {replacement}"):
        SimNode(context=context, parameter_overrides=LIGHT + [Parameter(name, value=value)])


def _subscribed(node):
    return {e.topic for e in opened(node) if e.direction == SUBSCRIBES}


@pytest.mark.parametrize('params, mode, command', [
    ({}, LockstepSim, contract.EFFORT_COMMANDS),
    (FREE, FreeRunningSim, contract.POSITION_COMMANDS),
    ({**FREE, 'position_command_type': 'joint_trajectory'}, FreeRunningSim,
     contract.TRAJECTORY_COMMANDS)])
def test_the_time_mode_picks_the_class_and_its_command_topic(context, params, mode, command):
    sim = SimNode(context=context, parameter_overrides=LIGHT + [
        Parameter(k, value=v) for k, v in params.items()])
    try:
        assert type(sim.mode) is mode
        assert _subscribed(sim) == {command}
        assert sim.mode.command_sub.topic_name == command
    finally:
        sim.destroy_node()


def test_free_running_clock_runs_at_least_at_the_command_rate(context):
    sim = SimNode(context=context, parameter_overrides=LIGHT + [
        Parameter(k, value=v) for k, v in {**FREE, 'clock_rate_hz': 10.0,
                                           'command_rate_hz': 250.0}.items()])
    try:
        assert sim.clock_period_ns == 4_000_000
    finally:
        sim.destroy_node()
    lockstep = SimNode(context=context, parameter_overrides=LIGHT + [
        Parameter('clock_rate_hz', value=10.0)])
    try:
        assert lockstep.clock_period_ns == 100_000_000
    finally:
        lockstep.destroy_node()


def test_a_start_outside_a_joints_range_is_refused_by_the_config():
    start = [4.0, 0.0, 0.0, 0.0, 0.0, 0.0]  # joint 1 at 229.2 deg, its range +-180 deg
    with pytest.raises(ParameterError, match=r"'start_joints'.*joint 1 at 229\.2 deg"):
        SimNodeConfig.make(start_joints=start)
    assert SimNodeConfig.make(start_joints=[0.1] * 6).start_joints == (0.1,) * 6
