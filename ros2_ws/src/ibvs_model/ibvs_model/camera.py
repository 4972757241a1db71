"""
ZED 2 stereo camera model: pose (eq. 12-15), projection (eq. 16-22), triangulation.

Frame {C} is the paper's: midway between the two lenses, x right, y down, z along the
parallel optical axes. The paper's lenses share the intrinsics (f_u, f_v, c_u, c_v), no
skew. A rectified pair may instead give each lens its own horizontal focal length and
principal point (f_u, c_u on the left, f_u' and c_u' on the right: older ZED SDKs publish
701.40 and 696.83 px); rows stay common (f_v, c_v), which is what rectified means.

Sign convention (docs/design.md §5). The paper's eq. (19)-(20) put the left lens at
X = +b/2, so that u_r > u_l. ROS puts the left lens at x = -b/2 (x to the right), and the
right camera's CameraInfo has P[3] = -f_u * b. This module follows ROS:

    u_l = f_u (X + b/2) / Z + c_u,   u_r = f_u (X - b/2) / Z + c_u,   v = f_v Y / Z + c_v

so the disparity u_l - u_r = f_u b / Z is positive. With c_u = c_v = 0 and b -> -b these
are exactly eq. (18)-(20). With lenses of their own, u_r = f_u' (X - b/2) / Z + c_u' (the
right CameraInfo's P = [f_u' 0 c_u' -f_u' b; 0 f_v c_v 0; 0 0 1 0] applied to a point of
the left lens's frame, x_left = X + b/2), and depth comes from the normalised disparity:
(u_l - c_u) / f_u - (u_r - c_u') / f_u' = b / Z.

Pixel coordinates follow OpenCV: the centre of pixel (i, j) is at u = i, v = j, so an
image W pixels wide spans u in [-0.5, W - 0.5] and its centre is c_u = (W - 1) / 2.
"""

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validate import as_array, as_transform
from .errors import BehindCameraError, InvalidInputError, TriangulationError

ZED2_FOCAL_LENGTH_M = 2.8e-3
ZED2_BASELINE_M = 0.12
ZED2_HFOV_DEG = 86.09
ZED2_VFOV_DEG = 55.35
#: The ZED 2's modes at their native size (width, height): what its SDK grabs and the
#: wrapper publishes with ``general.pub_resolution: NATIVE``.
ZED2_RESOLUTIONS = {'HD720': (1280, 720), 'VGA': (672, 376), 'HD1080': (1920, 1080),
                    'HD2K': (2208, 1242)}


