"""
ABB IRB 4600 kinematics: DH model (eq. 4-7), fiducial points (eq. 8-10), analytic IK (eq. 43).

Frames follow the paper's Table 1 (Denavit-Hartenberg, eq. 4-5)::

    link   a_i   alpha_i   d_i   theta_i
    1      a1    -pi/2     L1    q1
    2      L2     0        0     q2 - pi/2
    3      L3    -pi/2     0     q3
    4      0      pi/2     L4    q4
    5      0     -pi/2     0     q5
    6      0      0        Lt    q6 + pi

With q = 0 the flange {E} is at (a1 + L4 + Lt, 0, L1 + L2 + L3) = (1.27, 0, 1.57) m with
R = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]] (docs/design.md §5).

The inverse kinematics is the closed form of an elbow manipulator with a spherical wrist:
the wrist centre p_w = p_E - Lt * z6 fixes q1..q3 (two shoulder and two elbow branches),
the wrist orientation R_6^3 = (R_3^0)^T R fixes q4..q6 (two wrist branches). Joints whose
range exceeds 2*pi (J4, J6: +-400 deg) have several equivalent angles; the one nearest the
seed is taken.
"""

from dataclasses import dataclass, field, replace
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validate import as_array, as_transform
from .errors import InvalidInputError, UnreachablePoseError
from .joint_limits import IRB4600_60_205
from .tool import TOOL


