"""The local-minimum rule (minimum_watch): the image says near, the model says far, at rest."""

from ibvs_control import minimum_watch as mw
from ibvs_control.servo_status import ServoStatus
from ibvs_model import forward_kinematics, inverse_kinematics, IRB4600, paper
import numpy as np
import pytest

TARGET = paper.target_pose()
Q_TARGET = inverse_kinematics(TARGET, IRB4600)
#: Joint 5 turned: the tool axis tilted by 40 deg.
Q_TILTED = Q_TARGET + np.radians([0.0, 0.0, 0.0, 0.0, 40.0, 0.0])
FRAME_S = 1.0 / 30.0


def frames(watch, q, image_px, seconds, start_s=0.0, feedback=None, **kwargs):
    """Offer frames at 30 fps for ``seconds``; return the last verdict."""
    feedback = np.zeros(6) if feedback is None else feedback
    verdict = None
    for k in range(int(round(seconds / FRAME_S)) + 1):
        verdict = watch.offer(start_s + k * FRAME_S, image_px, q, feedback, **kwargs)
    return verdict


def test_the_model_pose_error_is_fk_of_the_joints_against_the_target():
    position, axis = mw.model_pose_error(Q_TARGET, TARGET)
    assert position < 1e-9 and axis < 1e-6
    position, axis = mw.model_pose_error(Q_TILTED, TARGET)
    assert axis == pytest.approx(40.0, abs=0.5)
    assert mw.FAR_AXIS_DEG < axis
    assert position > 0.05  # the flange swings on its 135 mm arm from the wrist centre


def test_disagreement_needs_a_small_image_error_above_the_floor_and_a_far_pose():
    far_axis, far_position = 2.0 * mw.FAR_AXIS_DEG, 2.0 * mw.FAR_POSITION_M
    assert mw.disagree(0.41, 0.0, far_axis)
    assert mw.disagree(mw.IMAGE_NEAR_PX, far_position, 0.0)
    # the image says far too: a stall of another kind (a limit, a singularity)
    assert not mw.disagree(1.01 * mw.IMAGE_NEAR_PX, far_position, far_axis)
    # the features on their target as well as the camera tells: a model's error, not this
    assert not mw.disagree(mw.IMAGE_FLOOR_PX, far_position, far_axis)
    # near in both: a run still converging, or converged
    assert not mw.disagree(0.41, 0.5 * mw.FAR_POSITION_M, 0.5 * mw.FAR_AXIS_DEG)


def test_the_image_bounds_lie_above_the_detectors_error():
    # the detector's own error is 0.002-0.004 px (docs/speed.md)
    assert 10 * 0.004 <= mw.IMAGE_FLOOR_PX < mw.IMAGE_NEAR_PX


def test_a_loop_at_rest_in_disagreement_is_reported_after_the_window_only():
    watch = mw.MinimumWatch(TARGET)
    verdict = frames(watch, Q_TILTED, 0.41, 0.9 * mw.STALL_WINDOW_S)
    assert verdict.status == ServoStatus.NO_WARNING and not verdict.holding
    verdict = frames(watch, Q_TILTED, 0.41, 0.2 * mw.STALL_WINDOW_S,
                     start_s=0.9 * mw.STALL_WINDOW_S + FRAME_S)
    assert verdict.status == ServoStatus.LOCAL_MINIMUM and not verdict.holding
    assert '0.41 px' in verdict.detail and '40.0 deg' in verdict.detail
    image, _, axis = watch.errors
    assert image == 0.41 and axis == pytest.approx(40.0, abs=0.5)
    # the image error falls to the floor (the loop moved on and converged): over at once
    later = 2.0 * mw.STALL_WINDOW_S
    assert watch.offer(later, 0.05, Q_TILTED, np.zeros(6)).status == ServoStatus.NO_WARNING


def test_a_loop_on_its_way_is_not_at_rest():
    watch = mw.MinimumWatch(TARGET)
    for k in range(90):  # joint 1 turning 2e-3 rad a frame, 3 s long
        q = Q_TILTED + np.array([2e-3 * k, 0.0, 0.0, 0.0, 0.0, 0.0])
        verdict = watch.offer(k * FRAME_S, 0.41, q, np.zeros(6))
        assert verdict.status == ServoStatus.NO_WARNING
    # the law's own output moving counts as well: its step has not stalled
    watch = mw.MinimumWatch(TARGET)
    for k in range(90):
        verdict = watch.offer(k * FRAME_S, 0.41, Q_TILTED, np.full(6, 2e-3 * k))
        assert verdict.status == ServoStatus.NO_WARNING


def test_a_frame_the_features_were_not_measured_for_starts_the_window_again():
    watch = mw.MinimumWatch(TARGET)
    frames(watch, Q_TILTED, 0.41, 0.9 * mw.STALL_WINDOW_S)
    watch.offer(0.95 * mw.STALL_WINDOW_S, 0.41, Q_TILTED, np.zeros(6), measured=False)
    verdict = frames(watch, Q_TILTED, 0.41, 0.5 * mw.STALL_WINDOW_S, start_s=mw.STALL_WINDOW_S)
    assert verdict.status == ServoStatus.NO_WARNING


def test_at_the_target_nothing_is_reported_whatever_the_image_error():
    watch = mw.MinimumWatch(TARGET)
    for image_px in (0.0, 0.41, 5.0):
        assert frames(watch, Q_TARGET, image_px, 2.0).status == ServoStatus.NO_WARNING


def test_the_model_robot_is_the_one_given():
    # The same joints are far for the nominal robot's target and near for a robot whose
    # FK puts the flange there (the watch compares FK of the model it is given).
    scaled = IRB4600.scaled(l2_scale=1.05)
    watch = mw.MinimumWatch(forward_kinematics(Q_TILTED, scaled), scaled)
    assert frames(watch, Q_TILTED, 0.41, 2.0).status == ServoStatus.NO_WARNING
    watch = mw.MinimumWatch(forward_kinematics(Q_TILTED, scaled))
    assert frames(watch, Q_TILTED, 0.41, 2.0).status == ServoStatus.LOCAL_MINIMUM
