"""
The Hough fiducial detector on synthetic stereo pairs (pure: no ROS, no PyBullet).

Synthetic frames (ibvs_vision.synthetic) are ray-traced spheres at the model projection of
eq. (16)-(22), anti-aliased, shaded with a highlight, on clutter with noise; the ground
truth is the projection of the true sphere centres. Properties first (the perspective
formula against the exact silhouette, linearity of the colour channel, agreement of the
search paths), then accuracy.
"""

from ibvs_model import fiducial_points, scene
from ibvs_model.scene import MARKER_RADIUS_M, MARKER_RGB
from ibvs_vision import synthetic
from ibvs_vision.detector import (centre_to_silhouette, colour_scores, DetectorConfig, Reason,
                                  silhouette_to_centre, StereoDetector)
import numpy as np
import pytest


def _conic_centre(points):
    """Return the centre of the conic through points (N, 2) (least squares, exact data)."""
    x, y = points[:, 0], points[:, 1]
    design = np.c_[x * x, x * y, y * y, x, y, np.ones_like(x)]
    a, b, c, d, e, _ = np.linalg.svd(design)[2][-1]
    return np.linalg.solve([[2 * a, b], [b, 2 * c]], [-d, -e])


def test_silhouette_centre_formula_matches_the_tangent_cone(hd_model):
    """Eq. (16) of a sphere's outline: the ellipse centre is the stretched centre projection."""
    k = hd_model.camera.intrinsics
    rng = np.random.default_rng(0)
    for _ in range(20):
        centre = np.r_[rng.uniform(-1.5, 1.5, 2), rng.uniform(0.8, 4.0)]
        radius = rng.uniform(0.01, 0.2)
        dist = np.linalg.norm(centre)
        axis = centre / dist
        e1 = np.cross(axis, [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(axis, e1)
        alpha = np.arcsin(radius / dist)
        phi = np.linspace(0.0, 2.0 * np.pi, 40, endpoint=False)
        rays = (np.cos(alpha) * axis[None] + np.sin(alpha)
                * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2))
        outline = np.c_[k.fu * rays[:, 0] / rays[:, 2] + k.cu,
                        k.fv * rays[:, 1] / rays[:, 2] + k.cv]
        expected = _conic_centre(outline)
        u = k.fu * centre[0] / centre[2] + k.cu
        v = k.fv * centre[1] / centre[2] + k.cv
        got = centre_to_silhouette(u, v, centre[2], k, radius)
        assert np.allclose(got, expected, atol=1e-6)
        back = silhouette_to_centre(*got, centre[2], k, radius)
        assert np.allclose(back, (u, v), atol=1e-9)


def test_colour_channels_are_linear_and_hue_selective():
    red, blue = (np.array(c, float) for c in MARKER_RGB)
    grey = np.array([120.0, 120.0, 120.0])
    orange = np.array([235.0, 150.0, 70.0])
    rows = [a * red + (1 - a) * grey for a in np.linspace(0.0, 1.0, 11)]
    rows += [0.4 * red, orange, grey, blue]
    image = np.round(np.array(rows))[None].astype(np.uint8)
    linear, selective = colour_scores(image, MARKER_RGB[0])
    mix = linear[0, :11].astype(float)
    # s = R - max(G, B) of a red/grey mix is the red share times s(red): coverage.
    assert np.allclose(mix, np.linspace(0.0, 1.0, 11) * (220 - 30), atol=1.0)
    assert selective[0, 10] > 0 and selective[0, 11] > 0  # red at any brightness
    assert linear[0, 12] > 50 and selective[0, 12] == 0  # orange: not red
    assert selective[0, 13] == 0 and selective[0, 14] == 0
    assert colour_scores(image, MARKER_RGB[1])[1][0, 14] > 0
    # bgr8 reads the same colours.
    bgr = np.ascontiguousarray(image[:, :, ::-1])
    for got, want in zip(colour_scores(bgr, MARKER_RGB[0], 'bgr8'), (linear, selective)):
        assert np.array_equal(got, want)


def _frames(model, count, seed, clutter=25):
    rng = np.random.default_rng(seed)
    out = []
    for q in scene.in_view_poses(model, count, rng):
        points = fiducial_points(q)
        out.append((model.camera.project(points).reshape(6),
                    synthetic.render_stereo(model.camera, points, rng, clutter=clutter)))
    return out


@pytest.fixture(scope='module')
def hd_frames(hd_model):
    return _frames(hd_model, 25, seed=1)


@pytest.fixture(scope='module')
def vga_frames(vga_model):
    return _frames(vga_model, 25, seed=2)


@pytest.mark.parametrize('which', ['hd', 'vga'])
def test_sub_pixel_accuracy_on_random_in_view_poses(which, request):
    model = request.getfixturevalue(f'{which}_model')
    frames = request.getfixturevalue(f'{which}_frames')
    detector = StereoDetector(model.camera.intrinsics)
    errors, hough_errors = [], []
    for truth, (left, right) in frames:
        result = detector.detect(left, right)
        assert result.ok, (result.reason, result.detail)
        errors.append(result.features - truth)
        # What the Hough transform alone gives (centres on a 0.5 px grid).
        hough = []
        for k in range(2):
            (bl,), (br,) = result.left.blobs[k], result.right.blobs[k]
            hough += [bl.hough[0], br.hough[0], 0.5 * (bl.hough[1] + br.hough[1])]
        hough_errors.append(np.array(hough) - truth)
        assert np.all(np.array(hough) * 2 == np.round(np.array(hough) * 2))
    errors, hough_errors = np.abs(errors), np.abs(hough_errors)
    assert np.median(errors) <= 0.05
    assert errors.max() <= 0.3
    # The refinement is what makes it sub-pixel.
    assert np.median(hough_errors) > 5.0 * np.median(errors)


def test_the_perspective_offset_of_a_sphere_is_undone(hd_model):
    """Near the image corner and close, the silhouette centre is ~0.4 px off; p_I is not."""
    camera = hd_model.camera
    k = camera.intrinsics
    rng = np.random.default_rng(4)
    depth = 1.0
    uv = np.array([[k.width - 60.0, k.width - 60.0 - k.fu * k.baseline / depth, 70.0],
                   [k.width - 120.0, k.width - 120.0 - k.fu * k.baseline / depth, 70.0]])
    points = camera.triangulate(uv)
    truth = camera.project(points).reshape(6)
    left, right = synthetic.render_stereo(camera, points, rng, clutter=0)
    result = StereoDetector(k).detect(left, right)
    assert result.ok, result.detail
    silhouette = np.array([[b.u for b in (result.left.blobs[m][0], result.right.blobs[m][0])]
                           for m in range(2)])
    offset = np.abs(silhouette - truth.reshape(2, 3)[:, :2])
    assert offset.min() > 0.25
    assert np.abs(result.features - truth).max() < 0.1


def test_no_marker_gives_no_detection_and_no_candidate(hd_model):
    detector = StereoDetector(hd_model.camera.intrinsics)
    rng = np.random.default_rng(5)
    for _ in range(5):
        left, right = synthetic.render_stereo(hd_model.camera, np.empty((0, 3)), rng,
                                              clutter=60)
        result = detector.detect(left, right)
        assert result.reason is Reason.NOT_IN_VIEW
        for side in (result.left, result.right):
            assert side.blobs == ((), ()) and side.rejected == {}


def test_a_hidden_marker_is_reported_missing(hd_model, hd_frames):
    camera = hd_model.camera
    truth, _ = hd_frames[0]
    points = camera.triangulate(truth.reshape(2, 3))
    rng = np.random.default_rng(6)
    left, right = synthetic.render_stereo(
        camera, points, rng, occluders=[synthetic.disc_occluder(camera, points[1])])
    result = StereoDetector(camera.intrinsics).detect(left, right)
    assert result.reason is Reason.MARKER_MISSING
    assert 'marker 2' in result.detail and 'marker 1' not in result.detail
    assert 'left and right image' in result.detail


def test_a_half_hidden_marker_is_refused_not_measured(hd_model, hd_frames):
    """An edge across marker 1 would pull its centroid by pixels: it must be rejected."""
    camera = hd_model.camera
    k = camera.intrinsics
    detector = StereoDetector(k)
    rng = np.random.default_rng(7)
    for truth, _ in hd_frames[:5]:
        points = camera.triangulate(truth.reshape(2, 3))
        u_l, u_r, v = truth[:3]
        # A vertical edge through marker 1, covering its left half.
        edge = [(u_l - 100.0, v - 100.0), (u_l, v - 100.0), (u_l, v + 100.0),
                (u_l - 100.0, v + 100.0)]
        left, right = synthetic.render_stereo(camera, points, rng,
                                              occluders=[(edge, u_l - u_r, (90, 90, 90))])
        result = detector.detect(left, right)
        assert result.reason is Reason.MARKER_MISSING, result.detail
        assert result.detail.startswith('marker 1') and 'not round' in result.detail


def test_vertical_misalignment_is_an_epipolar_mismatch(hd_model, hd_frames):
    truth, (left, right) = hd_frames[1]
    detector = StereoDetector(hd_model.camera.intrinsics)
    shifted = np.roll(right, 4, axis=0)
    result = detector.detect(left, shifted)
    assert result.reason is Reason.EPIPOLAR_MISMATCH
    # Within the tolerance the pair is still measured, v being the mean of both images.
    config = DetectorConfig(epipolar_tolerance_px=5.0)
    loose = StereoDetector(hd_model.camera.intrinsics, config).detect(left, shifted)
    assert loose.ok
    assert np.allclose(loose.features[[2, 5]], truth[[2, 5]] + 2.0, atol=0.3)


def test_two_markers_of_one_colour_on_one_epipolar_line_are_ambiguous(hd_model, hd_frames):
    camera = hd_model.camera
    truth, _ = hd_frames[2]
    points = camera.triangulate(truth.reshape(2, 3))
    extra = camera.to_base(camera.to_camera(points[:1]) + np.array([[0.15, 0.0, 0.0]]))
    rng = np.random.default_rng(8)
    left, right = synthetic.render_stereo(camera, np.r_[points, extra], rng,
                                          colours=MARKER_RGB + MARKER_RGB[:1])
    result = StereoDetector(camera.intrinsics).detect(left, right)
    assert result.reason is Reason.AMBIGUOUS
    assert result.detail.startswith('marker 1')


def test_a_sphere_of_the_wrong_size_for_its_depth_is_not_paired(hd_model, hd_frames):
    camera = hd_model.camera
    truth, _ = hd_frames[3]
    points = camera.triangulate(truth.reshape(2, 3))
    rng = np.random.default_rng(9)
    left, right = synthetic.render_stereo(camera, points, rng, radius=2.0 * MARKER_RADIUS_M)
    result = StereoDetector(camera.intrinsics).detect(left, right)
    assert not result.ok


def test_a_marker_cut_by_the_image_border_is_refused(hd_model):
    camera = hd_model.camera
    k = camera.intrinsics
    disparity = k.fu * k.baseline / 2.0
    uv = np.array([[k.width + 2.0, k.width + 2.0 - disparity, 300.0],
                   [640.0, 640.0 - disparity, 300.0]])
    points = camera.triangulate(uv)
    left, right = synthetic.render_stereo(camera, points, np.random.default_rng(10))
    result = StereoDetector(k).detect(left, right)
    assert result.reason is Reason.MARKER_MISSING
    assert result.detail.startswith('marker 1 (P1) not found in left image')
    assert 'at image border' in result.detail


def test_roi_search_agrees_with_the_full_search(hd_model, hd_frames):
    detector = StereoDetector(hd_model.camera.intrinsics)
    for truth, (left, right) in hd_frames[:5]:
        full = detector.detect(left, right)
        tracked = detector.detect(left, right, prior=full.features)
        assert tracked.search == 'roi' and full.search == 'full'
        assert np.allclose(tracked.features, full.features, atol=1e-9)
        # A prior far off: the windows miss the markers, the whole image is searched.
        lost = detector.detect(left, right, prior=truth + 300.0)
        assert lost.search == 'full'
        assert np.allclose(lost.features, full.features, atol=1e-9)


def test_bgr8_images_give_the_same_features(hd_model, hd_frames):
    detector = StereoDetector(hd_model.camera.intrinsics)
    _, (left, right) = hd_frames[4]
    rgb = detector.detect(left, right)
    bgr = detector.detect(np.ascontiguousarray(left[:, :, ::-1]),
                          np.ascontiguousarray(right[:, :, ::-1]), 'bgr8')
    assert np.array_equal(rgb.features, bgr.features)
    with pytest.raises(ValueError, match='encoding'):
        detector.detect(left, right, 'mono8')


def test_bgra8_images_are_read_as_they_are_and_give_the_same_features(hd_model, hd_frames):
    # The ZED wrapper's encoding: the detector reads its windows, the alpha unread.
    detector = StereoDetector(hd_model.camera.intrinsics)
    _, (left, right) = hd_frames[4]
    alpha = np.random.default_rng(3).integers(0, 256, left.shape[:2] + (1,), dtype=np.uint8)
    bgra = [np.concatenate([image[:, :, ::-1], alpha], axis=2) for image in (left, right)]
    for prior in (None, detector.detect(left, right).features):
        rgb = detector.detect(left, right, prior=prior)
        assert np.array_equal(detector.detect(*bgra, 'bgra8', prior).features, rgb.features)
    with pytest.raises(ValueError, match='4'):
        detector.detect(left, right, 'bgra8')


def test_candidates_refined_together_are_refined_as_each_alone(hd_model, hd_frames):
    """All the circles of a pair are refined at once: each blob as if alone, to rounding."""
    from ibvs_vision.detector.refine import find_object, refine_candidates, refine_circle
    detector = StereoDetector(hd_model.camera.intrinsics)
    cfg, k = detector.config, hd_model.camera.intrinsics
    candidates = []
    for _, (left, right) in hd_frames[:4]:
        for image, side in ((left, 'left'), (right, 'right')):
            found = getattr(detector.detect(left, right), side)
            for marker, blobs in enumerate(found.blobs):
                for blob in blobs:
                    u, v, r = blob.hough
                    bounds = (0, 0, image.shape[1], image.shape[0])
                    alone, why, box = refine_circle(image, 'rgb8', marker, u, v, r, bounds,
                                                    cfg, k)
                    assert why is None and abs(alone.u - blob.u) < 1e-9 \
                        and abs(alone.v - blob.v) < 1e-9
                    candidate, _, _ = find_object(image, 'rgb8', marker, u, v, r, bounds, cfg)
                    candidates.append((candidate, alone))
    assert len(candidates) >= 12
    together = refine_candidates([c for c, _ in candidates], cfg, k)
    for (_, alone), (blob, why) in zip(candidates, together):
        assert why is None
        assert abs(blob.u - alone.u) < 1e-9 and abs(blob.v - alone.v) < 1e-9
        assert blob.radius == pytest.approx(alone.radius, rel=1e-12)
        assert blob.roundness == pytest.approx(alone.roundness, rel=1e-12)


def test_config_rejects_meaningless_values():
    with pytest.raises(ValueError, match='min_radius_px'):
        DetectorConfig(hough_min_radius_px=0)
    with pytest.raises(ValueError, match='max_radius_px'):
        DetectorConfig(hough_min_radius_px=10, hough_max_radius_px=10)
    with pytest.raises(ValueError, match='marker_rgb'):
        DetectorConfig(marker_rgb=((200, 20, 20), (210, 40, 30)))
