"""Image and CameraInfo: the stereo pair written and read, and the ranges a lens is read in."""

from types import SimpleNamespace

from ibvs_common import contract, conversions
from ibvs_common.conversions import InputError
from ibvs_model import default_camera, default_model, StereoIntrinsics
import numpy as np
import pytest


def _infos(resolution='HD720'):
    return conversions.camera_infos(default_camera(resolution).intrinsics, 0)


def _reason(call, *args):
    with pytest.raises(InputError) as caught:
        call(*args)
    return caught.value.reason


def _set(info, index, value):
    p = list(info.p)
    p[index] = value
    info.p = p


def test_camera_round_trip_through_camera_info_and_pose():
    camera = default_model().camera
    left, right = conversions.camera_infos(camera.intrinsics, 0)
    assert right.p[3] == pytest.approx(-camera.intrinsics.fu * 0.12)
    pose = conversions.pose_stamped(camera.pose_C_O, 0, contract.BASE_FRAME)
    back = conversions.camera_from_msgs(left, right, pose)
    k, kb = camera.intrinsics, back.intrinsics
    assert (kb.width, kb.height) == (k.width, k.height)
    np.testing.assert_allclose([kb.fu, kb.fv, kb.cu, kb.cv, kb.baseline],
                               [k.fu, k.fv, k.cu, k.cv, k.baseline], rtol=1e-12)
    np.testing.assert_allclose(back.pose_C_O, camera.pose_C_O, atol=1e-12)
    point = np.array([[0.1, 0.3, 0.8]])
    np.testing.assert_allclose(back.project(point), camera.project(point), atol=1e-9)


def test_camera_info_mismatch_is_rejected():
    camera = default_model().camera
    left, right = conversions.camera_infos(camera.intrinsics, 0)
    right.width += 2  # a lens of its own, not this one's pair
    with pytest.raises(InputError, match='size mismatch'):
        conversions.intrinsics_from_infos(left, right)
    left, right = conversions.camera_infos(camera.intrinsics, 0)
    right.p[3] = 0.0
    with pytest.raises(InputError, match='P\\[3\\]'):
        conversions.intrinsics_from_infos(left, right)


def test_a_camera_info_without_twelve_finite_values_is_refused_before_the_pose_is_read():
    camera = default_model().camera
    left, right = conversions.camera_infos(camera.intrinsics, 0)
    left.p = [0.0] * 3
    with pytest.raises(InputError, match='12 finite'):
        conversions.camera_from_msgs(left, right, SimpleNamespace(pose=None))


@pytest.mark.parametrize('resolution', ['VGA', 'HD720', 'HD1080'])
def test_a_zed2_camera_info_is_read_back_exactly(resolution):
    k = default_camera(resolution).intrinsics
    back = conversions.intrinsics_from_infos(*conversions.camera_infos(k, 0))
    assert back == k


def test_camera_infos_are_read_back_as_the_intrinsics_they_were_written_from():
    rng = np.random.default_rng(51)
    for _ in range(300):
        width, height = (int(v) for v in rng.integers(16, conversions.MAX_IMAGE_SIDE_PX,
                                                      size=2))
        k = StereoIntrinsics.from_fov(width, height, rng.uniform(2.0, 160.0),
                                      rng.uniform(2.0, 160.0), rng.uniform(0.006, 4.9),
                                      cu=rng.uniform(0.05, 0.95) * width,
                                      cv=rng.uniform(0.0, height))
        if rng.random() < 0.5:  # lenses with their own f_u and c_u (older ZED SDKs)
            k = StereoIntrinsics(k.width, k.height, k.fu, k.fv, k.cu, k.cv, k.baseline,
                                 right_fu=k.fu * rng.uniform(0.99, 1.01),
                                 right_cu=k.cu + rng.uniform(-0.01, 0.01) * width)
        left, right = conversions.camera_infos(k, 5)
        assert (left.header.frame_id, right.header.frame_id) == \
            (contract.LEFT_CAMERA_FRAME, contract.RIGHT_CAMERA_FRAME)
        back = conversions.intrinsics_from_infos(left, right)
        # every value as written; the baseline through b = -P[3] / f_u'
        assert back.baseline == pytest.approx(k.baseline, rel=1e-15)
        assert back == StereoIntrinsics(k.width, k.height, k.fu, k.fv, k.cu, k.cv,
                                        back.baseline, k.right_fu, k.right_cu)


def test_the_focal_range_is_the_field_of_view_range():
    low, high = conversions.focal_range_px(1280)
    assert low == pytest.approx(640 / np.tan(np.radians(85.0)))
    assert high == pytest.approx(640 / np.tan(np.radians(0.5)))
    # a lens of 2 and of 160 degrees is read; 0.5 and 175 are not
    for fov, ok in ((2.0, True), (160.0, True), (0.5, False), (175.0, False)):
        k = StereoIntrinsics.from_fov(1280, 720, fov, 55.35)
        left, right = conversions.camera_infos(k, 0)
        if ok:
            conversions.intrinsics_from_infos(left, right)
        else:
            assert _reason(conversions.check_camera_info, left) == 'focal length out of range'