@dataclass(frozen=True)
class StereoIntrinsics:
    """
    Intrinsics of both images, and the baseline b (m) between the lenses.

    ``fu``, ``cu`` are the left lens's; ``right_fu``, ``right_cu`` the right lens's where
    they differ (None: the left's, the paper's camera). ``fv``, ``cv`` are both lenses'
    (a rectified pair shares its rows).
    """

    width: int
    height: int
    fu: float
    fv: float
    cu: float
    cv: float
    baseline: float
    right_fu: float | None = None
    right_cu: float | None = None

    def __post_init__(self):
        """Reject sizes, focal lengths and baselines that make the model meaningless."""
        if int(self.width) != self.width or int(self.height) != self.height \
                or self.width <= 0 or self.height <= 0:
            raise InvalidInputError(
                f'image size must be positive integers, got {self.width} x {self.height}')
        for name in ('fu', 'fv', 'baseline'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise InvalidInputError(f'{name} must be finite and > 0, got {value}')
        for name in ('cu', 'cv'):
            if not math.isfinite(getattr(self, name)):
                raise InvalidInputError(f'{name} must be finite')
        if self.right_fu is not None and not (math.isfinite(self.right_fu)
                                              and self.right_fu > 0.0):
            raise InvalidInputError(f'right_fu must be finite and > 0, got {self.right_fu}')
        if self.right_cu is not None and not math.isfinite(self.right_cu):
            raise InvalidInputError('right_cu must be finite')

    @property
    def fu_r(self) -> float:
        """Return the right lens's horizontal focal length f_u' (px)."""
        return self.fu if self.right_fu is None else self.right_fu

    @property
    def cu_r(self) -> float:
        """Return the right lens's principal point c_u' (px)."""
        return self.cu if self.right_cu is None else self.right_cu

    @property
    def same_lenses(self) -> bool:
        """Return whether both lenses have the same f_u and c_u (the paper's camera)."""
        return self.fu_r == self.fu and self.cu_r == self.cu

    @classmethod
    def from_fov(cls, width: int, height: int, hfov_deg: float = ZED2_HFOV_DEG,
                 vfov_deg: float = ZED2_VFOV_DEG, baseline: float = ZED2_BASELINE_M,
                 cu: float | None = None, cv: float | None = None) -> 'StereoIntrinsics':
        """
        Pinhole intrinsics from the image size and the field of view (paper Appendix).

        f_u = (W / 2) / tan(alpha / 2), f_v = (H / 2) / tan(beta / 2); principal point at the
        image centre unless given. ZED 2 at HD720: f_u ~ 686 px.

        Parameters
        ----------
        width, height : int
            Image size (px).
        hfov_deg, vfov_deg : float
            Horizontal and vertical field of view alpha, beta (deg), in (0, 180).
        baseline : float
            Distance b between the lenses (m).
        cu, cv : float, optional
            Principal point (px); default the image centre ((W - 1) / 2, (H - 1) / 2).

        Returns
        -------
        StereoIntrinsics

        """
        for name, value in (('hfov_deg', hfov_deg), ('vfov_deg', vfov_deg)):
            if not (math.isfinite(value) and 0.0 < value < 180.0):
                raise InvalidInputError(f'{name} must be in (0, 180) degrees, got {value}')
        fu = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        fv = (height / 2.0) / math.tan(math.radians(vfov_deg) / 2.0)
        return cls(int(width), int(height), fu, fv,
                   (width - 1) / 2.0 if cu is None else float(cu),
                   (height - 1) / 2.0 if cv is None else float(cv), float(baseline))

    @classmethod
    def zed2(cls, resolution: str = 'HD720', downscale: float = 1.0) -> 'StereoIntrinsics':
        """
        ZED 2 intrinsics at one of its modes, as published at a downscale of it.

        Parameters
        ----------
        resolution : str
            'HD720' (default), 'VGA', 'HD1080' or 'HD2K' (:data:`ZED2_RESOLUTIONS`).
        downscale : float
            The native size divided by this, rounded (>= 1; 1: native): zed-ros2-wrapper's
            ``general.pub_downscale_factor`` with ``general.pub_resolution: 'CUSTOM'``. The
            field of view stays; the focal length in pixels shrinks with the size.

        Returns
        -------
        StereoIntrinsics

        """
        if resolution not in ZED2_RESOLUTIONS:
            raise InvalidInputError(
                f'resolution must be one of {sorted(ZED2_RESOLUTIONS)}, got {resolution!r}')
        if not (math.isfinite(downscale) and downscale >= 1.0):
            raise InvalidInputError(f'downscale must be >= 1, got {downscale}')
        width, height = ZED2_RESOLUTIONS[resolution]
        return cls.from_fov(int(round(width / downscale)), int(round(height / downscale)))

    @property
    def K(self) -> NDArray[np.float64]:  # noqa: N802 (the usual name of the camera matrix)
        """Return the 3x3 camera matrix of the left image (eq. 16 with s_c = 0)."""
        return np.array([[self.fu, 0.0, self.cu], [0.0, self.fv, self.cv], [0.0, 0.0, 1.0]])

    @property
    def K_right(self) -> NDArray[np.float64]:  # noqa: N802 (as K)
        """Return the 3x3 camera matrix of the right image."""
        return np.array([[self.fu_r, 0.0, self.cu_r], [0.0, self.fv, self.cv],
                         [0.0, 0.0, 1.0]])


def merge_windows(windows: Iterable[Sequence[int]]) -> list[tuple[int, int, int, int]]:
    """
    Return pixel windows (u0, v0, u1, v1), u1 and v1 excluded, with overlapping ones merged.

    Two windows that share a pixel are replaced by their bounding box, until none overlap;
    the result is sorted. Windows that only touch stay apart.

    Parameters
    ----------
    windows : iterable of (u0, v0, u1, v1)
        The windows.

    Returns
    -------
    list of tuple
        The merged windows, sorted.

    """
    boxes = [list(w) for w in windows]
    merged = True
    while merged:
        merged = False
        for i in range(len(boxes)):
            for j in range(i + 1, len(boxes)):
                a, b = boxes[i], boxes[j]
                if a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]:
                    boxes[i] = [min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]),
                                max(a[3], b[3])]
                    del boxes[j]
                    merged = True
                    break
            if merged:
                break
    return [tuple(b) for b in sorted(boxes)]


