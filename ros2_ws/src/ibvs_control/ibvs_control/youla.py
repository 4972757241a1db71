"""
The paper's Youla designs (section 4), continuous and sampled-data (no ROS).

Youla parameterisation of a stable SISO plant P: choose the closed loop T (stable, with
what P forces on it), then Y = T / P and the controller G = Y / (1 - T) (eq. 38-41 for
one channel). For the double integrator of the inner loop (eq. 27), T must also satisfy
T(0) = 1 and T'(0) = 0 so that G cancels no unstable pole of P.

Every design takes the inner-loop time constant as ``tau_in`` (the node parameter); the
formulas write it tau, as the paper does.

Continuous designs (the paper, with the errata of docs/design.md §5):

- inner loop, eq. (28) corrected: G_c = (3 tau s + 1) / (tau^3 s + 3 tau^2) around 1/s^2
  gives T = (3 tau s + 1) / (tau s + 1)^3, eq. (29). The printed (3 tau^2 s + 1) /
  (tau^3 s + 3 tau^2) makes the loop unstable (:func:`inner_controller_printed`).
- outer loop, eq. (33)-(41): M_p = gain_i T_in (eq. 35), M_T = Butterworth (eq. 36),
  M_Y = M_T / M_p (eq. 37). Because every channel has the same SISO factor, G_C = Y S^-1
  reduces to C1^+ k(s) with k(s) = wn^2 (tau s + 1)^3 / ((3 tau s + 1) s (s + 2 zeta wn))
  (:func:`outer_controller`, checked against eq. 37-41 by :func:`outer_channel_design`).
- feedforward, eq. (44)-(45): T_forward = (tau s + 1)^3 / ((3 tau s + 1) (0.1 tau s + 1)^2).

Sampled-data designs. The controllers run at a sample time (inner loop: the physics rate,
1 kHz; outer loop: the camera rate, 30 Hz) and drive a held (zero-order-hold) input.
Discretising the continuous controllers misses the continuous closed loops: Tustin of G_c
at 1 kHz gives a step response 3.6 % away from eq. (29); Tustin (ZOH) of k(s) at 30 Hz is
8 % (14 %) away from eq. (36) at the frames, with 11 % overshoot instead of 4.3 %. So the
same Youla procedure is applied to the sampled plant instead:

- :func:`inner_controller_discrete`: plant ZOH{1/s^2} = dt^2 (z + 1) / (2 (z - 1)^2);
  closed loop T_d = K (z + 1)(z - z0) / (z - p)^3 with the poles of eq. (29) mapped,
  p = exp(-dt / tau), the plant's zero at z = -1 kept (it cannot be cancelled), and K, z0
  from T_d(1) = 1, T_d'(1) = 0 (the discrete form of the conditions on eq. 29). The
  controller is a first-order lead, 2K/dt^2 (z - z0) / (z - c), close to the
  pole-zero-matched G_c. Step response within 1.4 % of eq. (29) at 1 kHz.
- :func:`outer_controller_discrete`: plant ZOH{T_in} at the camera period, closed loop
  ZOH{M_T} (step invariant: at the frames the step response is that of eq. 36), so
  k_d = M_T,d / (P_d (1 - M_T,d)). P_d has its zeros inside the unit circle, so k_d is stable.
- :func:`feedforward_discrete`: the inverse of T_d but for its zero at z = -1, times a
  double pole at exp(-dt / tau_forward): T_d T_forward,d = (z + 1)/2 ((1 - p_f)/(z - p_f))^2,
  eq. (44)-(45) in discrete time (no overshoot; Tustin of eq. 44 gives 1.2 %).
"""

import math

import numpy as np

from .transfer_function import TransferFunction

#: T_forward's double pole at ``feedforward_ratio`` tau_in (eq. 44-45): the paper's 0.1, so
#: that T_d T_forward, the joints' designed response, has a 1 ms double pole.
FEEDFORWARD_RATIO = 0.1


def check_bandwidth_rule(tau_in: float, omega_n: float) -> None:
    """
    Raise ValueError unless 1 / omega_n > tau_in (the paper's rule after eq. 36).

    The outer loop must be slower than the inner loop it commands.
    """
    if not (tau_in > 0.0 and omega_n > 0.0):
        raise ValueError(f'tau_in = {tau_in} and omega_n = {omega_n} must be > 0')
    if not 1.0 / omega_n > tau_in:
        raise ValueError(f'1 / omega_n = {1.0 / omega_n:.6g} s must exceed '
                         f'tau_in = {tau_in:.6g} s (paper, after eq. 36)')


