"""A real camera's imperfections: image noise, frame drops and calibration error (pure)."""

import math

from ibvs_common.params import ParameterError
from ibvs_model import look_at, paper, StereoIntrinsics
from ibvs_sim.camera_effects import (add_image_noise, calibrated_intrinsics, calibrated_pose,
                                     CameraEffects, error_transform)
from ibvs_sim.node_params import SimConfig
from ibvs_sim.simulator import Simulator
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

#: Standard deviation of rounding to 8 bits, intensity units (uniform over one level).
QUANTISATION_STD = 1.0 / 255.0 / math.sqrt(12.0)


@pytest.mark.parametrize('stddev', [0.005, 0.01, 0.05])
def test_noise_has_the_set_standard_deviation_and_zero_mean(stddev):
    # A mid-grey HD720 image: no pixel is near 0 or 1, so nothing is clipped.
    image = np.full((720, 1280, 3), 128, dtype=np.uint8)
    noisy = add_image_noise(image, stddev, np.random.default_rng(7))
    assert noisy.dtype == np.uint8 and noisy.shape == image.shape
    diff = (noisy.astype(float) - image) / 255.0
    # Rounding to 8 bits adds a uniform quantisation error (module docstring).
    expected = math.hypot(stddev, QUANTISATION_STD)
    assert abs(diff.std() / stddev - 1.0) < 0.05
    assert diff.std() == pytest.approx(expected, rel=0.01)
    # zero mean: within 5 standard errors of the sample mean
    assert abs(diff.mean()) < 5.0 * expected / math.sqrt(diff.size)
    # independent per pixel and per channel: no correlation between neighbours or channels
    assert abs(np.corrcoef(diff[:, :-1, 0].ravel(), diff[:, 1:, 0].ravel())[0, 1]) < 0.01
    assert abs(np.corrcoef(diff[..., 0].ravel(), diff[..., 1].ravel())[0, 1]) < 0.01


def test_noise_is_clipped_to_the_valid_range():
    image = np.zeros((200, 200, 3), dtype=np.uint8)
    image[:, 100:] = 255
    noisy = add_image_noise(image, 0.05, np.random.default_rng(1))
    # black can only get brighter, white only darker: clipped, hence biased there
    assert noisy[:, :100].mean() > 0.0 and noisy[:, :100].min() == 0
    assert noisy[:, 100:].mean() < 255.0 and noisy[:, 100:].max() == 255


def test_the_same_seed_gives_the_same_noise_and_zero_noise_draws_nothing():
    image = np.random.default_rng(3).integers(0, 256, (60, 80, 3), dtype=np.uint8)
    a = CameraEffects(0.02, 0.3, seed=11)
    b = CameraEffects(0.02, 0.3, seed=11)
    c = CameraEffects(0.02, 0.3, seed=12)
    for _ in range(5):
        lost = a.frame_lost()
        assert b.frame_lost() == lost
        c.frame_lost()
        pair_a, pair_b, pair_c = (e.noisy((image, image)) for e in (a, b, c))
        assert all(np.array_equal(x, y) for x, y in zip(pair_a, pair_b))
        assert not np.array_equal(pair_a[0], pair_c[0])
        assert not np.array_equal(pair_a[0], pair_a[1])  # left and right drawn apart
    off = CameraEffects(seed=11)
    state = off.rng.bit_generator.state
    assert off.noisy((image,))[0] is image and not off.frame_lost()
    assert off.rng.bit_generator.state == state


@pytest.mark.parametrize('probability', [0.1, 0.5])
def test_drops_happen_at_the_set_rate_over_1000_frames(probability):
    n = 1000
    sigma = math.sqrt(n * probability * (1.0 - probability))
    for seed in range(5):
        effects = CameraEffects(drop_probability=probability, seed=seed)
        lost = [effects.frame_lost() for _ in range(n)]
        assert abs(sum(lost) - n * probability) < 4.0 * sigma
        # no pattern: losing a frame does not change the chance of losing the next one
        pairs = sum(a and b for a, b in zip(lost[:-1], lost[1:]))
        assert abs(pairs - (n - 1) * probability ** 2) < 4.0 * math.sqrt(
            (n - 1) * probability ** 2 * (1 - probability ** 2)) + 3.0


def test_the_simulator_loses_frames_at_the_set_rate_and_keeps_its_schedule():
    sim = Simulator(SimConfig.make(physics_rate_hz=100.0, camera_rate_hz=100.0,
                                   frame_drop_probability=0.1, camera_seed=5))
    try:
        lost = []
        for n in range(1000):
            stamp, images, was_lost = sim.take_frame(render=False)
            assert stamp == n * 10_000_000 and images is None
            lost.append(was_lost)
            sim.step()
        assert sim.frames_lost == sum(lost)
        assert abs(sum(lost) - 100) < 4.0 * math.sqrt(1000 * 0.1 * 0.9)
    finally:
        sim.close()


