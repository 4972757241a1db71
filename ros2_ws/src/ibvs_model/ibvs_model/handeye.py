"""
Hand-eye calibration of the fixed stereo camera from the tool's own fiducials; numpy, scipy.

An eye-to-hand calibration: the camera stands still, the arm carries the target. The target
is the tool itself: its two spheres sit at known points of the flange frame {E}
(``RobotParams.fiducials_E``), so at joint angles q_i the encoders and the kinematics put
them at known points P_ik of the base frame {O} (``base_link``), and the camera measures
their images p_I,i = (u_l, u_r, v) of each sphere (eq. 2-3; the feature node's
/ibvs/features). The unknown is the camera pose T_C^O (the ``camera_pose`` parameter): six
numbers, against six image coordinates a pose.

The solution (:func:`solve`):

1. a start without a guess (:func:`initial_pose`): each pose's spheres triangulated in {C}
   (eq. 19-22 inverted) and fitted to the P_ik by the least-squares rigid motion (Kabsch:
   the SVD of their cross-covariance);
2. the maximum-likelihood pose for independent, equal pixel errors: the reprojection error
   in pixels, both images, every pose, minimised over the pose T = T_0 Exp(delta)
   (delta: a translation along and a rotation vector about the axes of T_0's {C}) by
   ``scipy.optimize.least_squares`` (Levenberg-Marquardt);
3. a pose whose own RMS residual exceeds ``max_pose_rms_px`` and :data:`OUTLIER_RATIO`
   times the median of the others' (a mismatched or occluded sphere, a joint state of
   another moment: one pose against the rest) is dropped, the worst first, one at a time,
   and the fit repeated, while :data:`MIN_POSES` are left. Residuals high at every pose are
   no outliers but a model that disagrees with the images (encoder offsets, another tool,
   other intrinsics): they are kept, and :func:`describe` warns above
   :data:`RESIDUAL_WARN_PX`;
4. the uncertainty: the covariance sigma^2 (J^T J)^-1 of delta about the result, J the
   Jacobian of the residuals (px per m and per rad) and sigma^2 the residuals' sum of
   squares over their degrees of freedom (6 n - 6): the 1-sigma of each axis of {C}, in
   position and in rotation. It holds for independent detector errors of one spread; it
   does not see errors of the robot's kinematics, of the sphere positions on the tool or
   of the camera's intrinsics, which move the result as a bias.

:func:`draw_poses` draws the poses to visit with both spheres in both images of a nominal
camera (:func:`ibvs_model.scene.in_view_poses`, seeded). A recording of the arm jogged
through poses (joint states at their own rate, features at the camera's) becomes one
measurement per pose where the arm stood still (:func:`stations`).
"""

from collections.abc import Sequence
from dataclasses import dataclass
import math

from ibvs_model import fiducial_points, IRB4600, RobotParams, StereoCamera, StereoIntrinsics
from ibvs_model.errors import ModelError
from ibvs_model.scene import in_view_poses
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

#: Fewest poses a calibration takes: two poses give four points, which fix the six numbers
#: only when not coplanar with the camera's noise; three make a fit with a residual to judge.
MIN_POSES = 3
#: A pose whose RMS residual exceeds this (px) is dropped (module docstring, step 3): the
#: detector's centres are 0.002-0.01 px from the true projection, so this is a gross error.
MAX_POSE_RMS_PX = 0.5
#: ... and exceeds this many times the median of the other poses' RMS residuals.
OUTLIER_RATIO = 5.0
#: An RMS residual (px) above which the result is reported as suspect: ten times the
#: simulated detector's spread (0.003-0.01 px), far below what encoder offsets of tenths of
#: a degree give (docs/real_cell.md).
RESIDUAL_WARN_PX = 0.1
#: The default number of poses to visit.
DEFAULT_POSES = 12
#: Smallest singular value (px per m, per rad scaled to m at 1 m) of the residuals' Jacobian
#: below which the poses do not determine the camera (all alike, or too few points).
MIN_SINGULAR = 1e-6
#: A station (:func:`stations`): the arm counts as still at a frame when every joint stays
#: within ``still_tol_rad`` of its angle at the frame over STILL_WINDOW_S before and after
#: it; a station is a run of still frames at one pose, at least MIN_STATION_FRAMES of them.
STILL_WINDOW_S = 0.25
STILL_TOL_RAD = 1e-4
MIN_STATION_FRAMES = 5