def youla_controller(plant: TransferFunction, closed_loop: TransferFunction,
                     tol: float = 1e-6) -> TransferFunction:
    """
    Return G = Y / (1 - T) with Y = T / P: the controller that makes T the closed loop.

    Common roots are cancelled (``tol`` as :meth:`TransferFunction.minreal`).
    """
    youla = closed_loop / plant
    return (youla / (1.0 - closed_loop)).minreal(tol)


# -- continuous designs ---------------------------------------------------------------------

def double_integrator() -> TransferFunction:
    """Return 1 / s^2: the joint dynamics after feedback linearisation, eq. (27)."""
    return TransferFunction([1.0], [1.0, 0.0, 0.0])


def inner_closed_loop(tau_in: float) -> TransferFunction:
    """Return T_inner = (3 tau s + 1) / (tau s + 1)^3, eq. (29)."""
    return TransferFunction([3.0 * tau_in, 1.0], np.poly([-1.0 / tau_in] * 3) * tau_in ** 3)


def inner_controller(tau_in: float) -> TransferFunction:
    """Return G_c = (3 tau s + 1) / (tau^3 s + 3 tau^2): eq. (28) fixed (docs/design.md §5)."""
    return TransferFunction([3.0 * tau_in, 1.0], [tau_in ** 3, 3.0 * tau_in ** 2])


def inner_controller_printed(tau_in: float) -> TransferFunction:
    """Return eq. (28) as printed, (3 tau^2 s + 1) / (tau^3 s + 3 tau^2): unstable loop."""
    return TransferFunction([3.0 * tau_in ** 2, 1.0], [tau_in ** 3, 3.0 * tau_in ** 2])


def butterworth(omega_n: float, zeta: float) -> TransferFunction:
    """Return M_T = wn^2 / (s^2 + 2 zeta wn s + wn^2), eq. (36)."""
    return TransferFunction([omega_n ** 2], [1.0, 2.0 * zeta * omega_n, omega_n ** 2])


def outer_plant_channel(tau_in: float, gain: float = 1.0) -> TransferFunction:
    """Return M_p(i, i) = gain(i) (3 tau s + 1) / (tau s + 1)^3, eq. (35)."""
    return gain * inner_closed_loop(tau_in)


def outer_youla_channel(tau_in: float, omega_n: float, zeta: float,
                        gain: float = 1.0) -> TransferFunction:
    """Return M_Y(i, i) = M_T / M_p(i, i), eq. (37)."""
    return butterworth(omega_n, zeta) / outer_plant_channel(tau_in, gain)


def outer_channel_design(tau_in: float, omega_n: float, zeta: float, gain: float = 1.0
                         ) -> tuple[TransferFunction, TransferFunction, TransferFunction,
                                    TransferFunction]:
    """
    Return (M_Y, T_y, S_y, G_C) of one decoupled channel by eq. (37), (39), (40), (41).

    G_C = M_Y / (1 - M_p M_Y), with common roots cancelled: it equals k(s) / gain
    (:func:`outer_controller`).
    """
    m_y = outer_youla_channel(tau_in, omega_n, zeta, gain)
    t_y = (outer_plant_channel(tau_in, gain) * m_y).minreal(1e-4)
    s_y = 1.0 - t_y
    g_c = (m_y / s_y).minreal(1e-4)
    return m_y, t_y, s_y, g_c


def outer_controller(tau_in: float, omega_n: float, zeta: float) -> TransferFunction:
    """
    Return k(s) = wn^2 (tau s + 1)^3 / ((3 tau s + 1) s (s + 2 zeta wn)) (docs/design.md §5).

    G_C = C1^+ k(s) (eq. 38-41 with C1 = U_L diag(gain) U_R): an integrator (zero
    steady-state image error) and the inverse of the inner loop eq. (29).
    """
    num = omega_n ** 2 * np.poly([-1.0 / tau_in] * 3) * tau_in ** 3
    den = np.polymul([3.0 * tau_in, 1.0], [1.0, 2.0 * zeta * omega_n, 0.0])
    return TransferFunction(num, den)


def feedforward(tau_in: float, feedforward_ratio: float = FEEDFORWARD_RATIO
                ) -> TransferFunction:
    """
    Return T_forward = (tau s + 1)^3 / ((3 tau s + 1)(tau_f s + 1)^2), eq. (44).

    tau_f = feedforward_ratio * tau, eq. (45) (the paper: 0.1). Biproper with high-frequency
    gain tau^3 / (3 tau tau_f^2) ~ 33: a step asks ~33 times the step at first
    (docs/design.md §5).
    """
    tau_f = feedforward_ratio * tau_in
    num = np.poly([-1.0 / tau_in] * 3) * tau_in ** 3
    den = np.polymul([3.0 * tau_in, 1.0], np.poly([-1.0 / tau_f] * 2) * tau_f ** 2)
    return TransferFunction(num, den)


