"""
joint_controller_node against a second publisher on its inputs or its own command topic.

In an rclpy executor, as test_joint_controller_clock.py: a test node plays the feedforward,
the camera (its camera_info), the q_feedback, the arm's /joint_states and /clock, and
records the commands, /ibvs/servo_status and /diagnostics; a node 'rogue' comes with a
publisher of its own on one topic, and goes.
"""

import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from ibvs_common import contract, sim_time
from ibvs_common.conversions import camera_infos, joint_state, joint_trajectory, ns_stamp
from ibvs_control.joint_controller_node import JointControllerNode
from ibvs_control.servo_status import ServoStatus
from ibvs_model import default_camera, inverse_kinematics, paper
from ibvs_testing.fixtures import spin_until
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, JointState
from std_msgs.msg import Float64MultiArray, Int8
from trajectory_msgs.msg import JointTrajectory

MS = 1_000_000
S = 1000 * MS
Q0 = inverse_kinematics(paper.scenario_start_pose(1))
CAMERA = default_camera('VGA')
FRAME_NS = 33_333_333
TICK_NS = 4 * MS  # the command period at 250 Hz
KINDS = {contract.POSITION_COMMANDS: Float64MultiArray, contract.JOINT_STATES: JointState,
         contract.Q_FEEDBACK: JointState, contract.LEFT_INFO: CameraInfo,
         contract.FEEDFORWARD_TRAJECTORY: JointTrajectory}


class Cell:
    """The position joint controller and what a cell would send it and read from it."""

    def __init__(self, context):
        self.context = context
        self.node = JointControllerNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in {
                'command_interface': 'position', 'lockstep': False, 'use_sim_time': True,
                'frame_timeout_s': 0.3}.items()])
        self.test = Node('cell', context=context)
        self.commands, self.status, self.diagnostics = [], [], []
        self.test.create_subscription(
            Float64MultiArray, contract.POSITION_COMMANDS,
            lambda m: self.commands.append(np.asarray(m.data)), contract.RELIABLE)
        self.test.create_subscription(Int8, contract.SERVO_STATUS,
                                      lambda m: self.status.append(m.data), contract.LATCHED)
        self.test.create_subscription(
            DiagnosticArray, contract.DIAGNOSTICS,
            lambda m: self.diagnostics.extend(s for s in m.status
                                              if s.name.startswith('joint_controller_node')),
            10)
        self.pubs = {topic: self.test.create_publisher(kind, topic, qos) for topic, kind, qos in (
            (contract.CLOCK, Clock, contract.RELIABLE),
            (contract.LEFT_INFO, CameraInfo, contract.IMAGES),
            (contract.JOINT_STATES, JointState, contract.RELIABLE),
            (contract.Q_FEEDBACK, JointState, contract.RELIABLE),
            (contract.FEEDFORWARD_TRAJECTORY, JointTrajectory, contract.LATCHED))}
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.test)
        spin_until(self.executor,
                   lambda: all(p.get_subscription_count() for p in self.pubs.values()),
                   what='discovery')
        self.measured = Q0.copy()
        self.next_frame = None
        self.rogue = None

    def close(self):
        self.executor.shutdown()
        self.node.destroy_node()
        self.test.destroy_node()
        if self.rogue is not None:
            self.rogue.destroy_node()

    def frame(self, t_ns):
        """Publish the camera frame exposed at ``t_ns``: its camera_info and q_feedback."""
        self.pubs[contract.LEFT_INFO].publish(camera_infos(CAMERA.intrinsics, t_ns)[0])
        self.pubs[contract.Q_FEEDBACK].publish(joint_state(t_ns, np.zeros(6)))
        self.next_frame = t_ns + FRAME_NS

    def tick(self, t_ns):
        """One command period: the arm where it was told, 30 Hz frames; one command."""
        self.pubs[contract.JOINT_STATES].publish(joint_state(t_ns, self.measured, np.zeros(6)))
        if self.next_frame is None or t_ns >= self.next_frame:
            self.frame(t_ns)
        count = len(self.commands)
        self.pubs[contract.CLOCK].publish(Clock(clock=ns_stamp(t_ns)))
        spin_until(self.executor, lambda: len(self.commands) > count,
                   what=f'the command at {t_ns} ns')
        self.measured = self.commands[-1].copy()

    def start(self, t0_ns, target):
        self.pubs[contract.CLOCK].publish(Clock(clock=ns_stamp(t0_ns)))
        spin_until(self.executor,
                   lambda: self.node.get_clock().now().nanoseconds == t0_ns, what='/clock')
        self.pubs[contract.FEEDFORWARD_TRAJECTORY].publish(joint_trajectory(t0_ns, MS, [target]))
        self.pubs[contract.JOINT_STATES].publish(joint_state(t0_ns, Q0, np.zeros(6)))
        self.frame(t0_ns)
        spin_until(self.executor, lambda: not self.node.mode._watch.missing(),
                   what='every input once')
        watch = self.node.diagnostics.publishers
        spin_until(self.executor, lambda: len(watch.expected) == 5 and all(
            e.settled for e in watch.expected.values()),
            what="the inputs' publishers seen once")  # the cell's, before any rogue

    def rogue_on(self, topic):
        """Bring a node of its own with a publisher on ``topic`` (it sends nothing)."""
        self.rogue = Node('rogue', context=self.context)
        self.rogue.create_publisher(KINDS[topic], topic, contract.RELIABLE)

    def rogue_off(self):
        self.rogue.destroy_node()
        self.rogue = None

    def spin_to_status(self, code):
        spin_until(self.executor, lambda: self.status and self.status[-1] == code,
                   what=code.name)

    def said(self, *words):
        """Return whether a WARN on /diagnostics says every one of ``words``."""
        return any(s.level == DiagnosticStatus.WARN and all(w in s.message for w in words)
                   for s in self.diagnostics)


