"""
Discrete state-space filters that run one sample at a time on vector channels (no ROS).

One SISO discrete transfer function (A, B, C, D) applied independently to each of
``channels`` signals (the six joints): the state is an (n, channels) array, so one call
updates all channels with two small matrix products.

Anti-windup (used by the joint loop in 'limited' actuator mode) follows the conditioning
technique of Hanus et al. (1987): when the output actually applied differs from the one
computed, the state is updated with the input that would have produced the applied output,
u_r = u + (y_applied - y) / D, so the controller state stays consistent with the plant
input and does not wind up. This needs a biproper filter (D != 0).
"""

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .transfer_function import TransferFunction


class StateSpaceFilter:
    """A discrete SISO filter run on ``channels`` signals, one sample per :meth:`step`."""

    def __init__(self, tf: TransferFunction, channels: int = 6) -> None:
        """Realise the discrete :class:`TransferFunction` ``tf`` (controllable form)."""
        if not isinstance(tf, TransferFunction) or tf.dt is None:
            raise ValueError('StateSpaceFilter needs a discrete TransferFunction')
        a, b, c, d = tf.to_ss()
        self.tf = tf
        self.dt = tf.dt
        self.channels = int(channels)
        self.A = np.asarray(a, dtype=float)
        self.B = np.asarray(b, dtype=float).reshape(-1)
        self.C = np.asarray(c, dtype=float).reshape(-1)
        self.D = float(np.asarray(d).reshape(-1)[0]) if np.size(d) else 0.0
        self.order = self.A.shape[0]
        self.x = np.zeros((self.order, self.channels))
        self.last_output = np.zeros(self.channels)
        self.steps = 0

    def _input(self, u):
        u = np.asarray(u, dtype=float)
        if u.shape == ():
            u = np.full(self.channels, float(u))
        if u.shape != (self.channels,):
            raise ValueError(f'expected {self.channels} inputs, got shape {u.shape}')
        return u

    def output(self, u: ArrayLike) -> NDArray[np.float64]:
        """Return y = C x + D u for the input ``u`` now, without changing the state."""
        u = self._input(u)
        return self.C @ self.x + self.D * u

    def update(self, u: ArrayLike) -> None:
        """Advance the state one sample with input ``u``: x <- A x + B u."""
        u = self._input(u)
        self.x = self.A @ self.x + np.outer(self.B, u)
        self.steps += 1

    def step(self, u: ArrayLike, applied: ArrayLike | None = None) -> NDArray[np.float64]:
        """
        Return the output for input ``u`` and advance the state one sample.

        ``applied``: the output actually used downstream (e.g. after saturation); when
        given, the state is updated with the conditioned input (Hanus anti-windup).
        """
        u = self._input(u)
        y = self.C @ self.x + self.D * u
        if applied is not None:
            applied = self._input(applied)
            if self.D == 0.0:
                raise ValueError('conditioning (anti-windup) needs a biproper filter, D != 0')
            u = u + (applied - y) / self.D
            y = applied
        self.x = self.A @ self.x + np.outer(self.B, u)
        self.steps += 1
        self.last_output = y
        return y

    def reset(self, rest_input: ArrayLike | None = None) -> None:
        """
        Reset the state: zero, or at rest for a constant input ``rest_input``.

        At rest means x = A x + B u, so the output stays at DC gain * u for as long as the
        input stays u. A filter with a pole at z = 1 (an integrator) has no rest state for
        u != 0 and raises ValueError.
        """
        self.steps = 0
        if rest_input is None:
            self.x = np.zeros((self.order, self.channels))
            self.last_output = np.zeros(self.channels)
            return
        u = self._input(rest_input)
        lhs = np.eye(self.order) - self.A
        if abs(np.linalg.det(lhs)) < 1e-12:
            raise ValueError('a filter with an integrator has no rest state for u != 0')
        self.x = np.linalg.solve(lhs, np.outer(self.B, u))
        self.last_output = self.output(u)

    def copy(self) -> 'StateSpaceFilter':
        """Return an independent filter with the same coefficients and state."""
        other = StateSpaceFilter.__new__(StateSpaceFilter)
        other.__dict__.update(self.__dict__)
        other.x = self.x.copy()
        other.last_output = self.last_output.copy()
        return other
