"""
joint_controller_node with command_interface 'position', in an rclpy executor.

A test node (the ``position_cell`` of this directory's conftest.py) plays the feedforward,
the feedback, the camera (its camera_info), the arm's /joint_states and /clock (sim time, so
the command timer fires only when the test moves the clock), and records what a
forward_command_controller or a joint_trajectory_controller would get, and the status.
"""

from ibvs_common import contract
from ibvs_common.conversions import joint_state, joint_trajectory, stamp_ns
from ibvs_common.params import ParameterError
from ibvs_common.timing import frame_stamp_ns
from ibvs_control.joint_controller_node import JointControllerNode
from ibvs_control.servo_status import ServoStatus
from ibvs_model import inverse_kinematics, paper
from ibvs_model.drive import JERK_LIMITS
from ibvs_testing.fixtures import spin_until
import numpy as np
import pytest
from rclpy.parameter import Parameter
from std_msgs.msg import Float64MultiArray, Int8
from trajectory_msgs.msg import JointTrajectory

MS = 1_000_000
Q0 = inverse_kinematics(paper.scenario_start_pose(1))
ORDER = ['joint_2', 'joint_1', 'joint_3', 'joint_4', 'joint_6', 'joint_5']
PERMUTATION = [1, 0, 2, 3, 5, 4]
#: The most a reference moves from rest in one 4 ms command period: j t^3 / 6 at joint 1's
#: jerk limit (ibvs_model.drive.JERK_LIMITS).
JERK_STEP = JERK_LIMITS[0] * 0.004 ** 3 / 6 + 1e-12


def changes(codes):
    """Return the status codes as they changed (the node repeats them once a second)."""
    return [ServoStatus(c) for i, c in enumerate(codes) if i == 0 or c != codes[i - 1]]


def test_sends_shaped_references_in_the_controllers_joint_order_and_reports_latency(
        position_cell):
    cell = position_cell(joints=ORDER)
    node, executor, pubs = cell.node, cell.executor, cell.pubs
    rows = np.tile(Q0, (14, 1))
    rows[9:, 0] += 0.1  # the feedforward asks joint_1 to move at 9 ms
    pubs[contract.FEEDFORWARD_TRAJECTORY].publish(joint_trajectory(0, MS, rows))
    pubs[contract.JOINT_STATES].publish(joint_state(0, Q0, np.zeros(6)))
    spin_until(executor, lambda: node.mode._trajectory is not None and
               node.mode._measured is not None, what='trajectory and joint state')
    cell.clock(4 * MS)
    # the move starts on the feedforward and the joint states: no frame has come yet
    spin_until(executor, lambda: cell.commands, what='the first command, before any frame')
    cell.frame(0)
    spin_until(executor, lambda: node.mode._hold.stamp_ns == 0, what="frame 0's feedback")
    for t in range(8, 45, 4):
        cell.clock(t * MS)
        spin_until(executor, lambda n=t // 4: len(cell.commands) >= n,
                   what=f'the command at {t} ms')
    first = cell.commands[0]
    # controller order; joint_1 has left Q0 by at most what its jerk limit allows in
    # one 4 ms period (j t^3 / 6), toward the feedforward's target
    np.testing.assert_allclose(first, Q0[PERMUTATION], atol=JERK_STEP)
    last = cell.commands[-1][np.argsort(PERMUTATION)]
    moved = last - Q0
    # joint_1 moves toward the feedforward, under the acceleration limit (10 rad/s^2:
    # at most a t^2 / 2 = 8 mrad in 40 ms); the others stay
    assert 0.0 < moved[0] <= 10.0 * 0.04 ** 2 / 2 + 1e-9
    np.testing.assert_allclose(moved[1:], 0.0, atol=1e-12)
    spin_until(executor, lambda: cell.latency, what="frame 0's latency record")
    assert len(cell.latency) == 1 and stamp_ns(cell.latency[0].time_ref) == 0
    assert changes(cell.status) == [ServoStatus.NO_WARNING]
    # a q_feedback of the frame exposed at 34 ms: the next command uses it and says so
    cell.frame(34 * MS, np.full(6, 1e-3))
    spin_until(executor, lambda: node.mode._hold.stamp_ns == 34 * MS, what='the feedback')
    cell.clock(48 * MS)
    spin_until(executor, lambda: len(cell.latency) == 2, what='the latency record')
    report = cell.latency[1]
    assert stamp_ns(report.time_ref) == 34 * MS and stamp_ns(report.header.stamp) == 48 * MS
    # an older frame's q_feedback is refused (counted), the newer one stays
    pubs[contract.Q_FEEDBACK].publish(joint_state(0, np.full(6, 5e-3)))
    spin_until(executor, lambda: node.diagnostics.rejected_total == 1,
               what='the rejection')
    assert node.diagnostics.rejections[f'{contract.Q_FEEDBACK}: out of order'] == 1