class CalibrationError(ValueError):
    """The measurements do not determine the camera pose (the message says why)."""


@dataclass(frozen=True)
class Calibration:
    """
    A solved camera pose with its residual and uncertainty (:func:`solve`).

    ``pose_C_O``: T_C^O (4, 4). ``rms_px``: the RMS of the residuals of the poses used,
    per image coordinate. ``pose_rms_px``: the RMS of each pose given (NaN for none: every
    pose is fitted, dropped or not). ``used``, ``dropped``: indices of the poses given.
    ``covariance``: (6, 6) of (x, y, z in m, rotation about x, y, z in rad), along the axes
    of the result's {C}. ``sigma_position_m``, ``sigma_rotation_rad``: the square roots of
    its diagonal, (3,) each.
    """

    pose_C_O: NDArray[np.float64]
    rms_px: float
    pose_rms_px: NDArray[np.float64]
    used: tuple[int, ...]
    dropped: tuple[int, ...]
    covariance: NDArray[np.float64]

    @property
    def sigma_position_m(self) -> NDArray[np.float64]:
        """Return the 1-sigma of the position along x, y, z of {C} (m)."""
        return np.sqrt(np.diag(self.covariance)[:3])

    @property
    def sigma_rotation_rad(self) -> NDArray[np.float64]:
        """Return the 1-sigma of the rotation about x, y, z of {C} (rad)."""
        return np.sqrt(np.diag(self.covariance)[3:])


def exp_pose(delta: ArrayLike) -> NDArray[np.float64]:
    """Return the 4x4 transform of ``delta`` = (translation (3), rotation vector (3))."""
    delta = np.asarray(delta, dtype=float)
    tf = np.eye(4)
    tf[:3, :3] = Rotation.from_rotvec(delta[3:]).as_matrix()
    tf[:3, 3] = delta[:3]
    return tf


def pose_values(pose: ArrayLike) -> list[float]:
    """
    Return T_C^O as the ``camera_pose`` parameter's values: x, y, z, qx, qy, qz, qw.

    The quaternion is of unit length with qw >= 0 (one of its two signs, always the same).
    """
    pose = np.asarray(pose, dtype=float)
    quat = Rotation.from_matrix(pose[:3, :3]).as_quat()
    if quat[3] < 0.0:
        quat = -quat
    return [float(v) for v in (*pose[:3, 3], *quat)]


def pose_difference(reference: ArrayLike, pose: ArrayLike
                    ) -> tuple[NDArray[np.float64], float]:
    """
    Return how ``pose`` differs from ``reference``: inv(reference) @ pose.

    Returns (its translation (3,) in m along the reference's axes, its rotation angle in
    deg): the translation's norm and the angle are what "within 1 mm and 0.1 deg" reads.
    """
    diff = np.linalg.inv(np.asarray(reference, float)) @ np.asarray(pose, float)
    angle = np.linalg.norm(Rotation.from_matrix(diff[:3, :3]).as_rotvec())
    return diff[:3, 3], math.degrees(angle)


def _checked(joints, features):
    joints = np.asarray(joints, dtype=float)
    features = np.asarray(features, dtype=float)
    if joints.ndim != 2 or joints.shape[1] != 6 or features.shape != (len(joints), 6):
        raise CalibrationError(f'need n joint vectors (n, 6) and n feature vectors (n, 6), '
                               f'got {joints.shape} and {features.shape}')
    if not (np.all(np.isfinite(joints)) and np.all(np.isfinite(features))):
        raise CalibrationError('joints and features must be finite')
    if len(joints) < MIN_POSES:
        raise CalibrationError(f'{len(joints)} poses measured: a calibration needs at least '
                               f'{MIN_POSES}')
    return joints, features


def marker_points(joints: ArrayLike, params: RobotParams = IRB4600) -> NDArray[np.float64]:
    """Return the spheres' centres in {O} of each pose, (n, 2, 3), from the joint angles."""
    return np.array([fiducial_points(q, params) for q in np.asarray(joints, float)])