@pytest.fixture
def cell(context, monkeypatch):
    monkeypatch.setattr(sim_time, 'CLOCK_STALL_MIN_S', 1e6)  # it stands still at times
    made = Cell(context)
    try:
        t0 = 10 * S
        target = Q0.copy()
        target[0] += 1.0  # a long move: under way when the rogue comes
        made.start(t0, target)
        made.t = t0
        made.target = target
        for _ in range(30):
            made.t += TICK_NS
            made.tick(made.t)
        assert made.status[-1] == ServoStatus.NO_WARNING
        yield made
    finally:
        made.close()


@pytest.mark.parametrize('topic', [contract.POSITION_COMMANDS, contract.JOINT_STATES,
                                   contract.Q_FEEDBACK, contract.FEEDFORWARD_TRAJECTORY])
def test_a_second_publisher_on_what_the_arm_follows_holds_it_named_until_it_is_gone(
        cell, topic):
    """Acceptance: a second commander (or input) holds the arm with its code; it resumes."""
    cell.rogue_on(topic)
    came = time.monotonic()
    cell.spin_to_status(ServoStatus.HOLD_SECOND_PUBLISHER)  # from the steady-clock look
    print(f'{topic}: HOLD_SECOND_PUBLISHER {time.monotonic() - came:.3f} s of wall time '
          'after the rogue came (no sim time went by)')
    spin_until(cell.executor, lambda: cell.said(f'second publisher on {topic}: /rogue',
                                                'holding the arm'),
               what='the newcomer named on /diagnostics')
    values = cell.node.diagnostics.values
    assert values['second_publishers'] == f'second publisher on {topic}: /rogue'
    assert values['second_publishers_seen'] == 1
    for _ in range(150):  # 0.6 s: a controlled stop, then the arm holds still
        cell.t += TICK_NS
        cell.tick(cell.t)
    held = np.array(cell.commands[-50:])
    assert np.ptp(held, axis=0).max() < 1e-9, 'the arm holds still'
    assert held[-1, 0] < cell.target[0] - 0.1, 'stopped short of the target'
    assert set(cell.status[cell.status.index(ServoStatus.HOLD_SECOND_PUBLISHER):]) == {
        ServoStatus.HOLD_SECOND_PUBLISHER}
    cell.rogue_off()
    cell.spin_to_status(ServoStatus.NO_WARNING)
    for _ in range(20):
        cell.t += TICK_NS
        cell.tick(cell.t)
    assert cell.commands[-1][0] > held[-1, 0], 'servoing resumed toward the target'
    assert cell.node.diagnostics.values['second_publishers'] == 'none'
    assert cell.node.diagnostics.status().level == DiagnosticStatus.OK


def test_a_second_camera_is_reported_and_the_arm_servos_on(cell):
    """The camera's frames give only an age: a second camera_info is named, not held on."""
    since = len(cell.status)
    cell.rogue_on(contract.LEFT_INFO)
    spin_until(cell.executor, lambda: cell.said(
        f'second publisher on {contract.LEFT_INFO}: /rogue'), what='the newcomer named')
    for _ in range(20):
        cell.t += TICK_NS
        cell.tick(cell.t)
    assert set(cell.status[since:]) <= {ServoStatus.NO_WARNING}  # on a change, once a second
    assert cell.node.mode._verdict.status == ServoStatus.NO_WARNING
    assert cell.commands[-1][0] > cell.commands[-20][0], 'the arm moves on'


def test_the_effort_interface_reports_a_second_commander_and_answers_as_before(context):
    """Lockstep: a second publisher of effort commands is named and counted, not held on."""
    node = JointControllerNode(context=context, parameter_overrides=[
        Parameter('use_sim_time', value=True)])
    test = Node('simulator', context=context)
    efforts, statuses = [], []
    test.create_subscription(JointState, contract.EFFORT_COMMANDS, efforts.append,
                             contract.RELIABLE)
    test.create_subscription(DiagnosticArray, contract.DIAGNOSTICS,
                             lambda m: statuses.extend(m.status), 10)
    pubs = {topic: test.create_publisher(kind, topic, qos) for topic, kind, qos in (
        (contract.CLOCK, Clock, contract.RELIABLE),
        (contract.JOINT_STATES, JointState, contract.RELIABLE),
        (contract.Q_FEEDBACK, JointState, contract.RELIABLE),
        (contract.FEEDFORWARD_TRAJECTORY, JointTrajectory, contract.LATCHED))}
    rogue = Node('rogue', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(test)
    try:
        spin_until(executor, lambda: all(p.get_subscription_count() for p in pubs.values()),
                   what='discovery')
        pubs[contract.FEEDFORWARD_TRAJECTORY].publish(joint_trajectory(0, MS, [Q0] * 10))
        pubs[contract.Q_FEEDBACK].publish(joint_state(0, np.zeros(6)))
        rogue.create_publisher(JointState, contract.EFFORT_COMMANDS, contract.RELIABLE)
        words = f'second publisher on {contract.EFFORT_COMMANDS}: /rogue'
        spin_until(executor, lambda: any(s.level == DiagnosticStatus.WARN and words in s.message
                                         for s in statuses), what='the newcomer named')
        for k in range(3):
            pubs[contract.JOINT_STATES].publish(joint_state(k * MS, Q0, np.zeros(6)))
            spin_until(executor, lambda k=k: len(efforts) == k + 1,
                       what=f'the answer to step {k}')
        assert node.diagnostics.values['second_publishers_seen'] == 1
    finally:
        executor.shutdown()
        node.destroy_node()
        test.destroy_node()
        rogue.destroy_node()