@dataclass(frozen=True)
class RobotParams:
    """
    Geometry and joint limits of the IRB 4600-60/2.05 (paper Appendix, Table 2).

    Lengths in metres, angles in radians, speeds in rad/s. Joint ranges and speed limits
    are ABB's product specification for the IRB 4600-60/2.05 (docs/design.md §5), applied to
    the paper's DH angles q (which share the zero pose and signs of ABB's axes 1-6), read
    from the arm's joint_limits file (:data:`.joint_limits.IRB4600_60_205`).
    """

    a1: float = 0.175
    L1: float = 0.495
    L2: float = 0.9
    L3: float = 0.175
    L4: float = 0.96
    Lt: float = 0.135
    L_tool: float = TOOL.length_m
    q_min: tuple = field(default=IRB4600_60_205.min_position)
    q_max: tuple = field(default=IRB4600_60_205.max_position)
    qd_max: tuple = field(default=IRB4600_60_205.max_velocity)

    def __post_init__(self):
        """Check lengths and limits once, so that every function can trust them."""
        for name in ('a1', 'L1', 'L2', 'L3', 'L4', 'Lt', 'L_tool'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise InvalidInputError(f'RobotParams.{name} must be finite and > 0, got {value}')
        lo, hi = np.asarray(self.q_min, float), np.asarray(self.q_max, float)
        if lo.shape != (6,) or hi.shape != (6,) or not np.all(lo < hi):
            raise InvalidInputError(
                'RobotParams: q_min and q_max need 6 values with q_min < q_max')
        if np.asarray(self.qd_max, float).shape != (6,):
            raise InvalidInputError('RobotParams: qd_max needs 6 values')

    def scaled(self, l2_scale: float = 1.0, l4_scale: float = 1.0) -> 'RobotParams':
        """
        Return a copy with L2 and L4 multiplied by factors: model uncertainty, Figure 13.

        Parameters
        ----------
        l2_scale, l4_scale : float
            Factors of L2 and L4.

        Returns
        -------
        RobotParams

        """
        return replace(self, L2=self.L2 * l2_scale, L4=self.L4 * l4_scale)

    def dh_table(self) -> NDArray[np.float64]:
        """Return Table 1 as rows (a_i, alpha_i, d_i, theta offset_i); theta_i = q_i + offset_i."""
        return np.array([
            [self.a1, -math.pi / 2, self.L1, 0.0],
            [self.L2, 0.0, 0.0, -math.pi / 2],
            [self.L3, -math.pi / 2, 0.0, 0.0],
            [0.0, math.pi / 2, self.L4, 0.0],
            [0.0, -math.pi / 2, 0.0, 0.0],
            [0.0, 0.0, self.Lt, math.pi],
        ])

    @property
    def fiducials_E(self) -> NDArray[np.float64]:
        """Fiducial points in {E}: P1 = [0, 0, 0], P2 = [0, 0, L_tool / 2] (section 3.1)."""
        return np.array([[0.0, 0.0, 0.0], [0.0, 0.0, self.L_tool / 2.0]])

    def within_limits(self, q: ArrayLike, tol: float = 1e-9) -> bool:
        """
        Return True when every joint angle lies inside its range (with ``tol`` slack).

        Parameters
        ----------
        q : array_like, shape (6,)
            Joint angles (rad).
        tol : float
            Slack beyond each limit (rad).

        Returns
        -------
        bool

        """
        q = np.asarray(q, float)
        return bool(np.all(q >= np.asarray(self.q_min) - tol)
                    and np.all(q <= np.asarray(self.q_max) + tol))


IRB4600 = RobotParams()


def dh_transform(a: float, alpha: float, d: float, theta: float) -> NDArray[np.float64]:
    """
    Return A_i^{i-1} = Rot_z(theta) Trans_z(d) Trans_x(a) Rot_x(alpha), eq. (5).

    Parameters
    ----------
    a, d : float
        Link length and offset (m).
    alpha, theta : float
        Link twist and joint angle (rad).

    Returns
    -------
    ndarray, shape (4, 4)
        A_i^{i-1}.

    """
    return np.array(_dh_rows(a, alpha, d, math.cos(theta), math.sin(theta)))


def _dh_rows(a, alpha, d, ct, st):
    """Return the rows of A_i^{i-1} (eq. 5) from cos and sin of theta (floats or arrays)."""
    ca, sa = math.cos(alpha), math.sin(alpha)
    return ((ct, -st * ca, st * sa, a * ct),
            (st, ct * ca, -ct * sa, a * st),
            (0.0, sa, ca, d),
            (0.0, 0.0, 0.0, 1.0))


def _check_q(q):
    return as_array(q, (6,), 'q')


def joint_frames(q: ArrayLike, params: RobotParams = IRB4600) -> NDArray[np.float64]:
    """
    Return T_i^0 for i = 0..6; T_6^0 = T_E^O (eq. 7).

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    ndarray, shape (7, 4, 4)
        T_0^0 = I, T_1^0, ..., T_6^0.

    """
    q = _check_q(q)
    frames = np.empty((7, 4, 4))
    frames[0] = np.eye(4)
    for i, (a, alpha, d, offset) in enumerate(params.dh_table()):
        frames[i + 1] = frames[i] @ dh_transform(a, alpha, d, q[i] + offset)
    return frames


def forward_kinematics_batch(qs: ArrayLike, params: RobotParams = IRB4600
                             ) -> NDArray[np.float64]:
    """
    Return T_E^O(q) (eq. 7) for each row of ``qs``, bit for bit :func:`forward_kinematics`.

    One product A_1^0 ... A_6^5 per row, as :func:`joint_frames` builds it: the same
    operations in the same order (cos and sin from :mod:`math`, numpy's matmul of each 4x4
    pair), so that a pose does not depend on whether it was computed alone or in a batch
    (the simulator's evaluation poses).

    Parameters
    ----------
    qs : array_like, shape (n, 6)
        Joint angles (rad), one posture per row.
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    ndarray, shape (n, 4, 4)
        T_E^O of each row.

    """
    qs = np.asarray(qs, dtype=float).reshape(-1, 6)
    out = np.broadcast_to(np.eye(4), (len(qs), 4, 4)).copy()
    cos, sin = np.frompyfunc(math.cos, 1, 1), np.frompyfunc(math.sin, 1, 1)
    for i, (a, alpha, d, offset) in enumerate(params.dh_table()):
        theta = qs[:, i] + offset
        A = np.empty((len(qs), 4, 4))
        for r, row in enumerate(_dh_rows(a, alpha, d, cos(theta).astype(float),
                                         sin(theta).astype(float))):
            for c, value in enumerate(row):
                A[:, r, c] = value
        out = out @ A
    return out


def forward_kinematics(q: ArrayLike, params: RobotParams = IRB4600) -> NDArray[np.float64]:
    """
    Return T_E^O(q) = A_1^0 ... A_6^5, eq. (7).

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    ndarray, shape (4, 4)
        T_E^O.

    """
    return joint_frames(q, params)[6]


def fiducial_points(q: ArrayLike, params: RobotParams = IRB4600) -> NDArray[np.float64]:
    """
    Return the two fiducial points in {O}, eq. (8)-(10).

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    ndarray, shape (2, 3)
        P1 and P2 in {O} (m).

    """
    tf = forward_kinematics(q, params)
    return params.fiducials_E @ tf[:3, :3].T + tf[:3, 3]


def point_jacobian(q: ArrayLike, point_E: ArrayLike,
                   params: RobotParams = IRB4600) -> NDArray[np.float64]:
    """
    Return d p^O / dq for a point fixed in {E}, p^O = T_E^O(q) p^E.

    Column i is z_{i-1} x (p - o_{i-1}) for the revolute joint i (geometric Jacobian).

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    point_E : array_like, shape (3,)
        The point in {E} (m).
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    ndarray, shape (3, 6)
        d p^O / dq (m / rad).

    """
    frames = joint_frames(q, params)
    point_E = as_array(point_E, (3,), 'point_E')
    p = frames[6, :3, :3] @ point_E + frames[6, :3, 3]
    z = frames[:6, :3, 2]
    o = frames[:6, :3, 3]
    return np.cross(z, p - o).T


def geometric_jacobian(q: ArrayLike, params: RobotParams = IRB4600) -> NDArray[np.float64]:
    """
    Return the geometric Jacobian of the flange: rows (v, omega) in {O}.

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    ndarray, shape (6, 6)
        Linear (m / rad) over angular (rad / rad) velocity rows.

    """
    frames = joint_frames(q, params)
    z = frames[:6, :3, 2]
    o = frames[:6, :3, 3]
    jac = np.empty((6, 6))
    jac[:3] = np.cross(z, frames[6, :3, 3] - o).T
    jac[3:] = z.T
    return jac


def condition_number(q: ArrayLike, params: RobotParams = IRB4600) -> float:
    """
    Return sigma_max / sigma_min of :func:`geometric_jacobian` at ``q`` (inf: singular).

    The measure MoveIt Servo scales velocity by near a singularity (the safety envelope,
    ``ibvs_control.envelope``), and the task sampler keeps targets below its slow-down
    threshold.
    """
    s = np.linalg.svd(geometric_jacobian(q, params), compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0.0 else math.inf


def _wrap_pi(angle):
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _arm_solutions(p_wrist, params, q1_seed):
    """
    Return the (q1, q2, q3) triples placing the wrist centre at ``p_wrist`` (eq. 43).

    In the plane of frame {1} the wrist centre is at (x1, y1) with
        x1 = L2 cos(q2') + L3 cos(phi) - L4 sin(phi),
        y1 = L2 sin(q2') + L3 sin(phi) + L4 cos(phi),
    q2' = q2 - pi/2 and phi = q2' + q3: a two-link arm of lengths L2 and
    D = hypot(L3, L4), the second link rotated by gamma = atan2(L4, L3).
    """
    xw, yw, zw = p_wrist
    rho = math.hypot(xw, yw)
    if rho < 1e-12:
        # Shoulder singularity: q1 is free; keep the seed's.
        q1_options = [(q1_seed, -params.a1), (q1_seed + math.pi, -params.a1)]
    else:
        q1 = math.atan2(yw, xw)
        q1_options = [(q1, rho - params.a1), (q1 + math.pi, -rho - params.a1)]
    d_len = math.hypot(params.L3, params.L4)
    gamma = math.atan2(params.L4, params.L3)
    y1 = -(zw - params.L1)
    out = []
    closest = None
    for q1, x1 in q1_options:
        r2 = x1 * x1 + y1 * y1
        cos_beta = (r2 - params.L2 ** 2 - d_len ** 2) / (2.0 * params.L2 * d_len)
        closest = cos_beta if closest is None or abs(cos_beta) < abs(closest) else closest
        if abs(cos_beta) > 1.0 + 1e-12:
            continue
        cos_beta = min(1.0, max(-1.0, cos_beta))
        for beta in {math.acos(cos_beta), -math.acos(cos_beta)}:
            q2p = math.atan2(y1, x1) - math.atan2(d_len * math.sin(beta),
                                                  params.L2 + d_len * math.cos(beta))
            out.append((_wrap_pi(q1), _wrap_pi(q2p + math.pi / 2.0), _wrap_pi(beta - gamma)))
    return out, closest


def _rot_3(q123, params):
    frames = np.eye(4)
    for i, (a, alpha, d, offset) in enumerate(params.dh_table()[:3]):
        frames = frames @ dh_transform(a, alpha, d, q123[i] + offset)
    return frames[:3, :3]


def _wrist_from_axis(axis_3, q4_seed):
    """
    Return the (q4, q5) pairs that point z6 along ``axis_3`` (expressed in {3}).

    R_6^3 = A_4 A_5 A_6 has third column [-c4 s5, -s4 s5, c5]; the two branches are
    s5 > 0 and s5 < 0. At the wrist singularity (s5 = 0) q4 is free; the seed's is kept.
    """
    ax, ay, az = axis_3
    s5 = math.hypot(ax, ay)
    q5 = math.atan2(s5, az)
    if s5 < 1e-12:
        return [(q4_seed, q5)]
    q4 = math.atan2(-ay, -ax)
    return [(_wrap_pi(q4), q5), (_wrap_pi(q4 + math.pi), -q5)]


def _q6_from_rotation(r36, q4, q5):
    """Return q6 such that A_4 A_5 A_6 = R_6^3 given q4, q5 (the rest is a rotation about z6)."""
    c4, s4, c5, s5 = math.cos(q4), math.sin(q4), math.cos(q5), math.sin(q5)
    r35 = np.array([[c4 * c5, -s4, -c4 * s5],
                    [s4 * c5, c4, -s4 * s5],
                    [s5, 0.0, c5]])
    rz = r35.T @ r36
    return _wrap_pi(math.atan2(rz[1, 0], rz[0, 0]) - math.pi)


def _shifts_in_range(angle, lo, hi):
    """Return the angles angle + 2*pi*k inside [lo, hi] (empty when the range misses all)."""
    k_lo = math.ceil((lo - 1e-9 - angle) / (2.0 * math.pi))
    k_hi = math.floor((hi + 1e-9 - angle) / (2.0 * math.pi))
    return angle + 2.0 * math.pi * np.arange(k_lo, k_hi + 1)


def _nearest_within_limits(q, seed, params):
    """Shift each angle by 2*pi multiples into its range, nearest the seed; None if impossible."""
    out = np.empty(6)
    for j in range(6):
        candidates = _shifts_in_range(q[j], params.q_min[j], params.q_max[j])
        if candidates.size == 0:
            return None
        out[j] = candidates[np.argmin(np.abs(candidates - seed[j]))]
    return out


def _joints_out_of_range(q, params):
    """Return the 1-based indices of the joints that no 2*pi shift brings into range."""
    return [j + 1 for j in range(6)
            if _shifts_in_range(q[j], params.q_min[j], params.q_max[j]).size == 0]


def _seed(seed):
    return np.zeros(6) if seed is None else as_array(seed, (6,), 'seed')


def ik_solutions(pose: ArrayLike, params: RobotParams = IRB4600,
                 seed: ArrayLike | None = None) -> list[NDArray[np.float64]]:
    """
    Return every IK branch of T_E^O = ``pose`` within the joint limits (eq. 43).

    Up to 8 branches (shoulder x elbow x wrist); each angle is shifted by 2*pi multiples to
    the value nearest ``seed`` inside its range.

    Parameters
    ----------
    pose : array_like, shape (4, 4)
        T_E^O.
    params : RobotParams
        The robot's geometry.
    seed : array_like, shape (6,), optional
        Joint angles (rad) the 2*pi shifts are chosen nearest to; default zeros.

    Returns
    -------
    list of ndarray, shape (6,)
        The branches' joint angles q (rad).

    Raises
    ------
    UnreachablePoseError
        When no branch exists, with the reason (out of reach, or the joint limits that
        exclude it).

    """
    pose = as_transform(pose, 'pose')
    seed = _seed(seed)
    rot, pos = pose[:3, :3], pose[:3, 3]
    p_wrist = pos - params.Lt * rot[:, 2]
    arms, cos_beta = _arm_solutions(p_wrist, params, seed[0])
    if not arms:
        raise UnreachablePoseError(
            f'pose at {np.round(pos, 4).tolist()} m is out of reach: wrist centre '
            f'{np.round(p_wrist, 4).tolist()} m needs cos(elbow) = {cos_beta:.4f},'
            ' outside [-1, 1]')
    valid, rejected = [], []
    for q123 in arms:
        r36 = _rot_3(q123, params).T @ rot
        for q4, q5 in _wrist_from_axis(r36[:, 2], seed[3]):
            q = np.array([*q123, q4, q5, _q6_from_rotation(r36, q4, q5)])
            shifted = _nearest_within_limits(q, seed, params)
            if shifted is None:
                rejected.append(q)
            else:
                valid.append(shifted)
    if not valid:
        raise UnreachablePoseError(
            f'pose at {np.round(pos, 4).tolist()} m: all {len(rejected)} IK branches violate '
            f'joint limits (joints out of range, per branch: '
            f'{[_joints_out_of_range(q, params) for q in rejected]})')
    return valid


def inverse_kinematics(pose: ArrayLike, params: RobotParams = IRB4600,
                       seed: ArrayLike | None = None) -> NDArray[np.float64]:
    """
    Return the IK branch of T_E^O = ``pose`` nearest ``seed`` (eq. 43).

    Parameters
    ----------
    pose : array_like, shape (4, 4)
        T_E^O.
    params : RobotParams
        The robot's geometry.
    seed : array_like, shape (6,), optional
        Joint angles (rad); default q = 0.

    Returns
    -------
    ndarray, shape (6,)
        q (rad).

    """
    seed_arr = _seed(seed)
    solutions = ik_solutions(pose, params, seed_arr)
    return min(solutions, key=lambda q: float(np.sum((q - seed_arr) ** 2)))


def ik_position_axis(position: ArrayLike, axis: ArrayLike, q6: float,
                     params: RobotParams = IRB4600,
                     seed: ArrayLike | None = None) -> NDArray[np.float64]:
    """
    Return q placing the flange origin at ``position`` with z6 along ``axis``; q6 given.

    This is the inverse (eq. 43) of the two fiducial points, which fix the flange position
    and tool axis but not the roll about it: q6 is unobservable and taken from the caller.

    Parameters
    ----------
    position : array_like, shape (3,)
        The flange origin in {O} (m).
    axis : array_like, shape (3,)
        The tool axis z6 in {O} (any length > 0).
    q6 : float
        Joint 6's angle (rad).
    params : RobotParams
        The robot's geometry.
    seed : array_like, shape (6,), optional
        The branch nearest it is returned; default zeros with q6.

    Returns
    -------
    ndarray, shape (6,)
        q (rad).

    """
    position = as_array(position, (3,), 'position')
    axis = as_array(axis, (3,), 'axis')
    norm = np.linalg.norm(axis)
    if norm < 1e-9:
        raise InvalidInputError('axis: zero length, the tool axis is undefined')
    axis = axis / norm
    seed_arr = _seed(seed).copy()
    seed_arr[5] = float(q6)
    p_wrist = position - params.Lt * axis
    arms, cos_beta = _arm_solutions(p_wrist, params, seed_arr[0])
    if not arms:
        raise UnreachablePoseError(
            f'flange at {np.round(position, 4).tolist()} m is out of reach '
            f'(cos(elbow) = {cos_beta:.4f})')
    best, best_cost = None, math.inf
    for q123 in arms:
        axis_3 = _rot_3(q123, params).T @ axis
        for q4, q5 in _wrist_from_axis(axis_3, seed_arr[3]):
            q = np.array([*q123, q4, q5, seed_arr[5]])
            shifted = _nearest_within_limits(q, seed_arr, params)
            if shifted is None:
                continue
            cost = float(np.sum((shifted - seed_arr) ** 2))
            if cost < best_cost:
                best, best_cost = shifted, cost
    if best is None:
        raise UnreachablePoseError(
            f'flange at {np.round(position, 4).tolist()} m with axis '
            f'{np.round(axis, 4).tolist()}: every IK branch violates the joint limits')
    return best


def tool_axis_angle(rotation: ArrayLike, target_rotation: ArrayLike) -> NDArray[np.float64]:
    """
    Return the angle (rad) between each tool axis z6 and the target's.

    The roll about the tool axis is not controlled (docs/design.md §5): the project's
    tool-axis error compares the axes only.

    Parameters
    ----------
    rotation : array_like, shape (N, 3, 3) or (3, 3)
        Rotations R_E^O of the tool.
    target_rotation : array_like, shape (3, 3)
        The target's.

    Returns
    -------
    ndarray, shape (N,) or ()
        The angles (rad).

    """
    z = np.asarray(rotation, float)[..., :, 2]
    z_target = np.asarray(target_rotation, float)[:, 2]
    cos = np.clip(z @ z_target, -1.0, 1.0)
    # acos loses precision near 1: use the chord instead.
    chord = np.linalg.norm(z - z_target, axis=-1)
    return np.where(cos > 0.0, 2.0 * np.arcsin(np.clip(chord / 2.0, 0.0, 1.0)),
                    np.arccos(cos))


def pose_error(pose_a: ArrayLike, pose_b: ArrayLike) -> tuple[float, float]:
    """
    Return the position and rotation errors between two poses.

    Parameters
    ----------
    pose_a, pose_b : array_like, shape (4, 4)
        Homogeneous transforms.

    Returns
    -------
    tuple of (float, float)
        Position error (m) and rotation angle error (rad).

    """
    pa = np.asarray(pose_a, float)
    pb = np.asarray(pose_b, float)
    dpos = float(np.linalg.norm(pa[:3, 3] - pb[:3, 3]))
    # ||Ra - Rb||_F = 2 sqrt(2) sin(angle / 2): accurate for small angles, unlike acos.
    chord = np.linalg.norm(pa[:3, :3] - pb[:3, :3]) / (2.0 * math.sqrt(2.0))
    return dpos, float(2.0 * math.asin(min(1.0, chord)))


def pose_from(position: ArrayLike, rotation: ArrayLike) -> NDArray[np.float64]:
    """
    Return the homogeneous transform with the given position and rotation.

    Parameters
    ----------
    position : array_like, shape (3,)
        Translation (m).
    rotation : array_like, shape (3, 3)
        Rotation matrix.

    Returns
    -------
    ndarray, shape (4, 4)

    """
    tf = np.eye(4)
    tf[:3, :3] = as_array(rotation, (3, 3), 'rotation')
    tf[:3, 3] = as_array(position, (3,), 'position')
    return tf