def test_without_a_first_frame_within_its_timeout_the_started_move_holds(position_cell):
    """The camera follows the start; none within frame_timeout_s holds as a stale camera."""
    cell = position_cell(frame_timeout_s=0.1)
    node, executor, pubs = cell.node, cell.executor, cell.pubs
    target = Q0.copy()
    target[0] += 1.0
    pubs[contract.FEEDFORWARD_TRAJECTORY].publish(joint_trajectory(0, MS, [target]))
    pubs[contract.JOINT_STATES].publish(joint_state(0, Q0, np.zeros(6)))
    spin_until(executor, lambda: node.mode._trajectory is not None and
               node.mode._measured is not None, what='trajectory and joint state')
    for t in range(4, 101, 4):  # the start is the first command, at 4 ms
        cell.tick(t * MS, inputs=False)
        pubs[contract.JOINT_STATES].publish(joint_state(t * MS, cell.measured, np.zeros(6)))
    assert changes(cell.status) == [ServoStatus.NO_WARNING]
    assert cell.commands[-1][0] > Q0[0]  # on its way to the feedforward's target
    cell.clock(108 * MS)  # 104 ms after the start, no frame: hold
    cell.spin_to_status(ServoStatus.HOLD_STALE_CAMERA)
    assert 'none in the 0.104 s since the start' in node.diagnostics.status().message
    assert node.mode.holds == 1


def test_joint_trajectory_controller_gets_a_stamped_window_by_joint_name(position_cell):
    cell = position_cell('joint_trajectory', joints=ORDER)
    node, executor, pubs = cell.node, cell.executor, cell.pubs
    target = Q0.copy()
    target[0] += 1.0  # the feedforward moves joint_1 at t = 8 ms: the window sees it come
    pubs[contract.FEEDFORWARD_TRAJECTORY].publish(
        joint_trajectory(0, MS, [Q0] * 8 + [target]))
    # joint_state_broadcaster's: a track too, the arm's joints in its own order
    state = joint_state(0, np.r_[Q0[::-1], 0.5], np.zeros(7), names=[
        f'joint_{i}' for i in range(6, 0, -1)] + ['track_1'])
    pubs[contract.JOINT_STATES].publish(state)
    cell.frame(0)
    spin_until(executor, lambda: node.mode._trajectory is not None and
               node.mode._measured is not None and node.mode._hold.stamp_ns == 0,
               what='trajectory, joint state and feedback')
    cell.clock(4 * MS)
    spin_until(executor, lambda: cell.command_msgs, what='a trajectory command')
    msg = cell.command_msgs[0]
    # the controller's joints only, stamped now (MoveIt Servo's window), not 0
    assert list(msg.joint_names) == ORDER and stamp_ns(msg.header.stamp) == 4 * MS
    assert len(msg.points) == 26  # trajectory_window_points
    assert [stamp_ns(p.time_from_start) for p in msg.points] == \
        [k * 4 * MS for k in range(26)]
    window = np.array([p.positions for p in msg.points])[:, np.argsort(PERMUTATION)]
    np.testing.assert_allclose(window[0], Q0, atol=JERK_STEP)  # the reference now
    # ahead: joint_1 on its way to the feedforward's new point, at most 20 deg/s
    step = np.diff(window[:, 0])
    assert np.all(step >= 0.0) and window[-1, 0] > Q0[0] + 1e-3
    assert np.all(step <= np.radians(20.0) * 0.004 * (1 + 1e-9))
    np.testing.assert_allclose(window[:, 1:], np.tile(Q0[1:], (26, 1)), atol=1e-12)
    assert node.diagnostics.values['ignored_joints'] == 'track_1'


