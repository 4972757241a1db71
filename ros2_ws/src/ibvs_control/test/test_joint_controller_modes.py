"""
joint_controller_node: one class per command interface, picked from a typed config.

The config (:class:`ibvs_control.node_params.JointControllerConfig`) is pure
Python: its rules are checked without a node. The node starts the class of
``command_interface`` and nothing of the other.
"""

from ibvs_common import contract
from ibvs_common.kit import opened, PUBLISHES, SUBSCRIBES
from ibvs_common.params import ParameterError
from ibvs_control.effort_controller import EffortController
from ibvs_control.joint_controller_node import JointControllerNode, PARAMS
from ibvs_control.node_params import JointControllerConfig
from ibvs_control.position_controller import PositionController
import pytest
from rclpy.parameter import Parameter

POSITION = [Parameter('command_interface', value='position')]


def test_config_takes_the_declared_parameters_and_its_time_mode_from_the_interface():
    assert [p.name for p in PARAMS] == [p.name for p in JointControllerConfig.params()]
    config = JointControllerConfig(torque_limits=[1, 2, 3, 4, 5, 6])
    assert config.torque_limits == (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
    assert JointControllerConfig.make(command_interface='position').interface.lockstep is False
    assert JointControllerConfig().interface.lockstep is True
    assert 'lockstep' not in {p.name for p in PARAMS}
    with pytest.raises(TypeError):
        JointControllerConfig(lockstep=False)  # no such field: the interface gives it
    with pytest.raises(ParameterError, match="'trajectory_window_points'"):
        JointControllerConfig(trajectory_window_points=0)


def _topics(node):
    return {(e.topic, e.direction) for e in opened(node)}


def test_the_effort_interface_opens_only_its_topics(context):
    node = JointControllerNode(context=context)
    try:
        assert type(node.mode) is EffortController
        topics = _topics(node)
        assert (contract.EFFORT_COMMANDS, PUBLISHES) in topics
        assert (contract.FRAME_LOST, SUBSCRIBES) in topics
        # the status too: it never holds, but relays what the feedback node reports
        assert {(contract.SERVO_STATUS, PUBLISHES), (contract.FEEDBACK_STATUS, SUBSCRIBES)} \
            <= set(topics)
        assert not {t for t, _ in topics} & {contract.POSITION_COMMANDS, contract.LEFT_INFO}
    finally:
        node.destroy_node()


def test_the_position_interface_opens_only_its_topics_and_names_what_it_ignores(context,
                                                                                capfd):
    node = JointControllerNode(context=context, parameter_overrides=POSITION + [
        Parameter('actuators', value='limited'),
        Parameter('acceleration_margin', value=0.25)])
    try:
        assert type(node.mode) is PositionController
        topics = {t for t, _ in _topics(node)}
        assert {contract.POSITION_COMMANDS, contract.SERVO_STATUS, contract.LEFT_INFO} <= topics
        assert not topics & {contract.EFFORT_COMMANDS, contract.FRAME_LOST}
        err = capfd.readouterr().err
        assert err.count("ignored with command_interface 'position'") == 1
        assert "actuators = 'limited'" in err and 'acceleration_margin = 0.25' in err
        assert 'torque_limits' not in err  # at its default: nothing to say
    finally:
        node.destroy_node()


def test_the_position_interface_is_silent_about_defaults(context, capfd):
    node = JointControllerNode(context=context, parameter_overrides=POSITION)
    try:
        assert 'ignored with' not in capfd.readouterr().err
    finally:
        node.destroy_node()
