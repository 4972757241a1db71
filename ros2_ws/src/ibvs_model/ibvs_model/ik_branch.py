"""
The IK branch nearest the present configuration, within a reach cone, never flipped.

:func:`.robot.ik_solutions` gives up to 8 branches of eq. (43) (shoulder x elbow x wrist);
:func:`.robot.inverse_kinematics` takes the one nearest a seed, whatever it is: from a bad
seed that can be a shoulder-flipped, over-the-head arm (q1 + pi, the wrist centre behind
the shoulder). The reach cone (:class:`ReachCone`) says which arms are acceptable:

- shoulder not flipped: the wrist centre lies in front of joint 2 in the arm's plane
  (x1 = rho cos(q1 - atan2(y_w, x_w)) - a1 > 0, rho the wrist centre's distance from the
  base axis);
- elbow up: q3 > -atan2(L4, L3) + ``elbow_margin_rad`` (q3 = -atan2(L4, L3) is the
  stretched arm, the elbow singularity; below it the elbow is down);
- the wrist centre no higher than ``max_elevation_deg`` above joint 2's horizontal plane
  as seen from joint 2 (not over the head).

:func:`nearest_branch_ik` takes, among the branches inside the cone (and, when asked,
inside the joint limits less a margin, so that the straight joint-space path to it stays
out of the margin: the box of the limits is convex), the one nearest the present joints;
with ``same_arm_as`` it keeps the shoulder and elbow of that configuration, so that a
sequence of targets along a path never flips the arm mid-task.
"""

from dataclasses import dataclass
import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validate import as_array
from .errors import UnreachablePoseError
from .robot import ik_solutions, IRB4600, joint_frames, RobotParams


@dataclass(frozen=True)
class ReachCone:
    """
    The configurations an arm may take (module docstring).

    ``elbow_margin_rad``: least elbow bend from the stretched arm; ``max_elevation_deg``:
    highest the wrist centre may be above joint 2 (deg, from joint 2's horizontal plane).
    """

    elbow_margin_rad: float = 0.0
    max_elevation_deg: float = 75.0


#: The default cone.
REACH_CONE = ReachCone()


def arm_branch(q: ArrayLike, params: RobotParams = IRB4600) -> tuple[int, int]:
    """
    Return the (shoulder, elbow) signs of ``q``: +1 front / elbow up, -1 flipped / down.

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    tuple of (int, int)

    """
    q = as_array(q, (6,), 'q')
    wrist = joint_frames(q, params)[4, :3, 3]
    x1 = math.hypot(wrist[0], wrist[1]) * math.cos(q[0] - math.atan2(wrist[1], wrist[0])) \
        - params.a1
    elbow = q[2] + math.atan2(params.L4, params.L3)
    return (1 if x1 > 0.0 else -1), (1 if elbow > 0.0 else -1)


def in_cone(q: ArrayLike, params: RobotParams = IRB4600, cone: ReachCone = REACH_CONE) -> bool:
    """
    Return whether ``q`` is inside the reach cone (module docstring).

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    params : RobotParams
        The robot's geometry.
    cone : ReachCone
        The cone.

    Returns
    -------
    bool

    """
    q = as_array(q, (6,), 'q')
    frames = joint_frames(q, params)
    shoulder, wrist = frames[1, :3, 3], frames[4, :3, 3]
    if arm_branch(q, params) != (1, 1):
        return False
    if q[2] + math.atan2(params.L4, params.L3) < cone.elbow_margin_rad:
        return False
    rel = wrist - shoulder
    elevation = math.degrees(math.atan2(rel[2], math.hypot(rel[0], rel[1])))
    return elevation <= cone.max_elevation_deg


def _inside_margin(q, params, margin):
    return bool(np.all(q >= np.asarray(params.q_min) + margin)
                and np.all(q <= np.asarray(params.q_max) - margin))


def nearest_branch_ik(pose: ArrayLike, q_present: ArrayLike, params: RobotParams = IRB4600,
                      cone: ReachCone | None = REACH_CONE,
                      same_arm_as: ArrayLike | None = None,
                      margin_rad: float = 0.0) -> NDArray[np.float64]:
    """
    Return the IK branch of ``pose`` nearest ``q_present`` inside the reach cone.

    Candidates are :func:`.robot.ik_solutions` seeded at ``q_present`` (each angle of 2*pi
    period shifted nearest it); those outside ``cone`` (None: no cone), on another arm
    branch than ``same_arm_as`` (None: any), or within ``margin_rad`` of a joint limit are
    left out; the nearest (sum of squares) of the rest is returned. When every branch is
    left out, UnreachablePoseError says why: the caller decides (never a silent flip).
    When the nearest branch overall is inside the cone, this is
    :func:`.robot.inverse_kinematics` (the same array).

    Parameters
    ----------
    pose : array_like, shape (4, 4)
        T_E^O.
    q_present : array_like, shape (6,)
        The present joint angles (rad).
    params : RobotParams
        The robot's geometry.
    cone : ReachCone or None
        The reach cone.
    same_arm_as : array_like, shape (6,), optional
        Keep this configuration's shoulder and elbow (:func:`arm_branch`).
    margin_rad : float
        Least distance from every joint limit (rad).

    Returns
    -------
    ndarray, shape (6,)
        q (rad).

    Raises
    ------
    UnreachablePoseError
        No branch (or none acceptable).

    """
    q_present = as_array(q_present, (6,), 'q_present')
    solutions = ik_solutions(pose, params, q_present)
    arm = None if same_arm_as is None else arm_branch(same_arm_as, params)
    kept = [q for q in solutions
            if (cone is None or in_cone(q, params, cone))
            and (arm is None or arm_branch(q, params) == arm)
            and (margin_rad <= 0.0 or _inside_margin(q, params, margin_rad))]
    if not kept:
        raise UnreachablePoseError(
            f'pose at {np.round(np.asarray(pose)[:3, 3], 4).tolist()} m: none of the '
            f'{len(solutions)} IK branches is inside the reach cone {cone}'
            + ('' if arm is None else f' on the arm branch {arm}')
            + (f' and {margin_rad} rad inside the joint limits' if margin_rad > 0.0 else ''))
    return min(kept, key=lambda q: float(np.sum((q - q_present) ** 2)))


class BranchTracker:
    """
    IK along a task that keeps the arm branch of its first answer: no flip mid-task.

    The first :meth:`solve` takes :func:`nearest_branch_ik` from the present joints; each
    later one asks the same shoulder and elbow (``same_arm_as`` the first answer) and
    the branch nearest the previous answer.
    """

    def __init__(self, params: RobotParams = IRB4600, cone: ReachCone | None = REACH_CONE,
                 margin_rad: float = 0.0) -> None:
        """Keep the geometry, the cone and the margin; no branch chosen yet."""
        self.params, self.cone, self.margin_rad = params, cone, float(margin_rad)
        self.first = self.last = None

    def solve(self, pose: ArrayLike, q_present: ArrayLike | None = None) -> NDArray[np.float64]:
        """Return the branch of ``pose`` (q_present: the seed of the first call, else last)."""
        seed = self.last if q_present is None and self.last is not None else q_present
        if seed is None:
            raise ValueError('BranchTracker.solve: the first call needs q_present')
        q = nearest_branch_ik(pose, seed, self.params, self.cone, self.first, self.margin_rad)
        if self.first is None:
            self.first = q.copy()
        self.last = q
        return q
