"""Stereo camera (eq. 12-22), triangulation and the camera-and-robot model F (eq. 30-32, 42)."""

from ibvs_model import (BehindCameraError, CameraRobotModel, default_model, InvalidInputError,
                        inverse_kinematics, IRB4600, look_at, StereoCamera, StereoIntrinsics,
                        TriangulationError, UnreachablePoseError)
from ibvs_model import paper
from ibvs_model.camera import merge_windows
import numpy as np
import pytest

N_RANDOM = 200


@pytest.fixture(scope='module')
def model():
    return default_model()


def random_in_view_configurations(model, n, seed):
    """Return n joint vectors whose two fiducials are inside both images."""
    rng = np.random.default_rng(seed)
    q_target = inverse_kinematics(paper.target_pose())
    q_start = inverse_kinematics(paper.scenario_start_pose(1))
    out = []
    while len(out) < n:
        # Around the segment between two in-view poses, so that most draws are in view.
        s = rng.uniform()
        q = (1 - s) * q_start + s * q_target + rng.normal(0.0, 0.15, 6)
        if IRB4600.within_limits(q) and np.all(model.in_view(q)):
            out.append(q)
    return np.array(out)


def test_zed2_intrinsics_from_field_of_view():
    k = StereoIntrinsics.zed2('HD720')
    assert k.fu == pytest.approx(640 / np.tan(np.radians(86.09 / 2)))
    assert 680.0 < k.fu < 690.0 and 680.0 < k.fv < 690.0
    assert (k.cu, k.cv) == (639.5, 359.5)
    assert k.baseline == 0.12
    vga = StereoIntrinsics.zed2('VGA')
    assert (vga.width, vga.height) == (672, 376)


def test_look_at_gives_x_right_y_down_z_forward():
    tf = look_at([0.0, -2.0, 1.0], [0.0, 0.0, 1.0])
    np.testing.assert_allclose(tf[:3, 2], [0, 1, 0], atol=1e-12)   # forward
    np.testing.assert_allclose(tf[:3, 1], [0, 0, -1], atol=1e-12)  # down
    np.testing.assert_allclose(tf[:3, 0], [1, 0, 0], atol=1e-12)   # right
    np.testing.assert_allclose(tf[:3, :3].T @ tf[:3, :3], np.eye(3), atol=1e-12)


def test_projection_follows_ros_stereo_sign(model):
    cam = model.camera
    point_c = np.array([[0.1, -0.05, 2.0]])
    ul, ur, v = cam.project_camera(point_c)[0]
    k = cam.intrinsics
    assert ul - ur == pytest.approx(k.fu * k.baseline / 2.0)  # disparity f_u b / Z > 0
    # Eq. (19)-(20) with the lens at x = -b/2 for the left image (ROS), plus c_u.
    assert ul == pytest.approx(k.fu * (0.1 + 0.06) / 2.0 + k.cu)
    assert ur == pytest.approx(k.fu * (0.1 - 0.06) / 2.0 + k.cu)
    assert v == pytest.approx(k.fv * -0.05 / 2.0 + k.cv)


def test_triangulation_inverts_projection(model):
    rng = np.random.default_rng(6)
    cam = model.camera
    points_c = np.column_stack([rng.uniform(-1.5, 1.5, N_RANDOM),
                                rng.uniform(-1.0, 1.0, N_RANDOM),
                                rng.uniform(0.3, 5.0, N_RANDOM)])
    points_o = cam.to_base(points_c)
    back = cam.triangulate(cam.project(points_o))
    assert np.max(np.abs(back - points_o)) < 1e-9


def test_projection_jacobian_matches_finite_differences(model):
    cam = model.camera
    p = cam.to_base(np.array([[0.2, 0.1, 1.8]]))[0]
    h = 1e-6
    fd = np.column_stack([(cam.project((p + h * e)[None])[0]
                           - cam.project((p - h * e)[None])[0]) / (2 * h) for e in np.eye(3)])
    np.testing.assert_allclose(cam.projection_jacobian(p), fd, rtol=1e-6, atol=1e-6)


def test_in_view_and_margin(model):
    cam = model.camera
    centre = cam.to_base(np.array([[0.0, 0.0, 2.0]]))
    assert cam.in_view(centre)[0]
    behind = cam.to_base(np.array([[0.0, 0.0, -1.0]]))
    assert not cam.in_view(behind)[0]
    # A point that projects 5 px inside the left border is out with a 10 px margin.
    k = cam.intrinsics
    z = 2.0
    x = (5.0 - 0.5 - k.cu) * z / k.fu + k.baseline / 2.0  # u_r = 4.5 px (right image is left)
    edge = cam.to_base(np.array([[x, 0.0, z]]))
    assert cam.in_view(edge)[0]
    assert not cam.in_view(edge, margin_px=10.0)[0]