def initial_pose(intrinsics: StereoIntrinsics, joints: ArrayLike, features: ArrayLike,
                 params: RobotParams = IRB4600) -> NDArray[np.float64]:
    """
    Return T_C^O that best maps the triangulated spheres onto their kinematic positions.

    Each pose's features triangulated in {C} (``StereoCamera.triangulate_camera``), the
    spheres' centres in {O} from the joint angles; the rigid motion between the two point
    sets by Kabsch's SVD (least squares in metres, no guess needed). Raises
    :class:`CalibrationError` when a disparity is not positive or the points are collinear.
    """
    joints, features = _checked(joints, features)
    try:
        in_c = StereoCamera(intrinsics, np.eye(4)).triangulate_camera(features.reshape(-1, 3))
    except ModelError as exc:
        raise CalibrationError(f'the features do not triangulate: {exc}') from None
    in_o = marker_points(joints, params).reshape(-1, 3)
    mean_c, mean_o = in_c.mean(axis=0), in_o.mean(axis=0)
    u, s, vt = np.linalg.svd((in_c - mean_c).T @ (in_o - mean_o))
    if s[1] < 1e-9 * max(s[0], 1e-300):
        raise CalibrationError('the spheres of all poses lie on one line: visit poses that '
                               'move the tool sideways, not only along its axis')
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rot = vt.T @ np.diag([1.0, 1.0, d]) @ u.T  # in_o = rot @ in_c + t
    tf = np.eye(4)
    tf[:3, :3] = rot
    tf[:3, 3] = mean_o - rot @ mean_c
    return tf


def residuals(intrinsics: StereoIntrinsics, pose_C_O: ArrayLike, points_O: ArrayLike,
              features: ArrayLike) -> NDArray[np.float64]:
    """Return projected minus measured features (px), (n, 6), of the points (n, 2, 3)."""
    points = np.asarray(points_O, dtype=float)
    projected = StereoCamera(intrinsics, pose_C_O).project(points.reshape(-1, 3))
    return projected.reshape(len(points), 6) - np.asarray(features, dtype=float)


def _fit(intrinsics, start, points, features):
    """Return (pose, residuals (n, 6)) of the reprojection fit from ``start``."""
    def fun(delta):
        return residuals(intrinsics, start @ exp_pose(delta), points, features).ravel()
    result = least_squares(fun, np.zeros(6), method='lm', x_scale='jac', xtol=1e-15,
                           ftol=1e-15, gtol=1e-15, max_nfev=2000)
    pose = start @ exp_pose(result.x)
    return pose, residuals(intrinsics, pose, points, features)


def _jacobian(intrinsics, pose, points, features, step=1e-7):
    """Return d(residuals)/d(delta) at delta = 0 about ``pose`` (6 n, 6), central differences."""
    columns = []
    for k in range(6):
        delta = np.zeros(6)
        delta[k] = step
        plus = residuals(intrinsics, pose @ exp_pose(delta), points, features).ravel()
        minus = residuals(intrinsics, pose @ exp_pose(-delta), points, features).ravel()
        columns.append((plus - minus) / (2.0 * step))
    return np.column_stack(columns)


