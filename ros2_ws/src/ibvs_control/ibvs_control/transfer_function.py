"""
Rational transfer functions as numerator/denominator polynomials (no ROS).

A small algebra (product, sum, quotient, feedback, cancellation of common roots) that is
enough to write the paper's Youla designs, eq. (28)-(29), (33)-(41) and (44)-(45), the way
the paper writes them, and to check them (poles, DC gain, step response). Polynomials
are numpy arrays with the highest power first, as in scipy.signal. ``dt = None`` is a
continuous-time (Laplace, s) transfer function; ``dt > 0`` a discrete-time (z) one.

scipy.signal is imported by the conversions that use it, not with this module: it costs
about a second of CPU, and the runner reads the control nodes' parameters (which import
this module) before every run without designing anything.
"""

import numpy as np
from numpy.typing import ArrayLike, NDArray


def _trim(poly):
    """Return ``poly`` as a float array without leading zeros (at least one coefficient)."""
    poly = np.atleast_1d(np.asarray(poly, dtype=float))
    if poly.ndim != 1 or not np.all(np.isfinite(poly)):
        raise ValueError(f'a polynomial must be a finite 1-D sequence, got {poly!r}')
    nonzero = np.flatnonzero(poly)
    return poly[nonzero[0]:] if nonzero.size else np.zeros(1)