# -- sampled-data designs ------------------------------------------------------------------

def double_integrator_discrete(dt: float) -> TransferFunction:
    """Return ZOH{1/s^2} = dt^2 (z + 1) / (2 (z - 1)^2): the sampled eq. (27)."""
    return TransferFunction([dt * dt / 2.0, dt * dt / 2.0], [1.0, -2.0, 1.0], dt)


def _inner_discrete_coefficients(tau_in, dt):
    """Return (p, z0, K, c) of the sampled inner design (module docstring)."""
    if not (tau_in > 0.0 and dt > 0.0):
        raise ValueError(f'tau_in = {tau_in} and dt = {dt} must be > 0')
    p = math.exp(-dt / tau_in)
    # d/dz ln T_d at z = 1: 1/2 + 1/(1 - z0) - 3/(1 - p) = 0.
    z0 = 1.0 - 1.0 / (3.0 / (1.0 - p) - 0.5)
    gain = (1.0 - p) ** 3 / (2.0 * (1.0 - z0))
    # (z - p)^3 - K (z + 1)(z - z0) = (z - 1)^2 (z - c).
    rest = np.polysub(np.poly([p] * 3), gain * np.polymul([1.0, 1.0], [1.0, -z0]))
    quotient, remainder = np.polydiv(rest, [1.0, -2.0, 1.0])
    if np.max(np.abs(remainder)) > 1e-9:
        raise ArithmeticError('sampled inner design: (z - 1)^2 does not divide 1 - T_d')
    return p, z0, gain, -quotient[1]


def inner_closed_loop_discrete(tau_in: float, dt: float) -> TransferFunction:
    """Return T_d = K (z + 1)(z - z0) / (z - p)^3, the sampled eq. (29)."""
    p, z0, gain, _ = _inner_discrete_coefficients(tau_in, dt)
    return TransferFunction(gain * np.polymul([1.0, 1.0], [1.0, -z0]), np.poly([p] * 3), dt)


def inner_controller_discrete(tau_in: float, dt: float) -> TransferFunction:
    """
    Return the sampled eq. (28): G_c,d = (2 K / dt^2) (z - z0) / (z - c).

    The Youla controller T_d / (P_d (1 - T_d)) of the ZOH double integrator P_d for the
    closed loop :func:`inner_closed_loop_discrete`, written in closed form.
    """
    _, z0, gain, c = _inner_discrete_coefficients(tau_in, dt)
    return TransferFunction(2.0 * gain / dt ** 2 * np.array([1.0, -z0]), [1.0, -c], dt)


def outer_controller_discrete(tau_in: float, omega_n: float, zeta: float,
                              dt: float) -> TransferFunction:
    """
    Return k_d(z) = M_T,d / (P_d (1 - M_T,d)): eq. (37)-(41) on the sampled plant.

    P_d = ZOH{eq. 29}, M_T,d = ZOH{eq. 36} at the camera period ``dt``, so the sampled
    closed loop of each observable channel has the step response of eq. (36) at the
    frames. Raises ValueError when P_d has a zero outside the unit circle (k_d unstable).
    """
    plant = inner_closed_loop(tau_in).discretise(dt, 'zoh')
    target = butterworth(omega_n, zeta).discretise(dt, 'zoh')
    zeros = plant.zeros()
    if zeros.size and np.max(np.abs(zeros)) >= 1.0:
        raise ValueError(f'sampled outer plant has a zero outside the unit circle '
                         f'({zeros}): tau_in = {tau_in} s, dt = {dt} s')
    num = np.polymul(target.num, plant.den)
    den = np.polymul(plant.num, np.polysub(target.den, target.num))
    return TransferFunction(num, den, dt)


def feedforward_discrete(tau_in: float, dt: float, feedforward_ratio: float = FEEDFORWARD_RATIO
                         ) -> TransferFunction:
    """
    Return T_forward,d = (z + 1) / (2 T_d(z)) ((1 - p_f) / (z - p_f))^2, eq. (44)-(45).

    p_f = exp(-dt / (feedforward_ratio tau)). Unit DC gain; T_d T_forward,d has no overshoot.
    """
    p, z0, gain, _ = _inner_discrete_coefficients(tau_in, dt)
    p_f = math.exp(-dt / (feedforward_ratio * tau_in))
    num = np.poly([p] * 3) * (1.0 - p_f) ** 2 / (2.0 * gain)
    den = np.polymul([1.0, -z0], np.poly([p_f] * 2))
    return TransferFunction(num, den, dt)