def test_a_stale_camera_holds_the_arm_says_why_and_resumes_without_a_jump(position_cell):
    """Hold within the timeout, the status names the input, resume."""
    # the arm's own speed limits, not a first run's cap (max_joint_speed_deg_s)
    cell = position_cell(joints=ORDER, frame_timeout_s=0.3, max_joint_speed_deg_s=1000.0)
    node, executor, pubs = cell.node, cell.executor, cell.pubs
    target = Q0.copy()
    target[0] += 2.0  # the feedforward asks joint_1 to move 2 rad at once
    pubs[contract.FEEDFORWARD_TRAJECTORY].publish(joint_trajectory(0, MS, [target]))
    measured = Q0.copy()

    frames = iter(frame_stamp_ns(n, 33_333_333, MS) for n in range(1, 100))
    next_frame = [next(frames)]

    def tick(t_ns, camera):
        """One 4 ms command period: the arm is where it was told; 30 Hz frames."""
        pubs[contract.JOINT_STATES].publish(joint_state(t_ns, measured, np.zeros(6)))
        if t_ns >= next_frame[0]:
            if camera:
                cell.frame(next_frame[0])
            next_frame[0] = next(frames)
        cell.clock(t_ns)
        count = len(cell.commands)
        spin_until(executor, lambda: len(cell.commands) > count,
                   what=f'the command at {t_ns} ns')

    pubs[contract.JOINT_STATES].publish(joint_state(0, measured, np.zeros(6)))
    cell.frame(0)
    spin_until(executor, lambda: not node.mode._watch.missing(), what='every input once')
    commands = []
    for k in range(1, 350):  # 1.4 s: camera on to 0.2 s, off to 1.1 s, on again
        t_ns = k * 4 * MS
        tick(t_ns, camera=not 0.2e9 < t_ns < 1.1e9)
        if len(cell.commands) > len(commands):
            commands.append((t_ns, cell.commands[-1][np.argsort(PERMUTATION)]))
            measured = commands[-1][1]
    assert changes(cell.status)[-3:] == [
        ServoStatus.NO_WARNING, ServoStatus.HOLD_STALE_CAMERA, ServoStatus.NO_WARNING]
    assert node.mode.holds == 1
    times = np.array([t for t, _ in commands])
    q = np.array([c for _, c in commands])
    # the last frame before the outage is at 200 ms: stale from 500 ms; joint_1 moves at
    # its speed limit (3.05 rad/s) and brakes at drive_acceleration_margin (0.8) of 10 rad/s^2
    # and 100 rad/s^3: at rest 0.48 s later
    moving = (times > 0.1e9) & (times < 0.5e9)
    assert np.ptp(q[moving, 0]) > 0.5, 'the arm moved before the outage'
    braking = (times >= 0.5e9) & (times < 1.1e9)
    # a controlled stop: no turning back (but the braking curve's 4 ms samples: a few urad)
    assert np.diff(q[braking, 0]).min() > -1e-5
    held = (times > 1.0e9) & (times < 1.1e9)
    assert np.ptp(q[held, :], axis=0).max() < 1e-9, 'the arm holds still'
    # it resumes toward the target; no step larger than the speed limit allows
    assert q[-1, 0] > q[held, 0][-1]
    steps = np.abs(np.diff(q, axis=0)) / 4e-3
    assert np.all(steps <= node.mode.shaper.speed_limits + 1e-9)


