"""
Decoupling of the linearised camera-and-robot model C1 by SVD, eq. (33)-(38) (no ROS).

C1 = U_L diag(gain) U_R (eq. 34 with the constant matrix C1: U_L = U, gain = the singular
values, U_R = V^T). The controller of eq. (38)-(41) is G_C = U_R^T diag(M_Y/S) U_L^T
(the paper writes U_R M_Y U_L, transposes implied), i.e. C1^+ k(s).

Unobservable direction (docs/design.md §5): both fiducials lie on the joint-6 axis, so
joint 6 moves no feature, the sixth singular value of C1 is 0 (numerically ~1e-13 of the
first) and eq. (37) would divide by it. Only the singular values above ``svd_rcond`` times
the largest are inverted (truncated SVD: rank 5), so the feedback never moves the
unobservable direction (V's sixth column, e6): q6 is left to the feedforward and the
encoder, which is harmless for an axisymmetric screwdriver. An optional Tikhonov
``svd_damping`` lambda replaces 1/sigma by sigma/(sigma^2 + lambda^2) on the kept values
(damped least squares), which bounds the gain near a wrist singularity at the price of a
slower channel there; the default 0 is the paper's exact inverse.
"""

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Default of ``svd_rcond`` (the adaptive feedback node's parameter of the same name).
SVD_RCOND = 1e-6


@dataclass(frozen=True)
class Decoupling:
    """
    SVD of C1 = U diag(s) Vt, the rank used and the (truncated/damped) inverse.

    ``gain_inv``: the inverted gain of each decoupled channel (0 beyond the rank), so that
    ``pinv = Vt^T diag(gain_inv) U^T``.
    """

    U: np.ndarray
    s: np.ndarray
    Vt: np.ndarray
    rank: int
    pinv: np.ndarray
    gain_inv: np.ndarray

    @property
    def condition(self) -> float:
        """Return sigma_1 / sigma_rank, the condition number of the inverted part."""
        return float(self.s[0] / self.s[self.rank - 1]) if self.rank else float('inf')

    def channels(self, error: ArrayLike) -> NDArray[np.float64]:
        """Return the joint corrections of the decoupled channels, diag(gain_inv) U^T e."""
        n = self.s.size
        return self.gain_inv * (self.U[:, :n].T @ np.asarray(error, dtype=float))

    def joints(self, channels: ArrayLike) -> NDArray[np.float64]:
        """Return the joint-space vector V c of channel values ``channels`` (rad)."""
        return self.Vt[:self.s.size].T @ np.asarray(channels, dtype=float)

    @property
    def observable(self) -> NDArray[np.float64]:
        """Return the columns of U spanning the observable image directions (6, rank)."""
        return self.U[:, :self.rank]


def decouple(c1: ArrayLike, svd_rcond: float = SVD_RCOND, svd_damping: float = 0.0
             ) -> Decoupling:
    """
    Return the :class:`Decoupling` of C1 (eq. 34) with the inverse used by eq. (37)-(41).

    Singular values <= ``svd_rcond`` * sigma_1 are treated as zero (not inverted);
    ``svd_damping`` is the Tikhonov lambda (module docstring).
    """
    c1 = np.asarray(c1, dtype=float)
    if c1.ndim != 2 or not np.all(np.isfinite(c1)):
        raise ValueError('C1 must be a finite matrix')
    if not (0.0 < svd_rcond < 1.0) or svd_damping < 0.0:
        raise ValueError(f'svd_rcond = {svd_rcond} must be in (0, 1) and svd_damping = '
                         f'{svd_damping} >= 0')
    u, s, vt = np.linalg.svd(c1)
    rank = int(np.count_nonzero(s > svd_rcond * s[0])) if s[0] > 0.0 else 0
    inv = np.zeros_like(s)
    inv[:rank] = s[:rank] / (s[:rank] ** 2 + svd_damping ** 2)
    pinv = (vt[:s.size].T * inv) @ u[:, :s.size].T
    return Decoupling(u, s, vt, rank, pinv, inv)
