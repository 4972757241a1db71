"""The input checks of the one place of conversion: camera ranges, stamp order, commands."""

from builtin_interfaces.msg import Duration
from ibvs_common import contract, conversions
from ibvs_common.conversions import InputError, StampOrder
from ibvs_model import default_camera, StereoIntrinsics
import numpy as np
import pytest

MS = 1_000_000
NAMES = list(contract.JOINT_NAMES)


def _infos(resolution='HD720'):
    return conversions.camera_infos(default_camera(resolution).intrinsics, 0)


def _reason(call, *args):
    with pytest.raises(InputError) as caught:
        call(*args)
    return caught.value.reason


@pytest.mark.parametrize('resolution', ['VGA', 'HD720', 'HD1080'])
def test_a_zed2_camera_info_is_read_back_exactly(resolution):
    k = default_camera(resolution).intrinsics
    back = conversions.intrinsics_from_infos(*conversions.camera_infos(k, 0))
    assert back == k


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


def test_stamp_order_counts_duplicates_and_stamps_going_back_per_source():
    order = StampOrder()
    order.check('/a', 5)
    order.take('/a', 5)
    assert _reason(order.check, '/a', 5) == 'duplicate stamp'
    assert _reason(order.check, '/a', 4) == 'stamp went back'
    order.check('/b', 4)  # another source has its own order
    order.check('/a', 6)  # checked, not taken: 6 stays free
    order.check('/a', 6)
    assert order.newest('/a') == 5 and order.newest('/b') is None


def test_features_in_image():
    k = default_camera('VGA').intrinsics
    inside = [10.0, 5.0, 100.0, k.width - 0.5, k.width - 10.0, k.height + 0.5]
    conversions.check_features_in_image(inside, k)
    for index, value in ((0, -2.0), (1, k.width + 1.5), (2, 1e6), (5, -1e6)):
        bad = list(inside)
        bad[index] = value
        assert _reason(conversions.check_features_in_image, bad, k) == 'features off the image'


def _command(rows, times_ns=None, start_ns=0, names=NAMES):
    msg = conversions.joint_trajectory(start_ns, MS, np.atleast_2d(rows), names)
    if times_ns is not None:
        for point, t in zip(msg.points, times_ns):
            point.time_from_start = Duration(sec=t // 10 ** 9, nanosec=t % 10 ** 9)
    return msg


def test_a_good_trajectory_command_is_read_in_the_controllers_order():
    rows = np.arange(18, dtype=float).reshape(3, 6) * 0.01
    order = [5, 0, 1, 2, 3, 4]
    msg = _command(rows[:, order], names=[NAMES[i] for i in order])
    np.testing.assert_array_equal(conversions.read_command_trajectory(msg, 0, 100 * MS), rows)
    # stamped now, ending within the command timeout, and stamp 0 (start now) long after
    msg = _command(rows, start_ns=5 * MS)
    conversions.read_command_trajectory(msg, 100 * MS, 100 * MS)
    conversions.read_command_trajectory(_command(rows), 10 ** 12, 100 * MS)


def _point_change(field, k, value):
    def change(msg):
        setattr(msg.points[k], field, value)
        return msg
    return change


@pytest.mark.parametrize('change, reason', [
    (lambda m: _command(np.zeros((3, 6)), [0, 2 * MS, 2 * MS]), 'times not increasing'),
    (lambda m: _command(np.zeros((3, 6)), [0, 3 * MS, 2 * MS]), 'times not increasing'),
    (lambda m: _command(np.zeros((2, 6)), [-2 * 10 ** 9, MS]), 'negative time_from_start'),
    (_point_change('positions', 0, [np.nan] + [0.0] * 5), 'non-finite positions'),
    (_point_change('positions', 1, [np.inf] + [0.0] * 5), 'non-finite positions'),
    (_point_change('velocities', 0, [np.nan] + [0.0] * 5), 'non-finite velocities'),
    (_point_change('accelerations', 2, [0.0] * 5 + [-np.inf]), 'non-finite accelerations'),
    (_point_change('velocities', 1, [0.0] * 5), 'wrong velocities length'),
    (_point_change('positions', 0, [0.0] * 7), 'wrong positions length'),
    (_point_change('effort', 2, [0.0] * 6), 'effort in a position command'),
    (lambda m: _command(np.zeros((3, 6)), names=NAMES[:5] + ['joint_7']), 'wrong joint names'),
    (lambda m: _command(np.zeros((3, 6)), names=[NAMES[0]] * 6), 'wrong joint names'),
    (lambda m: _command(np.zeros((0, 6))), 'empty trajectory'),
    (lambda m: _command(np.zeros((3, 6)), start_ns=10 * MS), 'trajectory ends in the past'),
    (lambda m: _command(np.zeros((3, 6)), start_ns=10 ** 12), 'stamp in the future'),
])
def test_a_trajectory_command_joint_trajectory_controller_refuses(change, reason):
    msg = change(_command(np.zeros((3, 6))))
    # now 1 s, command timeout 100 ms: stamp 10 ms + 2 ms is 888 ms too old
    assert _reason(conversions.read_command_trajectory, msg, 10 ** 9, 100 * MS) == reason


def _set(info, index, value):
    p = list(info.p)
    p[index] = value
    info.p = p


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