def look_at(eye: ArrayLike, target: ArrayLike,
            up: ArrayLike = (0.0, 0.0, 1.0)) -> NDArray[np.float64]:
    """
    Return T_C^O (eq. 12) of a camera at ``eye`` whose optical axis points at ``target``.

    Columns of the rotation: x right (n), y down (s), z forward (a), with ``up`` pointing
    up in the image.

    Parameters
    ----------
    eye, target : array_like, shape (3,)
        The optical centre and the point looked at, in {O} (m).
    up : array_like, shape (3,)
        The direction in {O} that points up in the image.

    Returns
    -------
    ndarray, shape (4, 4)
        T_C^O.

    """
    eye = as_array(eye, (3,), 'eye')
    target = as_array(target, (3,), 'target')
    up = as_array(up, (3,), 'up')
    z = target - eye
    if np.linalg.norm(z) < 1e-9:
        raise InvalidInputError('look_at: eye and target coincide')
    z = z / np.linalg.norm(z)
    x = np.cross(z, up)
    if np.linalg.norm(x) < 1e-9:
        raise InvalidInputError('look_at: up is parallel to the viewing direction')
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    tf = np.eye(4)
    tf[:3, 0], tf[:3, 1], tf[:3, 2], tf[:3, 3] = x, y, z, eye
    return tf


