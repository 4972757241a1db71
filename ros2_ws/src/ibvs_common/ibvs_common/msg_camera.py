"""
sensor_msgs Image and CameraInfo <-> arrays and :class:`ibvs_model.StereoIntrinsics`.

Each CameraInfo is checked as a lens of a rectified pinhole pair (:func:`check_camera_info`),
the two as a pair by :func:`intrinsics_from_infos`; with /stereo/pose
(:func:`.msg_pose.read_camera_pose`) they give the :class:`ibvs_model.StereoCamera`
(:func:`camera_from_msgs`). Readers raise :class:`.input_error.InputError`.
"""

from array import array as Array
import math

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Pose, PoseStamped
from ibvs_model import StereoCamera, StereoIntrinsics
import numpy as np
from numpy.typing import ArrayLike
from sensor_msgs.msg import CameraInfo, Image

from . import contract
from .input_error import InputError
from .msg_pose import read_camera_pose
from .msg_time import ns_stamp


def image_msg(array: ArrayLike, stamp: int | Time, encoding: str = 'rgb8',
              frame_id: str = '') -> Image:
    """
    Return an (H, W, 3) uint8 array as a sensor_msgs/Image of ``encoding``.

    ``encoding`` rgb8 or bgr8: the array's channels as they are, in that order; bgra8
    (zed-ros2-wrapper's): the array is taken as RGB, reordered to BGR and given an opaque
    alpha channel.
    """
    array = np.ascontiguousarray(array, dtype=np.uint8)
    if array.ndim != 3 or array.shape[2] != 3:
        raise ValueError('array must be (H, W, 3)')
    if encoding == 'bgra8':
        import cv2  # here: of all the messages, only the ZED wrapper's encoding needs it
        # 0.12 ms an HD720 image, where numpy's reversed view and concatenation take 3.3
        array = cv2.cvtColor(array, cv2.COLOR_RGB2BGRA)
    msg = Image()
    msg.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
    msg.header.frame_id = frame_id
    msg.height, msg.width = int(array.shape[0]), int(array.shape[1])
    msg.encoding = encoding
    msg.is_bigendian = 0
    msg.step = array.shape[2] * msg.width
    data = Array('B')
    data.frombytes(array)
    # The one copy of the pixels: the generated setter copies even an array('B') (its
    # fast path is under ROS_PYTHON_CHECK_FIELDS only), 1.5 ms of a 2.7 MB HD720 image.
    msg._data = data
    return msg


def camera_infos(intrinsics: StereoIntrinsics, stamp: int | Time,
                 frames: tuple[str, str] = (contract.LEFT_CAMERA_FRAME,
                                            contract.RIGHT_CAMERA_FRAME)
                 ) -> tuple[CameraInfo, CameraInfo]:
    """
    Return (left, right) CameraInfo of a rectified stereo pair (ROS conventions).

    Each has K = [[f_u, 0, c_u], [0, f_v, c_v], [0, 0, 1]] of its lens (the right's f_u',
    c_u' where they differ: :class:`ibvs_model.StereoIntrinsics`), no distortion, and
    P = [K | t] with t = 0 on the left and t = (-f_u' b, 0, 0) on the right (as
    zed-ros2-wrapper fills it); ``frames`` are their frame ids.
    """
    k = intrinsics
    infos = []
    for frame, tx, fu, cu in zip(frames, (0.0, -k.fu_r * k.baseline), (k.fu, k.fu_r),
                                 (k.cu, k.cu_r)):
        info = CameraInfo()
        info.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
        info.header.frame_id = frame
        info.width, info.height = int(k.width), int(k.height)
        info.distortion_model = 'plumb_bob'
        info.d = [0.0] * 5
        info.k = [fu, 0.0, cu, 0.0, k.fv, k.cv, 0.0, 0.0, 1.0]
        info.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        info.p = [fu, 0.0, cu, tx, 0.0, k.fv, k.cv, 0.0, 0.0, 0.0, 1.0, 0.0]
        infos.append(info)
    return tuple(infos)


