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

#: Samples after a reset that :meth:`StateSpaceFilter.held_outputs` computes by the
#: recurrence, bit for bit as :meth:`StateSpaceFilter.step` would: 10 s at 1 kHz, more than
#: T_forward needs to settle at a ``tau_in`` up to 0.2 s. Later samples (a slower inner
#: loop's long tail) run the same recurrence in compiled code, equal to within rounding.
RECURRENCE_SAMPLES = 10_000


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
        # tf2ss's controllable form: x = the last n values of w, w_(k+1) = A[0] x_k + B[0] u
        self._shift_form = (self.order > 0 and not self.B[1:].any()
                            and np.array_equal(self.A[1:], np.eye(self.order - 1, self.order)))
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

    def held_outputs(self, u: ArrayLike, samples: int) -> NDArray[np.float64]:
        """
        Return the next ``samples`` outputs, shape (samples, channels), for input held at u.

        The state advances ``samples`` steps, as that many :meth:`step` calls would leave it.
        Samples up to :data:`RECURRENCE_SAMPLES` after the last :meth:`reset` are the
        recurrence y_k = C x_k + D u, x_(k+1) = A x_k + B u itself, bit for bit as
        :meth:`step`. Later ones run the same recurrence in scipy's ``lfilter``: in the
        controllable form (``tf2ss``) the state is the last n values of one signal w,
        w_(k+1) = A[0] x_k + B[0] u, so w continues as the all-pole filter 1 / den(z) from its
        last n values (``lfiltic``), and y_k = C x_k + D u. (A closed form x_inf + A^j (x_k -
        x_inf) is not an option: with T_forward's poles near z = 1, x_inf is far larger than
        the output and solving for it loses the output to rounding.)
        """
        u = self._input(u)
        out = np.empty((int(samples), self.channels))
        a, c, bu, du = self.A, self.C, np.outer(self.B, u), self.D * u
        x = self.x
        exact = (min(len(out), max(RECURRENCE_SAMPLES - self.steps, 0)) if self._shift_form
                 else len(out))
        for k in range(exact):
            out[k] = c @ x + du
            x = a @ x + bu
        rest = len(out) - exact
        if rest:
            from scipy import signal  # here: its import costs what most filters never use
            den = np.concatenate(([1.0], -a[0]))
            w = np.empty((rest + self.order, self.channels))
            w[:self.order] = x[::-1]
            for ch in range(self.channels):
                held = np.full(rest, self.B[0] * u[ch])
                zi = signal.lfiltic([1.0], den, x[:, ch], held[:1])
                w[self.order:, ch] = signal.lfilter([1.0], den, held, zi=zi)[0]
            # x_(k+j) = w[j + order - 1], ..., w[j] (newest first), for j = 0 ... rest
            states = np.lib.stride_tricks.sliding_window_view(w, self.order, axis=0)
            out[exact:] = np.einsum('i,jci->jc', c, states[:rest, :, ::-1]) + du
            x = states[rest, :, ::-1].T.copy()
        self.x = x
        self.steps += len(out)
        if len(out):
            self.last_output = out[-1].copy()
        return out

    def copy(self) -> 'StateSpaceFilter':
        """Return an independent filter with the same coefficients and state."""
        other = StateSpaceFilter.__new__(StateSpaceFilter)
        other.__dict__.update(self.__dict__)
        other.x = self.x.copy()
        other.last_output = self.last_output.copy()
        return other