@pytest.mark.parametrize('index, value, reason', [
    (0, 1e308, 'focal length out of range'),     # f_u
    (5, 1e308, 'focal length out of range'),     # f_v
    (0, -686.0, 'focal length out of range'),
    (0, 0.0, 'focal length out of range'),
    (5, 1e-300, 'focal length out of range'),
    (2, -1.0, 'principal point off the image'),  # c_u
    (2, 1281.0, 'principal point off the image'),
    (6, 1e300, 'principal point off the image'),  # c_v
    (3, -1e300, 'baseline out of range'),         # P[3] alone
    (3, 1e300, 'baseline out of range'),
    (0, float('nan'), 'bad camera_info'),
    (3, float('inf'), 'bad camera_info'),
])
def test_an_absurd_lens_is_refused_by_itself(index, value, reason):
    for info in _infos():
        p = list(info.p)
        p[index] = value
        info.p = p
        assert _reason(conversions.check_camera_info, info) == reason


def test_an_absurd_camera_never_reaches_the_model():
    """f_u = 1e308 with the right P[3] = -1e308 (b = 1 m), which overflows to inf features."""
    left, right = _infos()
    for info in (left, right):
        p = list(info.p)
        p[0] = 1e308
        info.p = p
    p = list(right.p)
    p[3] = -1e308
    right.p = p
    assert _reason(conversions.intrinsics_from_infos, left, right) == \
        'focal length out of range'
    left, right = _infos()
    p = list(right.p)
    p[3] = -1e300
    right.p = p
    assert _reason(conversions.intrinsics_from_infos, left, right) == 'baseline out of range'


@pytest.mark.parametrize('baseline, ok', [(0.12, True), (0.063, True), (0.005, True),
                                          (5.0, True), (0.004, False), (5.5, False)])
def test_the_baseline_range(baseline, ok):
    k = default_camera('HD720').intrinsics
    left, right = conversions.camera_infos(
        StereoIntrinsics(k.width, k.height, k.fu, k.fv, k.cu, k.cv, baseline), 0)
    if ok:
        assert conversions.intrinsics_from_infos(left, right).baseline == pytest.approx(baseline)
    else:
        assert _reason(conversions.intrinsics_from_infos, left, right) == \
            'baseline out of range'


def test_a_right_lens_with_a_positive_p3_has_no_baseline():
    left, right = _infos()
    p = list(right.p)
    p[3] = -p[3]
    right.p = p
    conversions.check_camera_info(right)  # as a lens alone it could be a left one
    assert _reason(conversions.intrinsics_from_infos, left, right) == 'baseline out of range'


def test_the_left_lens_is_the_reference():
    left, right = _infos()
    assert _reason(conversions.intrinsics_from_infos, right, right) == \
        'left lens with a baseline'


def test_lenses_with_their_own_f_u_and_c_u_are_read_each_from_its_p():
    # older ZED SDKs: left f_x 701.40, right 696.83; T_x = -f_x' b
    left, right = _infos()
    _set(left, 0, 701.40)
    _set(right, 0, 696.83)
    _set(right, 2, 641.25)
    _set(right, 3, -696.83 * 0.12)
    k = conversions.intrinsics_from_infos(left, right)
    assert (k.fu, k.fu_r, k.cu, k.cu_r) == (701.40, 696.83, left.p[2], 641.25)
    assert k.baseline == pytest.approx(0.12, rel=1e-15)
    # and written back as they came
    left2, right2 = conversions.camera_infos(k, 0)
    np.testing.assert_allclose(right2.p, right.p, rtol=1e-15)
    np.testing.assert_allclose(left2.p, left.p, rtol=1e-15)
    # identical lenses stay one: the paper's camera, bit for bit
    assert conversions.intrinsics_from_infos(*_infos()).same_lenses


@pytest.mark.parametrize('index, delta, ok', [
    (6, 0.4, True),      # c_v: rows 0.4 px apart
    (6, 0.6, False),     # beyond ROW_TOLERANCE_PX
    (5, 0.9, True),      # f_v: 0.9 / 686 * 360 = 0.47 px at the top and bottom rows
    (5, 1.2, False),     # 0.63 px
])
def test_a_pair_whose_rows_differ_is_refused_as_not_rectified(index, delta, ok):
    left, right = _infos()
    _set(right, index, right.p[index] + delta)
    if ok:
        conversions.intrinsics_from_infos(left, right)
    else:
        assert _reason(conversions.intrinsics_from_infos, left, right) == \
            'camera_info not rectified'


@pytest.mark.parametrize('encoding', ['rgb8', 'bgr8'])
def test_an_rgb8_or_bgr8_image_carries_the_pixels_as_they_are(encoding):
    array = np.random.default_rng(52).integers(0, 256, size=(5, 7, 3), dtype=np.uint8)
    msg = conversions.image_msg(array, 34_000_000, encoding, 'lens')
    assert (msg.height, msg.width, msg.step, msg.encoding) == (5, 7, 21, encoding)
    assert conversions.stamp_ns(msg.header.stamp) == 34_000_000
    assert msg.header.frame_id == 'lens' and msg.is_bigendian == 0
    assert bytes(msg.data) == array.tobytes()


def test_a_bgra8_image_is_the_rgb_array_reordered_with_an_opaque_alpha():
    array = np.random.default_rng(53).integers(0, 256, size=(4, 6, 3), dtype=np.uint8)
    msg = conversions.image_msg(array, 0, 'bgra8')
    assert (msg.height, msg.width, msg.step) == (4, 6, 24)
    pixels = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(4, 6, 4)
    assert pixels[..., :3].tobytes() == array[..., ::-1].tobytes()
    assert (pixels[..., 3] == 255).all()


def test_an_image_array_that_is_not_three_channels_is_refused():
    for shape in ((4, 6), (4, 6, 4), (4, 6, 1)):
        with pytest.raises(ValueError, match=r'\(H, W, 3\)'):
            conversions.image_msg(np.zeros(shape, dtype=np.uint8), 0)