def solve(intrinsics: StereoIntrinsics, joints: ArrayLike, features: ArrayLike,
          params: RobotParams = IRB4600, start: ArrayLike | None = None,
          max_pose_rms_px: float = MAX_POSE_RMS_PX) -> Calibration:
    """
    Return the camera pose T_C^O that best explains the features at the joint angles.

    Parameters
    ----------
    intrinsics : StereoIntrinsics
        The camera's (from its CameraInfo).
    joints : array_like, shape (n, 6)
        The encoders' joint angles of each pose (rad).
    features : array_like, shape (n, 6)
        The measured p_I of each pose, [u_l1, u_r1, v1, u_l2, u_r2, v2] (px).
    params : RobotParams
        The robot's geometry and the spheres' positions on the tool.
    start : array_like, shape (4, 4), optional
        Where the fit starts; default :func:`initial_pose`.
    max_pose_rms_px : float
        A pose whose RMS residual exceeds it is dropped (module docstring, step 3).

    Returns
    -------
    Calibration

    Raises
    ------
    CalibrationError
        Fewer than :data:`MIN_POSES` poses (given or left), features that do not
        triangulate, or poses that do not determine the camera.

    """
    joints, features = _checked(joints, features)
    if start is None:
        start = initial_pose(intrinsics, joints, features, params)
    points = marker_points(joints, params)
    used = list(range(len(joints)))
    dropped = []
    while True:
        pose, res = _fit(intrinsics, np.asarray(start, float), points[used], features[used])
        pose_rms = np.sqrt(np.mean(np.square(res), axis=1))
        worst = int(np.argmax(pose_rms))
        if pose_rms[worst] <= max(max_pose_rms_px,
                                  OUTLIER_RATIO * np.median(np.delete(pose_rms, worst))):
            break
        if len(used) <= MIN_POSES:
            raise CalibrationError(
                f'pose {used[worst]} has an RMS residual of {pose_rms[worst]:.3g} px (more than '
                f'{max_pose_rms_px:g} px) and only {len(used)} poses are left: the features '
                'and the joint states disagree (a mismatched sphere, a joint state of another '
                "moment, or a tool other than the model's)")
        dropped.append(used.pop(worst))
        start = pose
    jac = _jacobian(intrinsics, pose, points[used], features[used])
    singular = np.linalg.svd(jac, compute_uv=False)
    if singular[-1] < MIN_SINGULAR * singular[0]:
        raise CalibrationError(f'the {len(used)} poses do not determine the camera pose (the '
                               'fit is degenerate): visit poses spread over the view, at '
                               'different depths and tool attitudes')
    dof = res.size - 6
    sigma2 = float(np.sum(np.square(res))) / dof if dof > 0 else 0.0
    covariance = sigma2 * np.linalg.inv(jac.T @ jac)
    all_rms = np.sqrt(np.mean(np.square(residuals(intrinsics, pose, points, features)),
                              axis=1))
    return Calibration(pose_C_O=pose, rms_px=float(np.sqrt(np.mean(np.square(res)))),
                       pose_rms_px=all_rms, used=tuple(used), dropped=tuple(sorted(dropped)),
                       covariance=covariance)


def draw_poses(camera: StereoCamera, count: int = DEFAULT_POSES, seed: int = 0,
               params: RobotParams = IRB4600) -> NDArray[np.float64]:
    """
    Return ``count`` joint angle vectors (count, 6) with both spheres in view of ``camera``.

    :func:`ibvs_model.scene.in_view_poses` of the camera (the nominal one: the spheres are
    drawn inside the images with the margin of their radius and 3 px) from
    ``numpy.random.default_rng(seed)``: spread over the workspace in front of the arm, the
    tool pointing down within 35 deg, at least 1 m deep; the same seed, the same poses.
    """
    from ibvs_model import CameraRobotModel
    if count < MIN_POSES:
        raise CalibrationError(f'{count} poses: a calibration needs at least {MIN_POSES}')
    model = CameraRobotModel(camera, params)
    return np.array(in_view_poses(model, count, np.random.default_rng(seed)))


@dataclass(frozen=True)
class Stations:
    """
    The still poses of a recording (:func:`stations`): one measurement each.

    ``joints``, ``features``: (s, 6) means over the station's frames; ``frames``: (s,) how
    many; ``start_s``: (s,) the stamp of its first frame; ``spread_px``: (s,) the RMS over the
    six features of their standard deviation across its frames.
    """

    joints: NDArray[np.float64]
    features: NDArray[np.float64]
    frames: NDArray[np.int_]
    start_s: NDArray[np.float64]
    spread_px: NDArray[np.float64]


