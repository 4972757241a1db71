"""Input checks shared by the model functions (shapes, finiteness, rotations)."""

import numpy as np

from .errors import InvalidInputError


def as_array(value, shape, name):
    """
    Return ``value`` as a float array of ``shape``; raise if it is not or is not finite.

    ``shape`` may contain ``None`` for a free dimension (for example ``(None, 3)``).
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f'{name}: not a numeric array ({exc})') from None
    if arr.ndim != len(shape) or any(
            want is not None and got != want for got, want in zip(arr.shape, shape)):
        want = '(' + ', '.join('N' if s is None else str(s) for s in shape) + ')'
        raise InvalidInputError(f'{name}: expected shape {want}, got {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise InvalidInputError(f'{name}: contains NaN or inf')
    return arr


def as_rotation(value, name, tol=1e-6):
    """Return ``value`` as a 3x3 rotation matrix; raise if it is not orthonormal with det +1."""
    rot = as_array(value, (3, 3), name)
    err = np.max(np.abs(rot.T @ rot - np.eye(3)))
    if err > tol or np.linalg.det(rot) < 0.0:
        raise InvalidInputError(
            f'{name}: not a rotation matrix (|R^T R - I| = {err:.2e} > {tol:.0e} or det < 0);'
            ' orthonormalise it first, e.g. with ibvs_model.nearest_rotation')
    return rot


def as_transform(value, name, tol=1e-6):
    """Return ``value`` as a 4x4 homogeneous transform with a valid rotation block."""
    tf = as_array(value, (4, 4), name)
    as_rotation(tf[:3, :3], f'{name}[:3, :3]', tol)
    if np.max(np.abs(tf[3] - (0.0, 0.0, 0.0, 1.0))) > tol:
        raise InvalidInputError(f'{name}: last row must be [0, 0, 0, 1], got {tf[3]}')
    return tf


def nearest_rotation(matrix):
    """
    Return the rotation matrix nearest ``matrix`` in the Frobenius norm (SVD projection).

    Used for rotations printed with few digits (the paper gives four), which are not
    exactly orthonormal.
    """
    mat = as_array(matrix, (3, 3), 'matrix')
    u, _, vt = np.linalg.svd(mat)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt
