"""The joint controller's input watch and status codes (ibvs_control.servo_status), pure."""

from ibvs_common.publishers import Publisher
from ibvs_control.servo_status import (clock_stopped, FeedbackStatus, HOLD_CODES, HOLDING,
                                       InputWatch, second_publisher, ServoStatus, Verdict)
import pytest

MS = 1_000_000


def watch():
    return InputWatch({'joint_states': 100 * MS, 'camera': 300 * MS, 'feedback': 300 * MS},
                      required=('feedforward',))


def test_moveit_servo_codes_are_kept_and_ours_do_not_collide():
    """A supervisor written for MoveIt Servo's StatusCode reads 0-6 and -1 as Servo does."""
    assert [(c.name, c.value) for c in ServoStatus if c.value < 10] == [
        ('INVALID', -1), ('NO_WARNING', 0), ('DECELERATE_FOR_APPROACHING_SINGULARITY', 1),
        ('HALT_FOR_SINGULARITY', 2), ('DECELERATE_FOR_LEAVING_SINGULARITY', 3),
        ('DECELERATE_FOR_COLLISION', 4), ('HALT_FOR_COLLISION', 5), ('JOINT_BOUND', 6)]
    assert all(-128 <= c.value <= 127 for c in ServoStatus)  # std_msgs/Int8


def test_waiting_until_every_input_came_once_naming_them():
    w = watch()
    verdict = w.verdict(0)
    assert verdict.status == ServoStatus.WAITING and not verdict.holding
    assert verdict.detail == 'waiting for feedforward, joint_states, camera, feedback'
    w.heard('feedforward', 0)
    w.heard('joint_states', 0)
    w.heard('camera', 0)
    assert w.verdict(0).detail == 'waiting for feedback'
    w.heard('feedback', 0)
    assert w.verdict(0).status == ServoStatus.NO_WARNING


@pytest.mark.parametrize('stale, code', [
    ('joint_states', ServoStatus.HOLD_STALE_JOINT_STATES),
    ('camera', ServoStatus.HOLD_STALE_CAMERA),
    ('feedback', ServoStatus.HOLD_STALE_FEEDBACK)])
def test_the_stale_input_is_named_just_after_its_timeout(stale, code):
    w = watch()
    w.heard('feedforward', 0)
    for name in HOLD_CODES:
        w.heard(name, 0)
    timeout = w.timeouts_ns[stale]
    for name in HOLD_CODES:
        if name != stale:
            w.heard(name, timeout + 1)
    assert w.verdict(timeout).status == ServoStatus.NO_WARNING
    verdict = w.verdict(timeout + 1)
    assert verdict.status == code and verdict.holding and stale in verdict.detail
    w.heard(stale, timeout + 1)  # fresh again: resumes
    assert w.verdict(timeout + 1).status == ServoStatus.NO_WARNING


def test_joint_states_take_precedence_and_an_old_stamp_does_not_rejuvenate():
    w = watch()
    w.heard('feedforward', 0)
    for name in HOLD_CODES:
        w.heard(name, 0)
    assert w.verdict(400 * MS).status == ServoStatus.HOLD_STALE_JOINT_STATES
    w.heard('joint_states', 400 * MS)
    w.heard('joint_states', 10 * MS)  # late, older: the newest stays
    assert w.verdict(400 * MS).status == ServoStatus.HOLD_STALE_CAMERA


def position_watch():
    """Return the position controller's watch: the camera and the q_feedback follow the start."""
    return InputWatch({'joint_states': 100 * MS, 'camera': 300 * MS, 'feedback': 300 * MS},
                      required=('feedforward',), after_start=('camera', 'feedback'))


def test_the_move_starts_without_waiting_for_the_inputs_that_follow_the_start():
    w = position_watch()
    w.heard('feedforward', 0)
    assert w.verdict(0).detail == 'waiting for joint_states'
    assert w.missing() == ['joint_states', 'camera', 'feedback']  # all of them, for tests
    w.heard('joint_states', 20 * MS)
    assert w.verdict(20 * MS).status == ServoStatus.NO_WARNING  # the start: at 20 ms
    assert w.start_ns == 20 * MS and w.awaited() == []
    w.heard('joint_states', 320 * MS)
    w.heard('camera', 300 * MS)  # the first frame, 280 ms after the start
    assert w.verdict(320 * MS).status == ServoStatus.NO_WARNING
    verdict = w.verdict(321 * MS)  # no q_feedback within 300 ms of the start: hold
    assert verdict.status == ServoStatus.HOLD_STALE_FEEDBACK
    assert verdict.detail == ('feedback stale: none in the 0.301 s since the start '
                              '(timeout 0.3 s): holding the arm')
    w.heard('feedback', 321 * MS)
    assert w.verdict(321 * MS).status == ServoStatus.NO_WARNING


def test_an_input_that_follows_the_start_and_never_comes_holds_once_past_its_timeout():
    w = position_watch()
    w.heard('feedforward', 0)
    w.heard('joint_states', 0)
    assert w.verdict(0).status == ServoStatus.NO_WARNING
    w.heard('joint_states', 300 * MS)
    assert w.verdict(300 * MS).status == ServoStatus.NO_WARNING
    w.heard('joint_states', 301 * MS)
    assert w.verdict(301 * MS).status == ServoStatus.HOLD_STALE_CAMERA  # first in order
    # a jump back: a new start on the new time line, and every timed input again
    w.forget(301 * MS, 0)
    w.heard('joint_states', 10 * MS)
    assert w.verdict(10 * MS).detail.endswith('until fresh camera, feedback')
    assert w.start_ns == 10 * MS


