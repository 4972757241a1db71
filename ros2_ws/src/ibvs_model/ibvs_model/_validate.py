"""Input checks shared by the model functions (shapes, finiteness, rotations)."""

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InvalidInputError


def as_array(value: ArrayLike, shape: tuple, name: str) -> NDArray[np.float64]:
    """
    Return ``value`` as a float array of ``shape``; raise if it is not or is not finite.

    Parameters
    ----------
    value : array_like
        The input.
    shape : tuple of (int or None)
        The shape wanted; ``None`` for a free dimension (for example ``(None, 3)``).
    name : str
        The input's name in the error message.

    Returns
    -------
    ndarray
        ``value`` as floats.

    Raises
    ------
    InvalidInputError
        When ``value`` is not numeric, has another shape, or holds NaN or inf.

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


def as_rotation(value: ArrayLike, name: str, tol: float = 1e-6) -> NDArray[np.float64]:
    """
    Return ``value`` as a 3x3 rotation matrix; raise if it is not orthonormal with det +1.

    Parameters
    ----------
    value : array_like, shape (3, 3)
        The input.
    name : str
        The input's name in the error message.
    tol : float
        Largest |R^T R - I| accepted.

    Returns
    -------
    ndarray, shape (3, 3)
        The rotation.

    """
    rot = as_array(value, (3, 3), name)
    err = np.max(np.abs(rot.T @ rot - np.eye(3)))
    if err > tol or np.linalg.det(rot) < 0.0:
        raise InvalidInputError(
            f'{name}: not a rotation matrix (|R^T R - I| = {err:.2e} > {tol:.0e} or det < 0);'
            ' orthonormalise it first, e.g. with ibvs_model.nearest_rotation')
    return rot


def as_transform(value: ArrayLike, name: str, tol: float = 1e-6) -> NDArray[np.float64]:
    """
    Return ``value`` as a 4x4 homogeneous transform with a valid rotation block.

    Parameters
    ----------
    value : array_like, shape (4, 4)
        The input.
    name : str
        The input's name in the error message.
    tol : float
        Largest deviation of the rotation block and of the last row accepted.

    Returns
    -------
    ndarray, shape (4, 4)
        The transform.

    """
    tf = as_array(value, (4, 4), name)
    as_rotation(tf[:3, :3], f'{name}[:3, :3]', tol)
    if np.max(np.abs(tf[3] - (0.0, 0.0, 0.0, 1.0))) > tol:
        raise InvalidInputError(f'{name}: last row must be [0, 0, 0, 1], got {tf[3]}')
    return tf


def nearest_rotation(matrix: ArrayLike) -> NDArray[np.float64]:
    """
    Return the rotation matrix nearest ``matrix`` in the Frobenius norm (SVD projection).

    Used for rotations printed with few digits (the paper gives four), which are not
    exactly orthonormal.

    Parameters
    ----------
    matrix : array_like, shape (3, 3)
        A nearly orthonormal matrix.

    Returns
    -------
    ndarray, shape (3, 3)
        The rotation (det +1) nearest it.

    """
    mat = as_array(matrix, (3, 3), 'matrix')
    u, _, vt = np.linalg.svd(mat)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt
