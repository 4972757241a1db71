"""
joint_controller_node with command_interface 'position', in an rclpy executor.

A test node plays the feedforward, the feedback, the arm's /joint_states and /clock (sim
time, so the command timer fires only when the test moves the clock), and records what a
forward_command_controller or a joint_trajectory_controller would get.
"""

from ibvs_common import contract
from ibvs_common.conversions import joint_state, joint_trajectory, ns_stamp, stamp_ns
from ibvs_common.params import ParameterError
from ibvs_control.joint_controller_node import JointControllerNode
from ibvs_model import inverse_kinematics, paper
from ibvs_testing.fixtures import spin_until
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, TimeReference
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

MS = 1_000_000
Q0 = inverse_kinematics(paper.scenario_start_pose(1))
ORDER = ['joint_2', 'joint_1', 'joint_3', 'joint_4', 'joint_6', 'joint_5']
PERMUTATION = [1, 0, 2, 3, 5, 4]


def build(context, **params):
    values = {'command_interface': 'position', 'lockstep': False, 'joints': ORDER,
              'use_sim_time': True}
    values.update(params)
    node = JointControllerNode(context=context, parameter_overrides=[
        Parameter(k, value=v) for k, v in values.items()])
    test = Node('cell', context=context)
    rec = {'commands': [], 'trajectories': [], 'latency': []}
    test.create_subscription(Float64MultiArray, contract.POSITION_COMMANDS,
                             rec['commands'].append, contract.RELIABLE)
    test.create_subscription(JointTrajectory, contract.TRAJECTORY_COMMANDS,
                             rec['trajectories'].append, contract.RELIABLE)
    test.create_subscription(TimeReference, contract.FRAME_LATENCY, rec['latency'].append,
                             contract.RELIABLE)
    pubs = {topic: test.create_publisher(kind, topic, qos) for topic, kind, qos in (
        (contract.CLOCK, Clock, contract.RELIABLE),
        (contract.JOINT_STATES, JointState, contract.RELIABLE),
        (contract.Q_FEEDBACK, JointState, contract.RELIABLE),
        (contract.FEEDFORWARD_TRAJECTORY, JointTrajectory, contract.LATCHED))}
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(test)
    spin_until(executor, lambda: all(p.get_subscription_count() for p in pubs.values()),
               what='discovery')
    return node, test, executor, pubs, rec


def clock_to(executor, pubs, t_ns):
    pubs[contract.CLOCK].publish(Clock(clock=ns_stamp(t_ns)))


def test_sends_shaped_references_in_the_controllers_joint_order_and_reports_latency(context):
    node, test, executor, pubs, rec = build(context)
    try:
        rows = np.tile(Q0, (10, 1))
        rows[5:, 0] += 0.1  # the feedforward asks joint_1 to move at 5 ms
        pubs[contract.FEEDFORWARD_TRAJECTORY].publish(joint_trajectory(0, MS, rows))
        pubs[contract.JOINT_STATES].publish(joint_state(0, Q0, np.zeros(6)))
        spin_until(executor, lambda: node._trajectory is not None and
                   node._measured is not None, what='trajectory and joint state')
        for t in range(4, 41, 4):
            clock_to(executor, pubs, t * MS)
            spin_until(executor, lambda n=t // 4: len(rec['commands']) >= n,
                       what=f'the command at {t} ms')
        first = np.asarray(rec['commands'][0].data)
        np.testing.assert_allclose(first, Q0[PERMUTATION], atol=1e-12)  # controller order
        last = np.asarray(rec['commands'][-1].data)[np.argsort(PERMUTATION)]
        moved = last - Q0
        # joint_1 moves toward the feedforward, under the acceleration limit (10 rad/s^2:
        # at most a t^2 / 2 = 8 mrad in 40 ms); the others stay
        assert 0.0 < moved[0] <= 10.0 * 0.04 ** 2 / 2 + 1e-9
        np.testing.assert_allclose(moved[1:], 0.0, atol=1e-12)
        assert not rec['latency']  # no frame used yet
        # a q_feedback of the frame exposed at 34 ms: the next command uses it and says so
        pubs[contract.Q_FEEDBACK].publish(joint_state(34 * MS, np.full(6, 1e-3)))
        spin_until(executor, lambda: node._hold.stamp_ns == 34 * MS, what='the feedback')
        clock_to(executor, pubs, 44 * MS)
        spin_until(executor, lambda: rec['latency'], what='the latency record')
        report = rec['latency'][0]
        assert stamp_ns(report.time_ref) == 34 * MS and stamp_ns(report.header.stamp) == 44 * MS
        # an older frame's q_feedback is refused (counted), the newer one stays
        pubs[contract.Q_FEEDBACK].publish(joint_state(0, np.full(6, 5e-3)))
        spin_until(executor, lambda: node.diagnostics.rejected_total == 1,
                   what='the rejection')
        assert node.diagnostics.rejections[f'{contract.Q_FEEDBACK}: out of order'] == 1
    finally:
        executor.shutdown()
        node.destroy_node()
        test.destroy_node()


def test_joint_trajectory_controller_gets_one_point_by_joint_name(context):
    node, test, executor, pubs, rec = build(context, position_command_type='joint_trajectory')
    try:
        pubs[contract.FEEDFORWARD_TRAJECTORY].publish(joint_trajectory(0, MS, [Q0]))
        pubs[contract.JOINT_STATES].publish(joint_state(0, Q0, np.zeros(6)))
        spin_until(executor, lambda: node._trajectory is not None and
                   node._measured is not None, what='trajectory and joint state')
        clock_to(executor, pubs, 4 * MS)
        spin_until(executor, lambda: rec['trajectories'], what='a trajectory command')
        msg = rec['trajectories'][0]
        assert list(msg.joint_names) == ORDER and stamp_ns(msg.header.stamp) == 0
        assert len(msg.points) == 1
        assert stamp_ns(msg.points[0].time_from_start) == 4 * MS  # one command period
        np.testing.assert_allclose(msg.points[0].positions, Q0[PERMUTATION], atol=1e-12)
    finally:
        executor.shutdown()
        node.destroy_node()
        test.destroy_node()


@pytest.mark.parametrize('params, name', [
    ({'lockstep': True}, 'lockstep'),
    ({'joints': ORDER[:5] + ['joint_2']}, 'joints'),
    ({'joints': ORDER[:5]}, 'joints'),
    ({'command_interface': 'effort'}, 'lockstep'),
])
def test_bad_configurations_are_refused_naming_the_parameter(context, params, name):
    values = {'command_interface': 'position', 'lockstep': False}
    values.update(params)
    with pytest.raises(ParameterError, match=f"parameter '{name}'"):
        JointControllerNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in values.items()])