@pytest.mark.parametrize('xyz, rpy', [((0.002, 0.0, 0.0), (0.0, 0.2, 0.0)),
                                      ((-0.01, 0.003, 0.02), (0.5, -0.3, 1.0))])
def test_published_pose_differs_from_the_true_one_by_exactly_the_error(xyz, rpy):
    true = look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT)
    published = calibrated_pose(true, xyz, rpy)
    relative = np.linalg.inv(true) @ published
    np.testing.assert_allclose(relative, error_transform(xyz, rpy), atol=1e-12)
    np.testing.assert_allclose(relative[:3, 3], xyz, atol=1e-12)
    angle = np.degrees(Rotation.from_matrix(relative[:3, :3]).magnitude())
    assert angle == pytest.approx(np.degrees(
        Rotation.from_euler('xyz', rpy, degrees=True).magnitude()), abs=1e-9)
    # a pure translation along the camera's optical axis moves the eye along it
    ahead = calibrated_pose(true, (0.0, 0.0, 0.01), (0.0, 0.0, 0.0))
    np.testing.assert_allclose(ahead[:3, 3] - true[:3, 3], 0.01 * true[:3, 2], atol=1e-12)


def test_focal_length_error_scales_f_only():
    k = StereoIntrinsics.zed2('HD720')
    c = calibrated_intrinsics(k, 1.01)
    assert (c.fu, c.fv) == (k.fu * 1.01, k.fv * 1.01)
    kept = ('cu', 'cv', 'width', 'height', 'baseline')
    assert [getattr(c, a) for a in kept] == [getattr(k, a) for a in kept]


def test_simulator_renders_true_and_publishes_calibrated_camera():
    sim = Simulator(SimConfig.make(camera_pose_error_xyz_m=(0.002, 0.0, 0.0),
                                   camera_pose_error_rpy_deg=(0.0, 0.2, 0.0),
                                   focal_length_error=1.01))
    plain = Simulator(SimConfig.make())
    try:
        np.testing.assert_array_equal(sim.camera.pose_C_O, plain.camera.pose_C_O)
        assert sim.camera.intrinsics == plain.camera.intrinsics
        np.testing.assert_allclose(
            np.linalg.inv(sim.camera.pose_C_O) @ sim.calibrated_camera.pose_C_O,
            error_transform((0.002, 0.0, 0.0), (0.0, 0.2, 0.0)), atol=1e-12)
        assert sim.calibrated_camera.intrinsics.fu == pytest.approx(
            1.01 * plain.camera.intrinsics.fu, rel=1e-15)
        # the images show the truth: the same as without any calibration error
        _, seen, _ = sim.take_frame()
        _, truth, _ = plain.take_frame()
        assert all(np.array_equal(a, b) for a, b in zip(seen, truth))
    finally:
        sim.close()
        plain.close()


@pytest.mark.parametrize('kwargs, name', [
    ({'image_noise_stddev': -0.1}, 'image_noise_stddev'),
    ({'image_noise_stddev': math.nan}, 'image_noise_stddev'),
    ({'frame_drop_probability': 1.0}, 'frame_drop_probability'),
    ({'focal_length_error': 0.0}, 'focal_length_error'),
    ({'camera_pose_error_xyz_m': (0.0, 0.0)}, 'camera_pose_error_xyz_m'),
    ({'camera_pose_error_rpy_deg': (0.0, math.inf, 0.0)}, 'camera_pose_error_rpy_deg'),
])
def test_the_config_refuses_bad_camera_effects_naming_the_parameter(kwargs, name):
    with pytest.raises(ParameterError) as info:
        SimConfig.make(**kwargs)
    assert info.value.param == name


def test_a_pair_taught_on_n_frames_carries_one_over_sqrt_n_of_the_noise():
    from ibvs_model.paper import target_pose
    noise = {}
    for frames in (1, 16):
        sim = Simulator(SimConfig.make(resolution='VGA', image_noise_stddev=0.05, camera_seed=3,
                                       teach_frames=frames), teach_pose=target_pose())
        try:
            sim.world.reset(sim.teach_q)  # the arm is at its start now: back to the teach
            clean = sim._draw()
            assert all(t.dtype == np.uint8 and t.shape == c.shape
                       for t, c in zip(sim.teach_images, clean))
            # away from clipping (mid-grey and brighter pixels below 230)
            left = clean[0].astype(float)
            keep = (left > 30) & (left < 225)
            noise[frames] = np.std(sim.teach_images[0].astype(float)[keep] - left[keep])
        finally:
            sim.close()
    assert noise[1] == pytest.approx(0.05 * 255, rel=0.05)
    # 1/4 of it, and the rounding of the mean to 8 bits (uniform, 1/sqrt(12) of a level)
    expected = math.hypot(0.05 * 255 / 4.0, 1.0 / math.sqrt(12.0))
    assert noise[16] == pytest.approx(expected, rel=0.1)