class TransferFunction:
    """
    A SISO transfer function num(x) / den(x), x = s (``dt`` None) or z (``dt`` > 0).

    The denominator is normalised to a monic polynomial. Operations between a transfer
    function and a number or another transfer function of the same kind (same ``dt``)
    return new objects; nothing is modified in place.
    """

    def __init__(self, num: ArrayLike, den: ArrayLike, dt: float | None = None) -> None:
        """Store num/den (highest power first), normalised so that den is monic."""
        num, den = _trim(num), _trim(den)
        if not np.any(den):
            raise ValueError('the denominator of a transfer function cannot be 0')
        if dt is not None and not dt > 0.0:
            raise ValueError(f'dt must be None (continuous) or > 0, got {dt!r}')
        self.num = num / den[0]
        self.den = den / den[0]
        self.dt = dt

    # -- construction -----------------------------------------------------------------
    @classmethod
    def s(cls) -> 'TransferFunction':
        """Return the Laplace variable s as a transfer function."""
        return cls([1.0, 0.0], [1.0])

    @classmethod
    def from_roots(cls, zeros: ArrayLike, poles: ArrayLike, gain: float = 1.0,
                   dt: float | None = None) -> 'TransferFunction':
        """Return gain * prod(x - zeros) / prod(x - poles)."""
        return cls(gain * np.real_if_close(np.poly(zeros)), np.real_if_close(np.poly(poles)),
                   dt)

    def _coerce(self, other):
        if isinstance(other, TransferFunction):
            if other.dt != self.dt:
                raise ValueError(f'cannot combine dt = {self.dt} with dt = {other.dt}')
            return other
        return TransferFunction([float(other)], [1.0], self.dt)

    # -- algebra ------------------------------------------------------------------------
    def __mul__(self, other):
        """Return the series connection self * other."""
        other = self._coerce(other)
        return TransferFunction(np.polymul(self.num, other.num),
                                np.polymul(self.den, other.den), self.dt)

    __rmul__ = __mul__

    def __truediv__(self, other):
        """Return self / other (other must not be identically zero)."""
        other = self._coerce(other)
        if not np.any(other.num):
            raise ZeroDivisionError('division by a zero transfer function')
        return TransferFunction(np.polymul(self.num, other.den),
                                np.polymul(self.den, other.num), self.dt)

    def __rtruediv__(self, other):
        """Return other / self."""
        return self._coerce(other) / self

    def __add__(self, other):
        """Return the parallel connection self + other."""
        other = self._coerce(other)
        return TransferFunction(np.polyadd(np.polymul(self.num, other.den),
                                           np.polymul(other.num, self.den)),
                                np.polymul(self.den, other.den), self.dt)

    __radd__ = __add__

    def __neg__(self):
        """Return -self."""
        return TransferFunction(-self.num, self.den, self.dt)

    def __sub__(self, other):
        """Return self - other."""
        return self + (-self._coerce(other))

    def __rsub__(self, other):
        """Return other - self."""
        return self._coerce(other) - self

    def feedback(self, other: 'TransferFunction | float' = 1.0) -> 'TransferFunction':
        """Return the negative-feedback loop self / (1 + self * other)."""
        other = self._coerce(other)
        return TransferFunction(np.polymul(self.num, other.den),
                                np.polyadd(np.polymul(self.den, other.den),
                                           np.polymul(self.num, other.num)), self.dt)

    def minreal(self, tol: float = 1e-6) -> 'TransferFunction':
        """
        Return the transfer function with common roots of num and den cancelled.

        Two roots cancel when they are closer than ``tol`` relative to their size (at
        least 1). Multiple roots (the triple pole of eq. 29) are found less precisely by
        numpy.roots, about tol**(1/3), so pass a larger ``tol`` for them if needed.
        """
        zeros = list(np.roots(self.num)) if self.num.size > 1 else []
        poles = list(np.roots(self.den)) if self.den.size > 1 else []
        kept_zeros = []
        for z in zeros:
            dist = [abs(z - p) / max(1.0, abs(p)) for p in poles]
            if dist and min(dist) < tol:
                poles.pop(int(np.argmin(dist)))
            else:
                kept_zeros.append(z)
        gain = self.num[0] if np.any(self.num) else 0.0
        return TransferFunction.from_roots(kept_zeros, poles, gain, self.dt)

    # -- properties ---------------------------------------------------------------------
    def poles(self) -> NDArray[np.complex128]:
        """Return the roots of the denominator."""
        return np.roots(self.den) if self.den.size > 1 else np.zeros(0)

    def zeros(self) -> NDArray[np.complex128]:
        """Return the roots of the numerator."""
        return np.roots(self.num) if self.num.size > 1 else np.zeros(0)

    def __call__(self, x):
        """Evaluate at a complex frequency s (or z)."""
        return np.polyval(self.num, x) / np.polyval(self.den, x)

    def dc_gain(self) -> float:
        """Return the gain at s = 0 (continuous) or z = 1 (discrete); inf for a pole there."""
        x = 0.0 if self.dt is None else 1.0
        den = np.polyval(self.den, x)
        num = np.polyval(self.num, x)
        if abs(den) < 1e-14 * max(1.0, np.max(np.abs(self.den))):
            return np.inf if abs(num) > 0.0 else np.nan
        return float(num / den)

    def is_proper(self) -> bool:
        """Return True when deg(num) <= deg(den) (realisable)."""
        return self.num.size <= self.den.size

    def is_stable(self, margin: float = 0.0) -> bool:
        """Return True when every pole has Re < -margin (continuous) or |z| < 1 - margin."""
        poles = self.poles()
        if poles.size == 0:
            return True
        if self.dt is None:
            return bool(np.all(poles.real < -margin))
        return bool(np.all(np.abs(poles) < 1.0 - margin))

    def same_as(self, other: 'TransferFunction | float', rtol: float = 1e-6) -> bool:
        """Return True when both have the same coefficients once padded (monic den)."""
        other = self._coerce(other)

        def padded(a, n):
            return np.concatenate([np.zeros(n - a.size), a])
        n = max(self.num.size, self.den.size, other.num.size, other.den.size)
        a = np.concatenate([padded(self.num, n), padded(self.den, n)])
        b = np.concatenate([padded(other.num, n), padded(other.den, n)])
        return bool(np.allclose(a, b, rtol=rtol, atol=rtol * np.max(np.abs(a))))

    # -- conversion ---------------------------------------------------------------------
    def to_ss(self) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                             NDArray[np.float64]]:
        """Return (A, B, C, D) of a state-space realisation (scipy.signal.tf2ss)."""
        if not self.is_proper():
            raise ValueError('an improper transfer function has no state-space realisation')
        from scipy import signal  # here: module docstring
        a, b, c, d = signal.tf2ss(self.num, self.den)
        return a, b, c, d

    def discretise(self, dt: float, method: str = 'bilinear') -> 'TransferFunction':
        """
        Return the discrete-time equivalent at sample time ``dt`` (scipy cont2discrete).

        ``method``: 'zoh' (step invariant: exact for a piecewise constant input),
        'bilinear' (Tustin), or any other method of scipy.signal.cont2discrete.
        """
        if self.dt is not None:
            raise ValueError('already discrete')
        from scipy import signal  # here: module docstring
        num, den, _ = signal.cont2discrete((self.num, self.den), dt, method=method)
        return TransferFunction(np.ravel(num), den, dt)

    def step(self, t: ArrayLike) -> NDArray[np.float64]:
        """
        Return the unit step response at the times ``t`` (s).

        Continuous: scipy.signal.step (exact for the linear system). Discrete: the output
        at the samples t = k dt, held in between (``t`` is rounded down to samples).
        """
        from scipy import signal  # here: module docstring
        t = np.asarray(t, dtype=float)
        if self.dt is None:
            _, y = signal.step((self.num, self.den), T=t)
            return y
        n = int(np.floor(t.max() / self.dt + 1e-9)) + 1
        _, y = signal.dlsim((self.num, self.den, self.dt), np.ones(n))
        idx = np.floor(t / self.dt + 1e-9).astype(int)
        return np.ravel(y)[idx]

    def __repr__(self):
        """Show num, den and the kind."""
        kind = 's' if self.dt is None else f'z, dt={self.dt:g}'
        return f'TransferFunction({self.num.tolist()}, {self.den.tolist()}, {kind})'