class StereoCamera:
    """A calibrated stereo pair at a fixed pose T_C^O in the robot base frame {O}."""

    def __init__(self, intrinsics: StereoIntrinsics, pose_C_O: ArrayLike) -> None:
        """
        Store the intrinsics and the pose T_C^O (eq. 12); T_O^C = (T_C^O)^-1 (eq. 13).

        Parameters
        ----------
        intrinsics : StereoIntrinsics
            Intrinsics of both images and the baseline.
        pose_C_O : array_like, shape (4, 4)
            T_C^O, the pose of {C} in {O}.

        """
        if not isinstance(intrinsics, StereoIntrinsics):
            raise InvalidInputError('intrinsics must be a StereoIntrinsics')
        self.intrinsics = intrinsics
        self.pose_C_O = as_transform(pose_C_O, 'pose_C_O')
        self._rot_O_C = self.pose_C_O[:3, :3].T
        self._pos = self.pose_C_O[:3, 3]

    def to_camera(self, points_O: ArrayLike) -> NDArray[np.float64]:
        """
        Return points of {O} expressed in {C}, eq. (14)-(15).

        Parameters
        ----------
        points_O : array_like, shape (N, 3)
            Points in {O} (m).

        Returns
        -------
        ndarray, shape (N, 3)
            The same points in {C} (m).

        """
        points_O = as_array(points_O, (None, 3), 'points_O')
        return (points_O - self._pos) @ self._rot_O_C.T

    def to_base(self, points_C: ArrayLike) -> NDArray[np.float64]:
        """
        Return points of {C} expressed in {O}.

        Parameters
        ----------
        points_C : array_like, shape (N, 3)
            Points in {C} (m).

        Returns
        -------
        ndarray, shape (N, 3)
            The same points in {O} (m).

        """
        points_C = as_array(points_C, (None, 3), 'points_C')
        return points_C @ self._rot_O_C + self._pos

    def project_camera(self, points_C: ArrayLike) -> NDArray[np.float64]:
        """
        Return (u_l, u_r, v) rows of points given in {C}, eq. (16)-(22), ROS signs.

        Parameters
        ----------
        points_C : array_like, shape (N, 3)
            Points in {C} (m).

        Returns
        -------
        ndarray, shape (N, 3)
            Rows (u_l, u_r, v) (px).

        Raises
        ------
        BehindCameraError
            For a point with Z^C <= 0.

        """
        points_C = as_array(points_C, (None, 3), 'points_C')
        z = points_C[:, 2]
        if np.any(z <= 1e-9):
            idx = int(np.argmin(z))
            raise BehindCameraError(
                f'point {idx} is behind the camera (Z^C = {z[idx]:.4g} m <= 0): no projection')
        k = self.intrinsics
        half_b = k.baseline / 2.0
        out = np.empty_like(points_C)
        out[:, 0] = k.fu * (points_C[:, 0] + half_b) / z + k.cu
        out[:, 1] = k.fu_r * (points_C[:, 0] - half_b) / z + k.cu_r
        out[:, 2] = k.fv * points_C[:, 1] / z + k.cv
        return out

    def project(self, points_O: ArrayLike) -> NDArray[np.float64]:
        """
        Return (u_l, u_r, v) rows of points given in {O} (eq. 14-22).

        Parameters
        ----------
        points_O : array_like, shape (N, 3)
            Points in {O} (m).

        Returns
        -------
        ndarray, shape (N, 3)
            Rows (u_l, u_r, v) (px).

        """
        return self.project_camera(self.to_camera(points_O))

    def projection_jacobian(self, point_O: ArrayLike) -> NDArray[np.float64]:
        """
        Return d(u_l, u_r, v) / d p^O at one point of {O}.

        Parameters
        ----------
        point_O : array_like, shape (3,)
            The point in {O} (m).

        Returns
        -------
        ndarray, shape (3, 3)
            The derivative of eq. (14)-(22) (px / m).

        """
        point_C = self.to_camera(as_array(point_O, (3,), 'point_O')[None])[0]
        x, y, z = point_C
        if z <= 1e-9:
            raise BehindCameraError(f'point is behind the camera (Z^C = {z:.4g} m <= 0)')
        k = self.intrinsics
        half_b = k.baseline / 2.0
        d_dc = np.array([
            [k.fu / z, 0.0, -k.fu * (x + half_b) / z ** 2],
            [k.fu_r / z, 0.0, -k.fu_r * (x - half_b) / z ** 2],
            [0.0, k.fv / z, -k.fv * y / z ** 2],
        ])
        return d_dc @ self._rot_O_C

    def triangulate_camera(self, coords: ArrayLike) -> NDArray[np.float64]:
        """
        Return points in {C} from (u_l, u_r, v) rows: the inverse of eq. (19)-(22).

        Z = f_u b / (u_l - u_r), X = (u_l - c_u) Z / f_u - b / 2, Y = (v - c_v) Z / f_v;
        with lenses of their own (:class:`StereoIntrinsics` ``right_fu``, ``right_cu``),
        Z = b / d with the normalised disparity d = (u_l - c_u) / f_u - (u_r - c_u') / f_u'
        (the module docstring), which must then be positive.

        Parameters
        ----------
        coords : array_like, shape (N, 3)
            Rows (u_l, u_r, v) (px).

        Returns
        -------
        ndarray, shape (N, 3)
            The points in {C} (m).

        Raises
        ------
        TriangulationError
            When the disparity is not positive.

        """
        coords = as_array(coords, (None, 3), 'coords')
        k = self.intrinsics
        if k.same_lenses:
            disparity = coords[:, 0] - coords[:, 1]
            what = 'u_l - u_r'
        else:  # in pixels of the left lens, so that the threshold below means the same
            disparity = k.fu * ((coords[:, 0] - k.cu) / k.fu - (coords[:, 1] - k.cu_r) / k.fu_r)
            what = "f_u ((u_l - c_u) / f_u - (u_r - c_u') / f_u')"
        if np.any(disparity <= 1e-12):
            idx = int(np.argmin(disparity))
            raise TriangulationError(
                f'row {idx}: disparity {what} = {disparity[idx]:.4g} px must be > 0')
        z = k.fu * k.baseline / disparity
        out = np.empty_like(coords)
        out[:, 0] = (coords[:, 0] - k.cu) * z / k.fu - k.baseline / 2.0
        out[:, 1] = (coords[:, 2] - k.cv) * z / k.fv
        out[:, 2] = z
        return out

    def triangulate(self, coords: ArrayLike) -> NDArray[np.float64]:
        """
        Return points in {O} from (u_l, u_r, v) rows.

        Parameters
        ----------
        coords : array_like, shape (N, 3)
            Rows (u_l, u_r, v) (px).

        Returns
        -------
        ndarray, shape (N, 3)
            The points in {O} (m).

        """
        return self.to_base(self.triangulate_camera(coords))

    def in_view(self, points_O: ArrayLike, margin_px: float = 0.0) -> NDArray[np.bool_]:
        """
        Return a bool per point: in front of the camera and inside both images.

        Parameters
        ----------
        points_O : array_like, shape (N, 3)
            Points in {O} (m).
        margin_px : float
            Shrinks the image on every side (for example by a marker's radius in pixels, so
            that the whole marker is visible).

        Returns
        -------
        ndarray of bool, shape (N,)

        """
        points_C = self.to_camera(points_O)
        k = self.intrinsics
        front = points_C[:, 2] > 1e-9
        out = np.zeros(len(points_C), dtype=bool)
        if np.any(front):
            uv = self.project_camera(points_C[front])
            lo_u, hi_u = -0.5 + margin_px, k.width - 0.5 - margin_px
            lo_v, hi_v = -0.5 + margin_px, k.height - 0.5 - margin_px
            inside = ((uv[:, 0] >= lo_u) & (uv[:, 0] <= hi_u) & (uv[:, 1] >= lo_u)
                      & (uv[:, 1] <= hi_u) & (uv[:, 2] >= lo_v) & (uv[:, 2] <= hi_v))
            out[front] = inside
        return out