#: Largest image side (px) a CameraInfo may give: above any stereo camera's (ZED 2: 2208),
#: far below sizes whose images could not be held in memory.
MAX_IMAGE_SIDE_PX = 8192
#: Narrowest and widest field of view (deg, each axis) of a rectified pinhole lens that is
#: read: 1 deg is a long telephoto lens, 170 deg more than a rectified fisheye keeps (a
#: pinhole image cannot reach 180); a ZED 2 has 86 x 55 deg (``ibvs_model.camera``).
#: f = (side / 2) / tan(fov / 2) (Appendix): f_u within 0.044 to 57 times the width, f_v
#: the height (ZED 2 at HD720: 686 px over 1280). No overflow is left: f at most
#: 57.3 * 8192 = 4.7e5 px.
FOV_RANGE_DEG = (1.0, 170.0)
#: Shortest and longest stereo baseline b (m) that is read, b = -P[3] / P[0] of the right
#: lens: a ZED 2 has 0.12 m, a ZED Mini 0.063, the smallest stereo modules about 0.02 and
#: wide rigs a metre or two; 5 mm to 5 m holds all of them with margin.
BASELINE_RANGE_M = (0.005, 5.0)
#: Largest difference (px) between the rows of the left and right lens of a pair that is
#: read as rectified, over the whole image: |c_v - c_v'| + |f_v - f_v'| / f_v * height / 2
#: (a row offset plus a vertical scale, at the image's top or bottom edge). The model has
#: one v per marker for both images (eq. 22) and the detector pairs markers within
#: ``epipolar_tolerance_px`` = 1.5 px of each other's row (ibvs_vision.detector.config) and
#: takes their mean: half a pixel uses a third of that tolerance and biases v by at most
#: 0.25 px against either image. A pair beyond it is not rectified: refused.
ROW_TOLERANCE_PX = 0.5


#: Largest share of f_u that P's skew and vertical-baseline entries may have, and largest
#: difference of its third row from 0 0 1 0: rounding only (a rectified pinhole has 0).
PINHOLE_TOLERANCE = 1e-9
#: Largest difference between the c_u of the left and the right lens, as a share of the
#: width: a rectification that does not align the principal points (OpenCV's stereoRectify
#: without CALIB_ZERO_DISPARITY) moves them by a few per cent; a ZED 2 differs by 4.6 px
#: at HD720 (0.4 %). Beyond it the disparity, hence the depth, is the pair's offset.
CU_TOLERANCE = 0.05


def focal_range_px(side_px: int) -> tuple[float, float]:
    """Return (low, high) of a focal length (px) along an image side of ``side_px``."""
    narrow, wide = FOV_RANGE_DEG
    return ((side_px / 2.0) / math.tan(math.radians(wide) / 2.0),
            (side_px / 2.0) / math.tan(math.radians(narrow) / 2.0))


def check_camera_info(info: CameraInfo) -> None:
    """
    Raise :class:`InputError` unless one CameraInfo can be a lens of the stereo camera.

    Read from the projection matrix P of a rectified lens ([f_u 0 c_u -f_u b; 0 f_v c_v 0;
    0 0 1 0], the ROS convention that zed-ros2-wrapper follows), each refused with its
    reason:

    - 'bad camera_info size': a side outside 1 to :data:`MAX_IMAGE_SIDE_PX` px;
    - 'bad camera_info': P not 12 finite values;
    - 'focal length out of range': f_u or f_v outside :func:`focal_range_px` of its side
      (a field of view outside :data:`FOV_RANGE_DEG`; f_u <= 0 included);
    - 'camera_info not a rectified pinhole': a skew P[1], P[4], a vertical baseline P[7]
      or a third row other than 0 0 1 0 (beyond :data:`PINHOLE_TOLERANCE`), which the
      model, reading f_u, f_v, c_u, c_v and P[3] only, would ignore;
    - 'principal point off the image': c_u outside [0, width] or c_v outside [0, height];
    - 'baseline out of range': |P[3] / P[0]| beyond the longest of
      :data:`BASELINE_RANGE_M` (0 on the left lens; the right's range is checked by
      :func:`intrinsics_from_infos`, which knows which lens it is).

    So a finite but absurd camera (f_u = 1e308, P[3] = -1e300) never reaches
    :mod:`ibvs_model.camera`, where it would overflow to inf.
    """
    if not (0 < info.width <= MAX_IMAGE_SIDE_PX and 0 < info.height <= MAX_IMAGE_SIDE_PX):
        raise InputError('bad camera_info size',
                         f'{info.width} x {info.height}, each side 1 to {MAX_IMAGE_SIDE_PX}')
    p = np.asarray(info.p, dtype=float)
    if p.shape != (12,) or not np.all(np.isfinite(p)):
        raise InputError('bad camera_info', 'P must have 12 finite values')
    for name, f, side in (('f_u', p[0], info.width), ('f_v', p[5], info.height)):
        low, high = focal_range_px(side)
        if not low <= f <= high:
            raise InputError('focal length out of range',
                             f'{name} = {f:.6g} px, {low:.4g} to {high:.4g} px for a side of '
                             f'{side} px (a field of view of {FOV_RANGE_DEG[0]:g} to '
                             f'{FOV_RANGE_DEG[1]:g} deg)')
    skew = (p[1], p[4], p[7], p[8], p[9], p[11])
    if max(map(abs, skew)) > PINHOLE_TOLERANCE * p[0] or abs(p[10] - 1.0) > PINHOLE_TOLERANCE:
        raise InputError('camera_info not a rectified pinhole',
                         f'P = {p.tolist()}: P[1], P[4], P[7] (skew, vertical baseline) '
                         'must be 0 and the third row 0 0 1 0')
    if not (0.0 <= p[2] <= info.width and 0.0 <= p[6] <= info.height):
        raise InputError('principal point off the image',
                         f'({p[2]:.6g}, {p[6]:.6g}) px in a {info.width} x {info.height} '
                         f'image')
    if abs(p[3] / p[0]) > BASELINE_RANGE_M[1]:
        raise InputError('baseline out of range',
                         f'P[3] / P[0] = {p[3] / p[0]:.6g} m, at most '
                         f'{BASELINE_RANGE_M[1]:g} m')


