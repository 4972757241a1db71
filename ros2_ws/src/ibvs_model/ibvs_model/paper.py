"""
Numbers of the paper's section 5 and of docs/design.md §5, in one place.

Poses are T_E^O of the flange {E}; the paper prints rotations with four digits, so
:func:`nearest_rotation` makes them orthonormal before they are used as IK targets.
"""

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validate import nearest_rotation
from .errors import InvalidInputError
from .robot import pose_from

#: Target pose (section 5.1): P = [-1, 0.2, 0.3] m, tool pointing down.
TARGET_POSITION = (-1.0, 0.2, 0.3)
TARGET_ROTATION = ((0.0, -1.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 0.0, -1.0))

#: Scenario 1 start: both fiducials in view (rotation as printed, four digits).
SCENARIO1_POSITION = (1.404, 0.228, 1.171)
SCENARIO1_ROTATION_PRINTED = ((-0.4893, -0.0262, 0.8717),
                              (0.2427, 0.9560, 0.1650),
                              (-0.8377, 0.2932, -0.4614))

#: Scenarios 2 and 3 start: fiducials out of view; 1.5 cm from FK(q = 0) = (1.27, 0, 1.57).
SCENARIO23_POSITION = (1.285, 0.0, 1.57)
SCENARIO23_ROTATION = ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (-1.0, 0.0, 0.0))

#: Joint disturbance d_q of scenarios 1 and 3, degrees.
DISTURBANCE_DEG = (0.1, 0.5, 0.2, 0.3, -0.1, 0.3)

#: Inner-loop time constant (bandwidth 100 rad/s), outer-loop natural frequency and damping.
TAU_IN = 0.01
OMEGA_N = 10.0
ZETA = 1.0 / math.sqrt(2.0)

#: Camera pose (the paper gives none; docs/design.md §5): eye and look-at point in {O}, z up.
CAMERA_EYE = (0.3, -1.6, 1.2)
CAMERA_LOOK_AT = (0.3, 0.2, 0.5)


#: Largest |R^T R - I| of a target rotation given with few digits (:func:`target_pose`).
TARGET_ROTATION_TOL = 1e-3


def target_pose(position: ArrayLike = TARGET_POSITION, rotation: ArrayLike = TARGET_ROTATION,
                tol: float = TARGET_ROTATION_TOL) -> NDArray[np.float64]:
    """
    Return the target T_E^O (4x4) of a flange position (3,) and rotation (9 row-major or 3x3).

    The one builder of the target pose, the IK target of eq. (43): by default the paper's
    (section 5.1); the control nodes, the simulator's taught target and the run analysis
    build theirs from the ``target_position`` / ``target_rotation`` parameters with it. A
    rotation given with few digits (within ``tol`` of orthonormal, det > 0) is projected
    onto the nearest rotation (:func:`nearest_rotation`); anything further, or a value that
    is not finite, raises :class:`InvalidInputError` (a ValueError).

    Parameters
    ----------
    position : array_like, shape (3,)
        The flange position in {O} (m).
    rotation : array_like, shape (9,) or (3, 3)
        The flange rotation, row-major.
    tol : float
        Largest |R^T R - I| projected onto a rotation.

    Returns
    -------
    ndarray, shape (4, 4)
        T_E^O.

    """
    position = np.asarray(position, dtype=float).reshape(3)
    rot = np.asarray(rotation, dtype=float).reshape(3, 3)
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(rot))):
        raise InvalidInputError('target pose: not finite')
    err = np.max(np.abs(rot.T @ rot - np.eye(3)))
    if err > tol or np.linalg.det(rot) <= 0.0:
        raise InvalidInputError(f'target rotation is not a rotation matrix (|R^T R - I| = '
                                f'{err:.3g}, det = {np.linalg.det(rot):.3g})')
    return pose_from(position, nearest_rotation(rot))


def scenario_start_pose(scenario: int) -> NDArray[np.float64]:
    """
    Return the start T_E^O of a scenario (the printed rotation orthonormalised).

    Parameters
    ----------
    scenario : int
        1, 2 or 3 (section 5).

    Returns
    -------
    ndarray, shape (4, 4)
        T_E^O at the start.

    """
    if scenario == 1:
        return pose_from(SCENARIO1_POSITION,
                         nearest_rotation(np.array(SCENARIO1_ROTATION_PRINTED)))
    if scenario in (2, 3):
        return pose_from(SCENARIO23_POSITION, SCENARIO23_ROTATION)
    raise ValueError(f'scenario must be 1, 2 or 3, got {scenario!r}')


def scenario_disturbance(scenario: int) -> NDArray[np.float64]:
    """
    Return d_q of a scenario: the paper's in scenarios 1 and 3, zero in scenario 2.

    Parameters
    ----------
    scenario : int
        1, 2 or 3 (section 5).

    Returns
    -------
    ndarray, shape (6,)
        d_q (rad).

    """
    if scenario not in (1, 2, 3):
        raise ValueError(f'scenario must be 1, 2 or 3, got {scenario!r}')
    return np.radians(DISTURBANCE_DEG) if scenario in (1, 3) else np.zeros(6)