def test_the_feedback_nodes_local_minimum_is_relayed_on_the_status_without_a_hold(
        position_cell):
    cell = position_cell()
    node = cell.node
    feedback_status = cell.pubs[contract.FEEDBACK_STATUS]  # the feedback node's
    cell.start(0, Q0)
    cell.tick(4 * MS)
    cell.spin_to_status(ServoStatus.NO_WARNING)
    feedback_status.publish(Int8(data=int(ServoStatus.LOCAL_MINIMUM)))
    spin_until(cell.executor,
               lambda: node.mode._feedback_status.status == ServoStatus.LOCAL_MINIMUM,
               what="the feedback node's status")
    cell.tick(8 * MS)  # a command goes out: the arm is not held
    cell.spin_to_status(ServoStatus.LOCAL_MINIMUM)
    assert node.mode.holds == 0
    assert 'LOCAL_MINIMUM' in node.diagnostics.status().message
    # a code the feedback node never reports is refused, the status kept
    feedback_status.publish(Int8(data=int(ServoStatus.HOLD_STALE_CAMERA)))
    spin_until(cell.executor, lambda: cell.rejected('unknown code') == 1, what='the refusal')
    feedback_status.publish(Int8(data=int(ServoStatus.NO_WARNING)))
    spin_until(cell.executor,
               lambda: node.mode._feedback_status.status == ServoStatus.NO_WARNING,
               what="the feedback node's NO_WARNING")
    cell.tick(12 * MS)
    cell.spin_to_status(ServoStatus.NO_WARNING)
    assert changes(cell.status)[-3:] == [ServoStatus.NO_WARNING, ServoStatus.LOCAL_MINIMUM,
                                         ServoStatus.NO_WARNING]


@pytest.mark.parametrize('command_type, kind, topic', [
    ('forward_command', Float64MultiArray, contract.DRY_RUN_COMMANDS),
    ('joint_trajectory', JointTrajectory, contract.DRY_RUN_TRAJECTORY),
])
def test_a_dry_run_sends_its_references_on_its_own_topic_and_never_opens_the_arms(
        position_cell, command_type, kind, topic):
    cell = position_cell(command_type, dry_run=True)
    node, executor = cell.node, cell.executor
    dry = cell.record(kind, topic)
    spin_until(executor, lambda: node.mode._sender.pub.get_subscription_count() > 0,
               what='the dry run topic discovered')
    target = Q0 + np.radians(5.0)
    cell.start(0, target)
    for t in range(4, 41, 4):
        count = len(dry)
        cell.clock(t * MS)
        spin_until(executor, lambda c=count: len(dry) > c, what=f'the reference at {t} ms')
    first = np.asarray(dry[0].data if kind is Float64MultiArray else dry[0].points[0].positions)
    last = np.asarray(dry[-1].data if kind is Float64MultiArray else dry[-1].points[0].positions)
    assert np.all((last - first) * (target - Q0) > 0), 'toward the target, as it would send'
    assert not cell.commands, 'nothing on the command topic'
    arm = contract.POSITION_COMMANDS if kind is Float64MultiArray else \
        contract.TRAJECTORY_COMMANDS
    assert node.count_publishers(arm) == 0, "the arm's command topic is not even opened"


@pytest.mark.parametrize('params, name', [
    ({'lockstep': False}, 'lockstep'),  # retired: the interface gives the time mode
    ({'joints': ORDER[:5] + ['joint_2']}, 'joints'),
    ({'joints': ORDER[:5]}, 'joints'),
    ({'command_interface': 'effort', 'dry_run': True}, 'dry_run'),
])
def test_bad_configurations_are_refused_naming_the_parameter(context, params, name):
    values = {'command_interface': 'position'}
    values.update(params)
    with pytest.raises(ParameterError, match=f"parameter '{name}'"):
        JointControllerNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in values.items()])
