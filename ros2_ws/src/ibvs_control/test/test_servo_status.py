"""The joint controller's input watch and status codes (ibvs_control.servo_status), pure."""

from ibvs_control.servo_status import HOLD_CODES, InputWatch, ServoStatus
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


def test_bad_configurations_are_refused():
    with pytest.raises(ValueError, match='unknown input'):
        InputWatch({'lidar': MS})
    with pytest.raises(ValueError, match='must be > 0'):
        InputWatch({'camera': 0})
