"""
A long feedforward trajectory into joint_controller_node (position, wall time).

The node takes it between two commands without holding its command timer. The executor's
thread runs the command timer and the trajectory's callback in turn. What it spends between
two commands is measured in its own CPU time (``time.thread_time``), which a busy machine
does not stretch: a wall-clock gap there is the scheduler's, this one is the node's work.
The trajectory is published as bytes serialized beforehand, so that the test's own
serialization is not counted.
"""

import time

from ibvs_common import contract
from ibvs_common.conversions import camera_infos, joint_state, joint_trajectory
from ibvs_model import default_camera, inverse_kinematics, paper
from ibvs_testing.fixtures import spin_until
import numpy as np
from rclpy.serialization import serialize_message

MS = 1_000_000
Q0 = inverse_kinematics(paper.scenario_start_pose(1))
#: Points of the long trajectory: six seconds at the 1 kHz physics rate.
POINTS = 6000
#: The most CPU time (s) the executor's thread may spend between two commands: five
#: command periods at 250 Hz. Taking the trajectory as Python objects costs more than this
#: many times over; reading it from its bytes costs a few milliseconds.
CPU_GAP_S = 0.020


def test_a_long_trajectory_is_taken_without_holding_the_command_timer(controller_rig):
    rig = controller_rig('sender', (contract.LEFT_INFO, contract.JOINT_STATES,
                                    contract.Q_FEEDBACK, contract.FEEDFORWARD_TRAJECTORY),
                         command_interface='position', frame_timeout_s=10.0,
                         joint_state_timeout_s=10.0)
    node, pubs = rig.node, rig.pubs
    sent = []  # (thread CPU time, wall time) of each command, in the executor's thread
    publish = node.mode._sender.pub.publish

    def recorded(msg):
        sent.append((time.thread_time(), time.monotonic()))
        return publish(msg)

    node.mode._sender.pub.publish = recorded
    executor = rig.spin_up()
    t_ns = node.get_clock().now().nanoseconds
    rows = np.tile(Q0, (POINTS, 1))
    rows[:, 0] += np.linspace(0.0, 0.2, POINTS)  # a valid move of joint_1
    raw = serialize_message(joint_trajectory(t_ns, MS, rows))  # before the first command
    pubs[contract.FEEDFORWARD_TRAJECTORY].publish(
        joint_trajectory(t_ns, MS, np.tile(Q0, (2, 1))))
    pubs[contract.JOINT_STATES].publish(joint_state(t_ns, Q0))
    pubs[contract.LEFT_INFO].publish(camera_infos(default_camera('VGA').intrinsics, t_ns)[0])
    pubs[contract.Q_FEEDBACK].publish(joint_state(t_ns, np.zeros(6)))
    spin_until(executor, lambda: len(sent) >= 10, what='the first commands')
    first = len(sent)
    pubs[contract.FEEDFORWARD_TRAJECTORY].publish(raw)
    spin_until(executor, lambda: node.diagnostics.values.get('feedforward_points')
               == POINTS, what='the long trajectory taken')
    taken = len(sent)
    spin_until(executor, lambda: len(sent) >= taken + 10, what='the commands after it')
    assert node.diagnostics.rejected_total == 0
    np.testing.assert_array_equal(node.mode.feedforward_target(), rows[-1])
    window = np.array(sent[first - 1:])
    cpu, wall = np.diff(window[:, 0]), np.diff(window[:, 1])
    worst = int(np.argmax(cpu))
    assert cpu[worst] <= CPU_GAP_S, (
        f'{cpu[worst] * 1e3:.1f} ms of CPU between two commands ({wall[worst] * 1e3:.1f} '
        f'ms of wall time; the largest wall gap {wall.max() * 1e3:.1f} ms)')