def intrinsics_from_infos(left: CameraInfo, right: CameraInfo) -> StereoIntrinsics:
    """
    Return :class:`StereoIntrinsics` from the left and right CameraInfo.

    Each is checked by :func:`check_camera_info`. The baseline comes from the right
    projection matrix, b = -P[3] / f_u' (its own f_u': the ROS convention, T_x = -f_x' B),
    and must lie within :data:`BASELINE_RANGE_M` ('baseline out of range'; a right
    P[3] >= 0 is no right lens); the left lens is the reference, its P[3] = 0 ('left lens
    with a baseline': e.g. a right CameraInfo on the left topic). Each lens keeps its own
    f_u and c_u (older ZED SDKs: 701.40 and 696.83 px); raises :class:`InputError` when the
    two disagree on size ('camera_info size mismatch') or their rows are not those of a
    rectified pair, f_v and c_v beyond :data:`ROW_TOLERANCE_PX`, or their c_u differ by
    more than :data:`CU_TOLERANCE` of the width ('camera_info not rectified').
    """
    check_camera_info(left)
    check_camera_info(right)
    pl = np.asarray(left.p, dtype=float)
    pr = np.asarray(right.p, dtype=float)
    if (left.width, left.height) != (right.width, right.height):
        raise InputError('camera_info size mismatch',
                         f'{left.width}x{left.height} vs {right.width}x{right.height}')
    rows = abs(pl[6] - pr[6]) + abs(pl[5] - pr[5]) / pl[5] * left.height / 2.0
    if not rows <= ROW_TOLERANCE_PX:
        raise InputError('camera_info not rectified',
                         f'rows differ by up to {rows:.3g} px (f_v {pl[5]:.6g} and '
                         f'{pr[5]:.6g}, c_v {pl[6]:.6g} and {pr[6]:.6g} px), at most '
                         f'{ROW_TOLERANCE_PX:g}')
    if not abs(pl[2] - pr[2]) <= CU_TOLERANCE * left.width:
        raise InputError('camera_info not rectified',
                         f'c_u {pl[2]:.6g} and {pr[2]:.6g} px differ by more than '
                         f'{CU_TOLERANCE:.0%} of the width ({CU_TOLERANCE * left.width:g} px)')
    if pl[3] != 0.0:
        raise InputError('left lens with a baseline', f'left P[3] = {pl[3]:.6g}, must be 0')
    baseline = float(-pr[3] / pr[0])
    if not BASELINE_RANGE_M[0] <= baseline <= BASELINE_RANGE_M[1]:
        raise InputError('baseline out of range',
                         f'right P[3] = {pr[3]:.6g} gives b = {baseline:.6g} m, '
                         f'{BASELINE_RANGE_M[0]:g} to {BASELINE_RANGE_M[1]:g} m')
    try:
        same = pl[0] == pr[0] and pl[2] == pr[2]
        return StereoIntrinsics(int(left.width), int(left.height), float(pl[0]), float(pl[5]),
                                float(pl[2]), float(pl[6]), baseline,
                                right_fu=None if same else float(pr[0]),
                                right_cu=None if same else float(pr[2]))
    except ValueError as exc:
        raise InputError('bad camera_info', str(exc)) from None


def camera_from_msgs(left_info: CameraInfo, right_info: CameraInfo,
                     pose_msg: PoseStamped | Pose) -> StereoCamera:
    """Return the :class:`StereoCamera` described by both CameraInfo and /stereo/pose."""
    return StereoCamera(intrinsics_from_infos(left_info, right_info),
                        read_camera_pose(pose_msg))
