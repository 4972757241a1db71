"""The camera's stamp offset found from the encoders (ibvs_vision.stamp_offset), no ROS."""

from ibvs_model import CameraRobotModel, default_camera, IRB4600
from ibvs_vision import stamp_offset
from ibvs_vision.stamp_offset import fit_stamp_offset, StampOffsetEstimator
import numpy as np
import pytest

MS = 1_000_000
PERIOD_NS = 33_333_333
MODEL = CameraRobotModel(default_camera(), IRB4600)
Q0 = np.array([0.0, 0.1, 0.2, 0.0, 0.6, 0.0])
MOVE = np.array([0.5, 0.15, -0.1, 0.2, 0.1, 0.3])
#: What the model does not know of the arm (joint offsets, as the rehearsal's
#: disturbance_deg): the model's error changes with the pose.
OFFSETS = np.radians([0.1, 0.5, 0.2, 0.3, -0.1, 0.3])


def smooth_move(t_s, start_s=0.2, span_s=0.8):
    """Rest, a smoothstep move of span_s, rest."""
    x = np.clip((t_s - start_s) / span_s, 0.0, 1.0)
    return Q0 + MOVE * (x * x * (3.0 - 2.0 * x))


def encoders(q_of, rate_hz=250.0, until_s=4.0):
    """Return joints_at over 250 Hz joint states interpolated linearly, as JointTrack does."""
    stamps = np.arange(0, int(until_s * 1e9), int(1e9 / rate_hz))
    qs = np.array([q_of(t * 1e-9) for t in stamps])

    def joints_at(t_ns):
        if not stamps[0] <= t_ns <= stamps[-1]:
            return None
        return np.array([np.interp(t_ns, stamps, qs[:, j]) for j in range(6)])
    return joints_at


def frames(q_of, offset_ns, exposures_s, noise_px=0.2, seed=0):
    """Measured features of frames exposed at exposures_s, stamped offset_ns after."""
    rng = np.random.default_rng(seed)
    stamps = [int(round(e * 1e9)) + offset_ns for e in exposures_s]
    features = np.array([MODEL.features(q_of(e) + OFFSETS) for e in exposures_s])
    return stamps, features + rng.normal(0.0, noise_px, features.shape)


@pytest.mark.parametrize('offset_ms', [33, -20, 0])
def test_a_window_of_motion_gives_the_offset_within_a_millisecond(offset_ms):
    exposures = np.arange(0.2, 1.2, 1 / 30)
    stamps, features = frames(smooth_move, offset_ms * MS, exposures)
    fit = fit_stamp_offset(stamps, features, encoders(smooth_move), MODEL.features_batch)
    assert abs(fit.offset_ns - offset_ms * MS) < 1 * MS
    assert 0 < fit.sd_ns < 1 * MS and fit.frames == len(stamps)
    assert fit.excitation_px_s > stamp_offset.MIN_EXCITATION_PX_S


def test_a_frame_far_off_the_others_is_left_out():
    exposures = np.arange(0.2, 1.2, 1 / 30)
    stamps, features = frames(smooth_move, 33 * MS, exposures)
    features[7] += 25.0  # a blob taken for a marker
    fit = fit_stamp_offset(stamps, features, encoders(smooth_move), MODEL.features_batch)
    assert abs(fit.offset_ns - 33 * MS) < 1 * MS and fit.frames == len(stamps) - 1
    kept_in = fit_stamp_offset(stamps, features, encoders(smooth_move), MODEL.features_batch,
                               outliers_out=False)
    assert kept_in.frames == len(stamps)


def test_uniform_motion_cannot_tell_an_offset_from_a_bias():
    """A straight line shifted in time is a line: no excitation, no estimate."""
    def uniform(t_s):
        return Q0 + MOVE * 0.2 * t_s
    est = StampOffsetEstimator(1000 * MS, PERIOD_NS)
    joints_at = encoders(uniform)
    stamps, features = frames(uniform, 33 * MS, np.arange(0.3, 1.5, 1 / 30), noise_px=0.0)
    for t, s in zip(stamps, features):
        est.offer(t, s)
        state = est.update(joints_at, MODEL.features_batch, 8.3)
    assert state.estimate_ns is None and state.state == 'waiting for the tool to move'
    assert state.excitation_px_s < stamp_offset.MIN_EXCITATION_PX_S
    assert est.advance() == 0


def test_the_estimate_is_held_while_the_tool_is_still_and_applied_in_quarter_periods():
    est = StampOffsetEstimator(1000 * MS, PERIOD_NS)
    joints_at = encoders(smooth_move)
    stamps, features = frames(smooth_move, 33 * MS, np.arange(0.3, 3.5, 1 / 30))
    applied, states = [], []
    for t, s in zip(stamps, features):
        est.offer(t, s)
        states.append(est.update(joints_at, MODEL.features_batch, 8.3))
        applied.append(est.advance())
    assert abs(states[-1].estimate_ns - 33 * MS) < 2 * MS
    assert states[-1].state == 'holding: the tool is still'
    steps = np.diff([0] + applied)
    assert np.all(np.abs(steps) <= PERIOD_NS // 4) and applied[-1] == states[-1].estimate_ns
    corrected = np.array(stamps) - np.array(applied)
    assert np.all(np.diff(corrected) >= 3 * PERIOD_NS // 4 - 1)  # in order, a frame apart


def test_one_joint_state_a_frame_is_not_estimated_from():
    """The simulator's lockstep: the frames' own states, at their exposures, and no others."""
    est = StampOffsetEstimator(1000 * MS, PERIOD_NS, initial_ns=5 * MS)
    stamps, features = frames(smooth_move, 0, np.arange(0.3, 1.5, 1 / 30))
    for t, s in zip(stamps, features):
        est.offer(t, s)
        state = est.update(encoders(smooth_move), MODEL.features_batch, 1.0)
    assert state.state.startswith('not estimated: joint states a frame 1.0')
    assert state.estimate_ns is None and est.advance() == 5 * MS  # the initial one, kept


def test_an_initial_offset_is_applied_from_the_first_frame_and_refined():
    est = StampOffsetEstimator(1000 * MS, PERIOD_NS, initial_ns=30 * MS)
    assert est.advance() == 30 * MS
    joints_at = encoders(smooth_move)
    stamps, features = frames(smooth_move, 33 * MS, np.arange(0.3, 2.0, 1 / 30))
    for t, s in zip(stamps, features):
        est.offer(t, s)
        est.update(joints_at, MODEL.features_batch, 8.3)
        est.advance()
    assert abs(est.applied_ns - 33 * MS) < 2 * MS and est.fits > 0
