"""
One QoS a topic: every node of the graph opens its topics through ibvs_common.kit.

The kit records what each node opens (kit.opened); here every node of the graph is built in
one context, in each command interface, and each topic must have one profile across all
the nodes that publish or read it (not CameraInfo read RELIABLE by one node and with the
images' QoS by another), and the transport the kit chose must be rclcpp's rule.
"""

from collections import defaultdict

from ibvs_common import contract, kit
from ibvs_control.adaptive_feedback_node import AdaptiveFeedbackNode
from ibvs_control.feedforward_node import FeedforwardNode
from ibvs_control.joint_controller_node import JointControllerNode
from ibvs_sim.sim_node import SimNode
from ibvs_vision.feature_node import FeatureNode
from ibvs_viz.viz_node import VizNode
import pytest
from rclpy.parameter import Parameter


def _profile(qos):
    return (qos.history, qos.depth, qos.reliability, qos.durability)


@pytest.mark.parametrize('interface', ['effort', 'position'])
def test_each_topic_has_one_qos_across_the_nodes(context, interface):
    mode = {} if interface == 'effort' else {'command_interface': 'position'}
    nodes = []
    try:
        for cls in (FeatureNode, AdaptiveFeedbackNode, FeedforwardNode, VizNode):
            nodes.append(cls(context=context))
        for cls in (JointControllerNode, SimNode):
            nodes.append(cls(context=context, parameter_overrides=[
                Parameter(k, value=v) for k, v in mode.items()]))
        profiles = defaultdict(set)
        ends = [e for node in nodes for e in kit.opened(node)]
        for end in ends:
            profiles[end.topic].add(_profile(end.qos))
            assert end.direct == kit.direct(end.qos), end
        assert {t: p for t, p in profiles.items() if len(p) > 1} == {}
        # The nodes read what the graph carries: the lockstep's topics, the camera's.
        topics = {(e.topic, e.direction) for e in ends}
        for topic in (contract.JOINT_STATES, contract.Q_FEEDBACK, contract.LEFT_INFO,
                      contract.RIGHT_INFO, contract.FEEDFORWARD_TRAJECTORY):
            assert (topic, kit.PUBLISHES) in topics and (topic, kit.SUBSCRIBES) in topics
        assert profiles[contract.LEFT_INFO] == {_profile(contract.CAMERA_INFO)}
        assert not any(e.direct for e in ends if e.topic == contract.STEREO_POSE)
    finally:
        for node in nodes:
            node.destroy_node()