def test_bad_configurations_are_refused():
    with pytest.raises(ValueError, match='unknown input'):
        InputWatch({'lidar': MS})
    with pytest.raises(ValueError, match='must be > 0'):
        InputWatch({'camera': 0})
    with pytest.raises(ValueError, match='has no timeout'):
        InputWatch({'camera': MS}, after_start=('feedback',))


def started(t_ns=0):
    w = watch()
    w.heard('feedforward', 0)
    for name in HOLD_CODES:
        w.heard(name, t_ns)
    return w


def test_a_clock_jumped_back_holds_at_once_until_each_input_came_again():
    w = started(5_000 * MS)
    assert w.verdict(5_050 * MS).status == ServoStatus.NO_WARNING
    w.forget(5_050 * MS, 50 * MS)  # 5 s back: the old ages would be negative
    verdict = w.verdict(50 * MS)
    assert verdict.status == ServoStatus.HOLD_CLOCK_JUMPED_BACK and verdict.holding
    assert verdict.detail == ('clock jumped back from 5.050 s to 0.050 s: holding the arm '
                              'until fresh joint_states, camera, feedback')
    assert ServoStatus.HOLD_CLOCK_JUMPED_BACK >= 10
    # inputs stopped: the hold stays, whatever the clock does next
    assert w.verdict(5_000 * MS).status == ServoStatus.HOLD_CLOCK_JUMPED_BACK
    w.heard('joint_states', 60 * MS)
    w.heard('camera', 60 * MS)
    assert w.verdict(60 * MS).detail.endswith('until fresh feedback')
    w.heard('feedback', 60 * MS)
    assert w.verdict(60 * MS).status == ServoStatus.NO_WARNING
    # ages count on the new time line: the joint states go stale 100 ms after 60 ms
    assert w.verdict(161 * MS).status == ServoStatus.HOLD_STALE_JOINT_STATES


def test_a_jump_before_every_input_came_still_waits_and_names_them():
    w = watch()
    w.heard('feedforward', 0)
    w.heard('joint_states', 5_000 * MS)
    w.forget(5_000 * MS, 0)
    assert w.verdict(0).detail == 'waiting for camera, feedback'
    w.heard('camera', 0)
    w.heard('feedback', 0)
    assert w.verdict(0).detail.endswith('until fresh joint_states')  # the old one is not


def test_a_stopped_clock_holds_once_past_its_wall_bound():
    assert clock_stopped(None, 2.0) is None  # /clock never moved: nothing to hold yet
    assert clock_stopped(2.0, 2.0) is None
    verdict = clock_stopped(2.5, 2.0)
    assert verdict.status == ServoStatus.HOLD_CLOCK_STOPPED and verdict.holding
    assert verdict.detail.startswith('clock stopped: /clock has not moved for 2.5 s')
    assert ServoStatus.HOLD_CLOCK_STOPPED >= 10


def test_a_second_publisher_holds_naming_each_topic_and_node():
    assert second_publisher({}) is None
    assert second_publisher({'/joint_states': []}) is None
    verdict = second_publisher({'/fwd/commands': [Publisher('/rogue')],
                                '/joint_states': [Publisher('/a'), Publisher('/b')]})
    assert verdict.status == ServoStatus.HOLD_SECOND_PUBLISHER == 16 and verdict.holding
    assert ServoStatus.HOLD_SECOND_PUBLISHER in HOLDING
    assert verdict.detail == ('second publisher on /fwd/commands: /rogue; second publisher on '
                              '/joint_states: /a, /b: holding the arm until it is gone')


def test_the_feedback_nodes_local_minimum_is_relayed_only_when_nothing_else_is_said():
    status = FeedbackStatus()
    ok = Verdict(ServoStatus.NO_WARNING, 'ok')
    assert status.over(ok) is ok
    assert status.take(int(ServoStatus.LOCAL_MINIMUM)) and not status.take(17)
    relayed = status.over(ok)
    assert relayed.status == ServoStatus.LOCAL_MINIMUM == 17 and not relayed.holding
    assert 'local minimum' in relayed.detail
    # a hold, or waiting, is the controller's own and comes first
    hold = Verdict(ServoStatus.HOLD_STALE_CAMERA, 'camera stale')
    assert status.over(hold) is hold
    waiting = Verdict(ServoStatus.WAITING, 'waiting for camera')
    assert status.over(waiting) is waiting
    assert status.take(int(ServoStatus.NO_WARNING)) and status.over(ok) is ok


def test_a_code_the_feedback_node_never_reports_is_refused_naming_the_allowed():
    status = FeedbackStatus()
    for code in (int(ServoStatus.HOLD_STALE_CAMERA), 99, -1):
        with pytest.raises(ValueError, match='LOCAL_MINIMUM'):
            status.take(code)
    assert status.status == ServoStatus.NO_WARNING