def stations(frame_t: ArrayLike, features: ArrayLike, joint_t: ArrayLike, joints: ArrayLike,
             still_tol_rad: float = STILL_TOL_RAD, window_s: float = STILL_WINDOW_S,
             min_frames: int = MIN_STATION_FRAMES) -> Stations:
    """
    Return the stations of a recording: the poses at which the arm stood still.

    Parameters
    ----------
    frame_t : array_like, shape (f,)
        The stamps of the measured frames (s), on the joint states' clock.
    features : array_like, shape (f, 6)
        Their features p_I (px).
    joint_t : array_like, shape (j,)
        The stamps of the joint states (s), increasing.
    joints : array_like, shape (j, 6)
        Their angles (rad).
    still_tol_rad : float
        How far any joint may move over the window about a frame that counts as still.
    window_s : float
        The window before and after each frame (s); a frame without joint states over the
        whole window is not still (the recording's start and end).
    min_frames : int
        Fewest still frames that make a station.

    Returns
    -------
    Stations
        In time order. The angles at a frame are interpolated linearly between the joint
        states that bracket its stamp; consecutive still frames belong to one station while
        every joint stays within ``still_tol_rad`` of its angle at the station's first frame.

    """
    frame_t = np.asarray(frame_t, dtype=float)
    features = np.asarray(features, dtype=float).reshape(len(frame_t), 6)
    joint_t = np.asarray(joint_t, dtype=float)
    joints = np.asarray(joints, dtype=float).reshape(len(joint_t), 6)
    order = np.argsort(frame_t, kind='stable')
    frame_t, features = frame_t[order], features[order]
    groups, current = [], []
    for t, p in zip(frame_t, features):
        still = None
        if len(joint_t) >= 2 and joint_t[0] <= t - window_s and t + window_s <= joint_t[-1]:
            q = np.array([np.interp(t, joint_t, joints[:, i]) for i in range(6)])
            lo, hi = np.searchsorted(joint_t, [t - window_s, t + window_s], side='left')
            near = joints[max(lo - 1, 0):min(hi + 1, len(joint_t))]
            if np.all(np.abs(near - q) <= still_tol_rad):
                still = q
        if still is None or (current and np.any(np.abs(still - current[0][1])
                                                > still_tol_rad)):
            if len(current) >= min_frames:
                groups.append(current)
            current = []
        if still is not None:
            current.append((t, still, p))
    if len(current) >= min_frames:
        groups.append(current)
    out = {'joints': [], 'features': [], 'frames': [], 'start_s': [], 'spread_px': []}
    for group in groups:
        qs = np.array([g[1] for g in group])
        ps = np.array([g[2] for g in group])
        out['joints'].append(qs.mean(axis=0))
        out['features'].append(ps.mean(axis=0))
        out['frames'].append(len(group))
        out['start_s'].append(group[0][0])
        spread = np.var(ps, axis=0, ddof=1) if len(ps) > 1 else np.zeros(6)
        out['spread_px'].append(float(np.sqrt(np.mean(spread))))
    return Stations(joints=np.array(out['joints']).reshape(-1, 6),
                    features=np.array(out['features']).reshape(-1, 6),
                    frames=np.array(out['frames'], dtype=int),
                    start_s=np.array(out['start_s'], dtype=float),
                    spread_px=np.array(out['spread_px'], dtype=float))


def describe(calibration: Calibration, labels: Sequence[str] | None = None) -> list[str]:
    """Return the result in lines of text: pose, residual, uncertainty, dropped poses."""
    c = calibration
    values = pose_values(c.pose_C_O)
    sp = c.sigma_position_m * 1e3
    sr = np.degrees(c.sigma_rotation_rad)
    names = list(labels) if labels is not None else [f'pose {i}' for i in
                                                     range(len(c.pose_rms_px))]
    used_rms = c.pose_rms_px[list(c.used)]
    worst = c.used[int(np.argmax(used_rms))]
    lines = [
        f'camera pose {{C}} in base_link from {len(c.used)} poses:',
        '  position    [' + ', '.join(f'{v:.6f}' for v in values[:3]) + '] m',
        '  quaternion  [' + ', '.join(f'{v:.8f}' for v in values[3:]) + '] (qx, qy, qz, qw)',
        f'  residual    {c.rms_px:.4f} px RMS (worst {names[worst]}: '
        f'{c.pose_rms_px[worst]:.4f} px)',
        f'  1-sigma     position {sp[0]:.4f}, {sp[1]:.4f}, {sp[2]:.4f} mm; rotation '
        f'{sr[0]:.5f}, {sr[1]:.5f}, {sr[2]:.5f} deg (along and about x, y, z of {{C}})',
    ]
    for i in c.dropped:
        lines.append(f'  dropped     {names[i]}: {c.pose_rms_px[i]:.3f} px RMS against the '
                     "others' fit")
    if c.rms_px > RESIDUAL_WARN_PX:
        lines.append(f'warning: the residual, {c.rms_px:.3f} px RMS, is far above a '
                     f"detector's ({RESIDUAL_WARN_PX:g} px at most): the joint angles, the "
                     'kinematics or the tool disagree with the images (encoder offsets, a '
                     "tool other than the model's, the camera_info of another mode), and "
                     'the pose absorbs that disagreement; the uncertainty does not cover it')
    return lines
