"""The hand-eye solver on synthetic measurements: the features the true camera projects."""

import math

from ibvs_model import default_camera, handeye, StereoCamera
from ibvs_sim.camera_effects import calibrated_pose
import numpy as np
import pytest

#: A calibration error of 10 mm and 1 deg (the nominal camera is the true one moved by it).
ERROR_XYZ_M = (0.006, -0.008, 0.0)
ERROR_RPY_DEG = (0.6, 0.0, -0.8)


def cameras():
    """Return (true camera, nominal camera): the paper's, and it with the error."""
    true = default_camera('HD720')
    nominal = StereoCamera(true.intrinsics,
                           calibrated_pose(true.pose_C_O, ERROR_XYZ_M, ERROR_RPY_DEG))
    return true, nominal


def measurements(count, seed=0, noise_px=0.0):
    """Return (true camera, nominal camera, joints, features) of ``count`` drawn poses."""
    true, nominal = cameras()
    joints = handeye.draw_poses(nominal, count, seed)
    features = np.array([true.project(handeye.marker_points([q])[0]).reshape(6)
                         for q in joints])
    rng = np.random.default_rng(seed + 100)
    return true, nominal, joints, features + rng.normal(0.0, noise_px, features.shape)


def errors(reference, pose):
    shift, angle = handeye.pose_difference(reference, pose)
    return np.linalg.norm(shift), angle


def test_the_nominal_camera_carries_the_error_to_recover():
    true, nominal = cameras()
    shift, angle = errors(true.pose_C_O, nominal.pose_C_O)
    assert shift == pytest.approx(0.010, abs=1e-12) and angle == pytest.approx(1.0, abs=1e-5)


def test_noise_free_features_give_the_true_camera_exactly():
    true, nominal, joints, features = measurements(12)
    start = handeye.initial_pose(true.intrinsics, joints, features)
    shift, angle = errors(true.pose_C_O, start)  # Kabsch alone, no guess: exact too
    assert shift < 1e-9 and angle < 1e-7
    result = handeye.solve(true.intrinsics, joints, features)
    shift, angle = errors(true.pose_C_O, result.pose_C_O)
    assert shift < 1e-9 and angle < 1e-7
    assert result.rms_px < 1e-8 and result.dropped == () and len(result.used) == 12
    # From the nominal camera as the start, the same.
    again = handeye.solve(true.intrinsics, joints, features, start=nominal.pose_C_O)
    assert errors(true.pose_C_O, again.pose_C_O)[0] < 1e-9


def test_a_hundredth_of_a_pixel_of_noise_stays_within_its_uncertainty_and_the_bounds():
    true, _, joints, features = measurements(12, noise_px=0.01)
    result = handeye.solve(true.intrinsics, joints, features)
    shift, angle = errors(true.pose_C_O, result.pose_C_O)
    assert shift < 1e-3 and angle < 0.1  # the acceptance's bounds, by far
    assert result.rms_px == pytest.approx(0.01, rel=0.3)
    # The error along and about each axis of {C} within 4 sigma of its estimated spread.
    diff = np.linalg.inv(true.pose_C_O) @ result.pose_C_O
    from scipy.spatial.transform import Rotation
    rotation = Rotation.from_matrix(diff[:3, :3]).as_rotvec()
    assert np.all(np.abs(diff[:3, 3]) < 4.0 * result.sigma_position_m)
    assert np.all(np.abs(rotation) < 4.0 * result.sigma_rotation_rad)
    assert np.all(result.sigma_position_m < 1e-4)


def test_the_uncertainty_shrinks_with_the_number_of_poses():
    sigmas = []
    for count in (6, 24, 96):
        true, _, joints, features = measurements(count, seed=count, noise_px=0.01)
        result = handeye.solve(true.intrinsics, joints, features)
        sigmas.append((np.linalg.norm(result.sigma_position_m),
                       np.linalg.norm(result.sigma_rotation_rad)))
    sigmas = np.array(sigmas)
    assert np.all(np.diff(sigmas, axis=0) < 0.0)
    # About 1 / sqrt(N): 16 times the poses, a quarter of the spread (within a factor 2).
    assert np.all(sigmas[2] / sigmas[0] < 0.5)


def test_a_pose_that_disagrees_with_the_others_is_dropped():
    true, _, joints, features = measurements(12, noise_px=0.005)
    features[4, 3] += 5.0  # a sphere measured 5 px off: a mismatch
    result = handeye.solve(true.intrinsics, joints, features)
    assert result.dropped == (4,) and 4 not in result.used
    assert result.pose_rms_px[4] > 1.0
    shift, angle = errors(true.pose_C_O, result.pose_C_O)
    assert shift < 1e-4 and angle < 0.01
    assert any('dropped' in line and 'pose 4' in line for line in handeye.describe(result))


