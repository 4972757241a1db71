"""
joint_controller_node (position interface) against its clock: a jump back, a /clock that stops.

In an rclpy executor, through the ``position_cell`` of this directory's conftest.py: a test
node plays the feedforward, the camera (its camera_info), the q_feedback, the arm's
/joint_states and /clock, and records the commands, /ibvs/servo_status and /diagnostics.
"""

from diagnostic_msgs.msg import DiagnosticStatus
from ibvs_common import contract, sim_time
from ibvs_common.conversions import joint_state, joint_trajectory, ns_stamp
from ibvs_control.joint_controller_node import JointControllerNode
from ibvs_control.servo_status import ServoStatus
from ibvs_model import inverse_kinematics, paper
from ibvs_testing.fixtures import spin_until
import numpy as np
import pytest
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

MS = 1_000_000
S = 1000 * MS
Q0 = inverse_kinematics(paper.scenario_start_pose(1))
TICK_NS = 4 * MS  # the command period at 250 Hz


@pytest.mark.parametrize('command_type', ['forward_command', 'joint_trajectory'])
def test_a_clock_set_back_holds_at_once_says_why_and_resumes_on_fresh_inputs(
        monkeypatch, position_cell, command_type):
    """Acceptance: /clock 5 s back, inputs stopped: hold at the jump; fresh inputs: servo."""
    # the test stands still waiting for /diagnostics: not a stopped clock here
    monkeypatch.setattr(sim_time, 'CLOCK_STALL_MIN_S', 1e6)
    cell = position_cell(command_type)
    t0 = 10 * S
    target = Q0.copy()
    target[0] += 1.0  # a long move: under way when the clock jumps
    cell.start(t0, target)
    t = t0
    for _ in range(30):
        t += TICK_NS
        cell.tick(t)
    assert cell.status[-1] == ServoStatus.NO_WARNING
    moving = cell.commands[-1][0] - cell.commands[-2][0]
    assert moving > 0.0, 'the arm is under way'
    # the clock is set back 5 s (a restarted simulator, an NTP step); no input after it
    t -= 5 * S
    commands = len(cell.commands)
    cell.clock(t)
    cell.spin_to_status(ServoStatus.HOLD_CLOCK_JUMPED_BACK)  # at the jump's own /clock
    assert len(cell.commands) <= commands + 1
    spin_until(cell.executor, lambda: any(
        'clock jumped back from 10.120 s to 5.120 s' in s.message
        and s.level == DiagnosticStatus.WARN for s in cell.diagnostics),
        what='the reason on /diagnostics')
    for _ in range(150):  # 0.6 s of the new time line with no input: the arm holds
        t += TICK_NS
        cell.tick(t, inputs=False)
    assert set(cell.status[cell.status.index(ServoStatus.HOLD_CLOCK_JUMPED_BACK):]) == {
        ServoStatus.HOLD_CLOCK_JUMPED_BACK}
    held = np.array(cell.commands[-50:])
    assert np.ptp(held, axis=0).max() < 1e-9, 'the arm holds still'
    assert held[-1, 0] < target[0] - 0.1, 'stopped short of the target'
    # fresh inputs on the new time line are taken, not refused as out of order
    cell.next_frame = None
    for _ in range(20):
        t += TICK_NS
        cell.tick(t)
    cell.spin_to_status(ServoStatus.NO_WARNING)
    assert cell.rejected('out of order') == 0 and cell.rejected('stamp') == 0
    for _ in range(20):
        t += TICK_NS
        cell.tick(t)
    assert cell.commands[-1][0] > held[-1, 0], 'servoing resumed toward the target'
    assert cell.node.diagnostics.values['clock_jumps_back'] == 1


def test_a_stopped_clock_holds_after_its_wall_bound_and_resumes_when_it_moves(
        monkeypatch, position_cell):
    """Acceptance: a /clock that stops (a dead simulator) is not read as healthy."""
    monkeypatch.setattr(sim_time, 'CLOCK_STALL_MIN_S', 0.5)  # the test's wall bound
    cell = position_cell('forward_command')
    t = 0
    cell.start(t, Q0)
    for _ in range(20):
        t += TICK_NS
        cell.tick(t)
    assert cell.status[-1] == ServoStatus.NO_WARNING
    commands = len(cell.commands)
    cell.spin_to_status(ServoStatus.HOLD_CLOCK_STOPPED)  # no /clock from here on
    assert len(cell.commands) == commands  # sim time stood still: no command either
    assert cell.node.mode._clock.stalled_s() > 0.5
    spin_until(cell.executor, lambda: any(
        s.message.startswith('clock stopped: /clock has not moved for')
        and s.level == DiagnosticStatus.WARN for s in cell.diagnostics),
        what='the reason on /diagnostics')
    for _ in range(5):
        t += TICK_NS
        cell.tick(t)
    cell.spin_to_status(ServoStatus.NO_WARNING)


def test_the_effort_interface_answers_a_restarted_simulators_steps_from_the_start(
        controller_rig):
    """Lockstep: /clock back to 0 with the simulator's restart; its steps are answered."""
    rig = controller_rig('simulator', (contract.CLOCK, contract.JOINT_STATES,
                                       contract.Q_FEEDBACK, contract.FEEDFORWARD_TRAJECTORY),
                         use_sim_time=True)
    node, pubs = rig.node, rig.pubs
    efforts = rig.record(JointState, contract.EFFORT_COMMANDS)
    executor = rig.spin_up()
    pubs[contract.FEEDFORWARD_TRAJECTORY].publish(joint_trajectory(0, MS, [Q0] * 10))

    def run_from_zero(count):
        pubs[contract.Q_FEEDBACK].publish(joint_state(0, np.zeros(6)))
        for k in range(3):
            pubs[contract.JOINT_STATES].publish(joint_state(k * MS, Q0, np.zeros(6)))
            spin_until(executor, lambda k=k: len(efforts) == count + k + 1,
                       what=f'the answer to step {k}')

    for t in (0, MS, 2 * MS):
        pubs[contract.CLOCK].publish(Clock(clock=ns_stamp(t)))
    run_from_zero(0)
    pubs[contract.CLOCK].publish(Clock(clock=ns_stamp(0)))  # the simulator restarts
    spin_until(executor, lambda: sim_time.clock_watch(node).jumps_back == 1,
               what='the jump back')
    run_from_zero(3)
    assert [e.header.stamp.nanosec for e in efforts] == [0, MS, 2 * MS] * 2
    assert not node.diagnostics.rejections


def test_the_lockstep_effort_interface_never_looks_at_a_stopped_clock(context):
    """The lockstep's simulator waits for the controllers: its /clock may stand still."""
    node = JointControllerNode(context=context, parameter_overrides=[
        Parameter('use_sim_time', value=True)])
    try:
        assert node.config.interface.command_interface == 'effort'
        assert node.config.interface.lockstep
        assert not hasattr(node.mode, '_check_clock')
    finally:
        node.destroy_node()
