"""
robot_state_node in an rclpy executor: ABB's description and link frames, as a listener sees.

A driver publishes joint states; the node's /robot_description, /tf_static and /tf are
composed as a tf listener does and checked against ibvs_model.abb_urdf and eq. (7).
"""

from diagnostic_msgs.msg import DiagnosticArray
from ibvs_common import contract
from ibvs_common.contract import ROBOT_DESCRIPTION, TF, TF_STATIC
from ibvs_common.conversions import joint_state, ns_stamp, pose_matrix, stamp_ns
from ibvs_common.params import ParameterError
from ibvs_model import abb_urdf, forward_kinematics, IRB4600
from ibvs_sim.robot_state_node import RobotStateNode
from ibvs_testing.fixtures import spin_until
import numpy as np
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

D_Q_DEG = [0.5, -0.3, 0.2, 0.0, 0.4, -0.6]
Q = np.array([0.1, 0.2, -0.1, 0.3, 0.5, -0.2])


class Driver(Node):
    """Publishes joint states; keeps what the node publishes (transient local: late too)."""

    def __init__(self, context):
        super().__init__('driver', context=context)
        self.got = {ROBOT_DESCRIPTION: [], TF_STATIC: [], TF: [], 'diag': []}
        self.joints = self.create_publisher(JointState, contract.JOINT_STATES,
                                            contract.RELIABLE)
        for topic, kind, qos in ((ROBOT_DESCRIPTION, String, contract.LATCHED),
                                 (TF_STATIC, TFMessage, contract.LATCHED),
                                 (TF, TFMessage, 100)):
            self.create_subscription(kind, topic, self.got[topic].append, qos)
        self.create_subscription(DiagnosticArray, contract.DIAGNOSTICS, self._on_diag, 10)

    def _on_diag(self, msg):
        for status in msg.status:
            if status.name.startswith('robot_state_node'):
                self.got['diag'].append({kv.key: kv.value for kv in status.values})


def chain(tf_messages):
    """Compose the transforms of TFMessages from base_link, as a tf listener does."""
    local = {t.child_frame_id: (t.header.frame_id, t.transform)
             for msg in tf_messages for t in msg.transforms}

    def pose(frame):
        if frame == contract.BASE_FRAME:
            return np.eye(4)
        parent, tf = local[frame]
        return pose(parent) @ pose_matrix(type('Pose', (), {'position': tf.translation,
                                                            'orientation': tf.rotation}))
    return pose


@pytest.fixture
def rig(context, executor_of):
    node = RobotStateNode(context=context, parameter_overrides=[
        Parameter('disturbance_deg', value=D_Q_DEG), Parameter('l2_scale', value=1.1)])
    driver = Driver(context)
    executor = executor_of(node, driver)
    spin_until(executor, lambda: driver.count_subscribers(contract.JOINT_STATES) == 1
               and driver.got[ROBOT_DESCRIPTION] and driver.got[TF_STATIC],
               what='discovery, /robot_description and /tf_static')
    return executor, driver


def test_description_and_frames_are_abbs_at_the_true_angles(rig):
    executor, driver = rig
    params = IRB4600.scaled(1.1, 1.0)
    assert driver.got[ROBOT_DESCRIPTION][-1].data == abb_urdf.robot_description(params)
    static = driver.got[TF_STATIC][-1]
    assert [(t.header.frame_id, t.child_frame_id) for t in static.transforms] == [
        ('base_link', 'base'), ('link_6', 'flange'), ('flange', 'tool0')]
    for k, q in enumerate((Q, -Q, np.zeros(6), Q[::-1])):
        driver.joints.publish(joint_state(34_000_000 * (k + 1), q))
        spin_until(executor, lambda: len(driver.got[TF]) == k + 1, what='/tf')
        tf = driver.got[TF][-1]
        assert {t.header.stamp.nanosec for t in tf.transforms} == {34_000_000 * (k + 1)}
        assert [(t.header.frame_id, t.child_frame_id) for t in tf.transforms] == [
            (parent, child) for _, parent, child, *_ in abb_urdf.ABB_JOINTS]
        pose = chain([static, tf])
        true_q = q + np.radians(D_Q_DEG)
        for frame, expected in abb_urdf.link_poses(true_q, params).items():
            np.testing.assert_allclose(pose(frame), expected, atol=1e-9, err_msg=frame)
        np.testing.assert_allclose(pose('tool0'), forward_kinematics(true_q, params),
                                   atol=1e-9)


def test_bad_joint_states_are_rejected_and_counted(rig):
    executor, driver = rig
    driver.joints.publish(joint_state(0, [np.nan] * 6))
    spin_until(executor, lambda: any(
        d.get('rejected[/joint_states: non-finite position]') == '1'
        for d in driver.got['diag']), what='the rejection on /diagnostics')
    driver.joints.publish(joint_state(5_000_000, Q))
    spin_until(executor, lambda: driver.got[TF], what='/tf')
    driver.joints.publish(joint_state(5_000_000, Q))  # the same stamp again
    spin_until(executor, lambda: any(
        d.get('rejected[/joint_states: duplicate stamp]') == '1'
        for d in driver.got['diag']), what='the duplicate on /diagnostics')
    assert len(driver.got[TF]) == 1


def test_bad_parameter_is_refused_with_its_name(context):
    with pytest.raises(ParameterError, match='l4_scale'):
        RobotStateNode(context=context,
                       parameter_overrides=[Parameter('l4_scale', value=-1.0)])


def test_joint_states_of_a_new_time_line_are_taken_after_the_clock_jumped_back(
        context, executor_of):
    """A simulator restarted under the node: /clock and stamps start again near 0."""
    node = RobotStateNode(context=context, parameter_overrides=[
        Parameter('use_sim_time', value=True)])
    driver = Driver(context)
    clock = driver.create_publisher(Clock, contract.CLOCK, contract.RELIABLE)
    executor = executor_of(node, driver)
    spin_until(executor, lambda: driver.count_subscribers(contract.JOINT_STATES) == 1
               and clock.get_subscription_count() == 1, what='discovery')
    for k, t in enumerate((10_000_000_000, 500_000_000)):  # the second: 9.5 s back
        clock.publish(Clock(clock=ns_stamp(t)))
        spin_until(executor, lambda t=t: node.get_clock().now().nanoseconds == t,
                   what='/clock')
        driver.joints.publish(joint_state(t, Q))
        spin_until(executor, lambda k=k: len(driver.got[TF]) == k + 1, what='/tf')
    assert stamp_ns(driver.got[TF][-1].transforms[0].header.stamp) == 500_000_000
    assert not node._diag.rejections