def test_too_few_or_alike_poses_are_refused_in_words():
    true, _, joints, features = measurements(4)
    with pytest.raises(handeye.CalibrationError, match='at least 3'):
        handeye.solve(true.intrinsics, joints[:2], features[:2])
    same = np.repeat(joints[:1], 4, axis=0)
    with pytest.raises(handeye.CalibrationError, match='one line'):
        handeye.solve(true.intrinsics, same, np.repeat(features[:1], 4, axis=0))
    with pytest.raises(handeye.CalibrationError, match='finite'):
        handeye.solve(true.intrinsics, joints, features * np.nan)
    with pytest.raises(handeye.CalibrationError, match='at least 3'):
        handeye.draw_poses(true, 2)


def test_drawn_poses_repeat_with_their_seed_and_keep_the_spheres_in_view():
    _, nominal = cameras()
    a, b = handeye.draw_poses(nominal, 8, seed=5), handeye.draw_poses(nominal, 8, seed=5)
    assert a.tobytes() == b.tobytes()
    assert not np.array_equal(a, handeye.draw_poses(nominal, 8, seed=6))
    for q in a:
        assert nominal.in_view(handeye.marker_points([q])[0]).all()


def test_pose_values_are_the_camera_pose_parameter():
    from ibvs_common.shared_params import camera_pose_from
    true, _ = cameras()
    values = handeye.pose_values(true.pose_C_O)
    assert len(values) == 7 and values[6] >= 0.0
    assert math.isclose(np.linalg.norm(values[3:]), 1.0, abs_tol=1e-12)
    assert np.allclose(camera_pose_from({'camera_pose': values}), true.pose_C_O, atol=1e-12)


def hold_and_move(holds, hold_s=1.0, move_s=0.5, rate_hz=100.0):
    """Return (t, q) of an arm that holds each pose of ``holds`` and moves between them."""
    t, q, now = [], [], 0.0
    dt = 1.0 / rate_hz
    for i, pose in enumerate(holds):
        for _ in range(int(hold_s * rate_hz)):
            t.append(now)
            q.append(pose)
            now += dt
        if i + 1 < len(holds):
            steps = int(move_s * rate_hz)
            for k in range(steps):
                t.append(now)
                q.append(pose + (holds[i + 1] - pose) * (k + 1) / steps)
                now += dt
    return np.array(t), np.array(q)


def test_stations_are_the_poses_the_arm_held_still():
    true, _, joints, features = measurements(3)
    joint_t, joint_q = hold_and_move(joints)
    frame_t = np.arange(0.0, joint_t[-1], 1.0 / 30.0)
    q_at = np.array([[np.interp(t, joint_t, joint_q[:, i]) for i in range(6)]
                     for t in frame_t])
    frame_p = np.array([true.project(handeye.marker_points([q])[0]).reshape(6)
                        for q in q_at])
    found = handeye.stations(frame_t, frame_p, joint_t, joint_q)
    assert len(found.frames) == 3
    assert np.allclose(found.joints, joints, atol=1e-12)
    assert np.allclose(found.features, features, atol=1e-9)
    assert np.all(found.frames >= handeye.MIN_STATION_FRAMES)
    assert np.all(found.spread_px < 1e-9)
    # A hold shorter than the still window either side of a frame gives no station.
    short = handeye.stations(frame_t, frame_p, joint_t, joint_q, window_s=0.6)
    assert len(short.frames) == 0
    # A slow drift within the tolerance is still; beyond it, not.
    drift = joint_q + np.outer(joint_t, np.full(6, 1e-5))
    assert len(handeye.stations(frame_t, frame_p, joint_t, drift).frames) == 3
    assert len(handeye.stations(frame_t, frame_p, joint_t, drift,
                                still_tol_rad=1e-6).frames) == 0


def test_encoder_offsets_are_no_outliers_but_a_residual_it_warns_of():
    true, _, joints, features = measurements(12)
    offsets = np.radians([0.1, 0.5, 0.2, 0.3, -0.1, 0.3])  # scenario 1's d_q
    seen = np.array([true.project(handeye.marker_points([q + offsets])[0]).reshape(6)
                     for q in joints])
    result = handeye.solve(true.intrinsics, joints, seen)
    assert result.dropped == () and result.rms_px > handeye.RESIDUAL_WARN_PX
    assert any(line.startswith('warning:') for line in handeye.describe(result))
    assert not any(line.startswith('warning:') for line in handeye.describe(
        handeye.solve(true.intrinsics, joints, features)))