def test_paper_scenarios_visibility(model):
    q_target = inverse_kinematics(paper.target_pose())
    q_s1 = inverse_kinematics(paper.scenario_start_pose(1))
    q_s23 = inverse_kinematics(paper.scenario_start_pose(2))
    assert model.in_view(q_target, margin_px=20).all()
    assert model.in_view(q_s1, margin_px=20).all()
    assert not model.in_view(q_s23).any()


def test_c1_matches_central_differences(model):
    h = 1e-6
    worst = 0.0
    for q in random_in_view_configurations(model, N_RANDOM, 7):
        jac = model.jacobian(q)
        fd = np.empty((6, 6))
        for i in range(6):
            dq = np.zeros(6)
            dq[i] = h
            fd[:, i] = (model.features(q + dq) - model.features(q - dq)) / (2 * h)
        scale = np.max(np.abs(fd))
        worst = max(worst, float(np.max(np.abs(jac - fd)) / scale))
    assert worst < 1e-6


def test_c1_has_rank_five_with_joint_six_in_its_null_space(model):
    for q in random_in_view_configurations(model, N_RANDOM, 8):
        jac = model.jacobian(q)
        s = np.linalg.svd(jac, compute_uv=False)
        assert s[5] < 1e-9 * s[0]
        assert s[4] > 1e-6 * s[0], 'away from the wrist singularity the rank is exactly 5'
        np.testing.assert_allclose(jac[:, 5], 0.0, atol=1e-9 * s[0])
        _, _, vt = np.linalg.svd(jac)
        assert abs(vt[5, 5]) == pytest.approx(1.0, abs=1e-9)


def test_inverse_model_recovers_q(model):
    worst = 0.0
    for q in random_in_view_configurations(model, N_RANDOM, 9):
        q_back = model.inverse(model.features(q), q[5], seed=q)
        worst = max(worst, float(np.max(np.abs(q_back - q))))
    assert worst < 1e-8


def test_inverse_model_without_seed_finds_the_paper_target(model):
    q = inverse_kinematics(paper.target_pose())
    q_back = model.inverse(model.features(q), q[5])
    np.testing.assert_allclose(q_back, q, atol=1e-9)


def test_behind_camera_raises(model):
    with pytest.raises(BehindCameraError, match='behind the camera'):
        model.camera.project_camera(np.array([[0.0, 0.0, -1.0]]))
    with pytest.raises(BehindCameraError):
        model.camera.projection_jacobian(model.camera.to_base(np.array([[0, 0, -1.0]]))[0])


def test_triangulation_rejects_non_positive_disparity(model):
    with pytest.raises(TriangulationError, match='disparity'):
        model.camera.triangulate(np.array([[100.0, 120.0, 50.0]]))


def test_inverse_model_rejects_unreachable_features(model):
    far = model.camera.project(np.array([[5.0, 0.0, 1.0], [5.0, 0.0, 1.1]])).reshape(6)
    with pytest.raises(UnreachablePoseError):
        model.inverse(far, 0.0)


@pytest.mark.parametrize('bad,match', [
    (np.zeros(5), 'shape'),
    (np.full(6, np.nan), 'NaN or inf'),
])
def test_model_rejects_bad_arrays(model, bad, match):
    with pytest.raises(InvalidInputError, match=match):
        model.inverse(bad, 0.0)
    with pytest.raises(InvalidInputError, match=match):
        model.features(bad)


def test_bad_intrinsics_and_camera_are_rejected():
    with pytest.raises(InvalidInputError, match='fu'):
        StereoIntrinsics(640, 480, -1.0, 500.0, 320.0, 240.0, 0.12)
    with pytest.raises(InvalidInputError, match='resolution'):
        StereoIntrinsics.zed2('4K')
    with pytest.raises(InvalidInputError, match='hfov'):
        StereoIntrinsics.from_fov(640, 480, hfov_deg=200.0)
    with pytest.raises(InvalidInputError, match='rotation'):
        StereoCamera(StereoIntrinsics.zed2(), np.diag([1.0, 1.0, 2.0, 1.0]))
    with pytest.raises(InvalidInputError, match='coincide'):
        look_at([0, 0, 0], [0, 0, 0])
    with pytest.raises(InvalidInputError, match='StereoCamera'):
        CameraRobotModel('camera')


def test_merge_windows_merges_overlaps_until_none_are_left():
    # a and b overlap; their union overlaps c; d only touches c; e is apart.
    a, b, c, d, e = (0, 0, 10, 10), (5, 5, 20, 12), (18, 0, 30, 4), (30, 0, 40, 4), \
        (0, 50, 3, 60)
    assert merge_windows([a, b, c, d, e]) == [(0, 0, 30, 12), (0, 50, 3, 60), (30, 0, 40, 4)]
    assert merge_windows([]) == []
    assert merge_windows([e]) == [e]


