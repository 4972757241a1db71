"""
joint_controller_node against a second publisher on its inputs or its own command topic.

In an rclpy executor, through the ``position_cell`` of this directory's conftest.py: a test
node plays the feedforward, the camera (its camera_info), the q_feedback, the arm's
/joint_states and /clock, and records the commands, /ibvs/servo_status and /diagnostics; a
node 'rogue' comes with a publisher of its own on one topic, and goes.
"""

import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from ibvs_common import contract, sim_time
from ibvs_common.conversions import joint_state, joint_trajectory
from ibvs_control.servo_status import ServoStatus
from ibvs_model import inverse_kinematics, paper
from ibvs_testing.fixtures import spin_until
import numpy as np
import pytest
from rclpy.node import Node
from sensor_msgs.msg import JointState

MS = 1_000_000
S = 1000 * MS
Q0 = inverse_kinematics(paper.scenario_start_pose(1))
TICK_NS = 4 * MS  # the command period at 250 Hz


@pytest.fixture
def cell(monkeypatch, position_cell):
    monkeypatch.setattr(sim_time, 'CLOCK_STALL_MIN_S', 1e6)  # it stands still at times
    made = position_cell()
    t0 = 10 * S
    target = Q0.copy()
    target[0] += 1.0  # a long move: under way when the rogue comes
    made.start(t0, target)
    watch = made.node.diagnostics.publishers
    spin_until(made.executor, lambda: len(watch.expected) == 6 and all(
        e.settled for e in watch.expected.values()),
        what="the inputs' publishers seen once")  # the cell's, before any rogue
    made.t = t0
    made.target = target
    for _ in range(30):
        made.t += TICK_NS
        made.tick(made.t)
    assert made.status[-1] == ServoStatus.NO_WARNING
    return made


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


def test_the_effort_interface_reports_a_second_commander_and_answers_as_before(
        context, controller_rig):
    """Lockstep: a second publisher of effort commands is named and counted, not held on."""
    rig = controller_rig('simulator', (contract.CLOCK, contract.JOINT_STATES,
                                       contract.Q_FEEDBACK, contract.FEEDFORWARD_TRAJECTORY),
                         use_sim_time=True)
    node, pubs = rig.node, rig.pubs
    efforts, statuses = rig.record(JointState, contract.EFFORT_COMMANDS), []
    rig.test.create_subscription(DiagnosticArray, contract.DIAGNOSTICS,
                                 lambda m: statuses.extend(m.status), 10)
    rogue = Node('rogue', context=context)
    executor = rig.spin_up()
    try:
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
        rogue.destroy_node()