def per_lens_camera(right_fu=696.83, right_cu=652.1):
    """Return a ZED 2 at HD720 whose lenses differ as older SDKs give them (701.40, 696.83)."""
    k = StereoIntrinsics(1280, 720, 701.40, 701.40, 639.5, 359.5, 0.12,
                         right_fu=right_fu, right_cu=right_cu)
    return StereoCamera(k, look_at([2.0, -1.5, 1.2], [0.8, 0.1, 0.6]))


def test_per_lens_projection_round_trip_and_each_lens_its_own_pinhole():
    camera = per_lens_camera()
    k = camera.intrinsics
    assert not k.same_lenses and (k.fu_r, k.cu_r) == (696.83, 652.1)
    rng = np.random.default_rng(3)
    points_C = np.c_[rng.uniform(-0.8, 0.8, (N_RANDOM, 2)), rng.uniform(0.5, 6.0, N_RANDOM)]
    uv = camera.project_camera(points_C)
    # each image is the pinhole of its own lens: the left at x = -b/2, the right at +b/2
    np.testing.assert_allclose(uv[:, 0], 701.40 * (points_C[:, 0] + 0.06) / points_C[:, 2]
                               + 639.5, rtol=1e-13)
    np.testing.assert_allclose(uv[:, 1], 696.83 * (points_C[:, 0] - 0.06) / points_C[:, 2]
                               + 652.1, rtol=1e-13)
    np.testing.assert_allclose(camera.triangulate_camera(uv), points_C, rtol=1e-10,
                               atol=1e-12)
    points_O = camera.to_base(points_C)
    np.testing.assert_allclose(camera.triangulate(camera.project(points_O)), points_O,
                               atol=1e-9)
    # taking one f_u for both (the old model) would misplace the points by centimetres
    same = StereoCamera(StereoIntrinsics(1280, 720, 701.40, 701.40, 639.5, 359.5, 0.12),
                        camera.pose_C_O)
    assert np.abs(same.triangulate_camera(uv) - points_C).max() > 0.01


def test_per_lens_jacobian_is_the_derivative_of_the_projection():
    camera = per_lens_camera()
    point = camera.to_base(np.array([[0.2, -0.1, 2.5]]))[0]
    jac = camera.projection_jacobian(point)
    h = 1e-6
    numeric = np.array([(camera.project((point + h * e)[None])[0]
                         - camera.project((point - h * e)[None])[0]) / (2 * h)
                        for e in np.eye(3)]).T
    np.testing.assert_allclose(jac, numeric, rtol=1e-6, atol=1e-6)


def test_per_lens_triangulation_refuses_a_point_behind_by_normalised_disparity():
    camera = per_lens_camera(right_cu=630.0)
    # u_l > u_r in pixels, yet behind the camera once each lens's own centre is taken
    with pytest.raises(TriangulationError, match='disparity'):
        camera.triangulate_camera([[640.0, 639.0, 360.0]])
    camera.triangulate_camera([[640.0, 620.0, 360.0]])  # in front: read


def test_identical_lenses_given_either_way_are_the_same_camera():
    one = StereoIntrinsics.zed2('HD720')
    both = StereoIntrinsics(one.width, one.height, one.fu, one.fv, one.cu, one.cv,
                            one.baseline, right_fu=one.fu, right_cu=one.cu)
    assert one.same_lenses and both.same_lenses
    pose = look_at([2.0, -1.5, 1.2], [0.8, 0.1, 0.6])
    points = np.array([[0.7, 0.2, 0.5], [1.0, -0.1, 0.9]])
    a, b = StereoCamera(one, pose), StereoCamera(both, pose)
    assert np.array_equal(a.project(points), b.project(points))
    assert np.array_equal(a.triangulate(a.project(points)), b.triangulate(b.project(points)))


@pytest.mark.parametrize('right_fu, right_cu', [(0.0, None), (float('nan'), None),
                                                (None, float('inf'))])
def test_a_right_lens_that_is_no_lens_is_refused(right_fu, right_cu):
    with pytest.raises(InvalidInputError, match='right_'):
        StereoIntrinsics(1280, 720, 700.0, 700.0, 639.5, 359.5, 0.12, right_fu=right_fu,
                         right_cu=right_cu)


def test_features_of_many_postures_at_once_equal_each_posture_alone():
    from ibvs_model import default_model
    model = default_model()
    rng = np.random.default_rng(3)
    qs = rng.uniform(-0.5, 0.5, (7, 6)) + np.array([0.0, 0.1, 0.2, 0.0, 0.6, 0.0])
    batch = model.features_batch(qs)
    assert batch.shape == (7, 6)
    np.testing.assert_allclose(batch, [model.features(q) for q in qs], rtol=0, atol=1e-9)
