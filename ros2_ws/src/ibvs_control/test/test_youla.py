"""Youla designs of section 4 and their sampled versions: poles, algebra, step responses."""

from ibvs_control import youla
from ibvs_control.filters import StateSpaceFilter
from ibvs_control.transfer_function import TransferFunction
import numpy as np
import pytest

TAU = 0.01
WN = 10.0
ZETA = 1.0 / np.sqrt(2.0)
DT = 1e-3
CAMERA_DT = 1.0 / 30.0


def simulate_inner(controller, ref, steps, dt=DT):
    """Close a discrete controller around the exact ZOH double integrator (per channel)."""
    filt = StateSpaceFilter(controller, np.size(ref[0]))
    q = np.zeros(np.size(ref[0]))
    qd = np.zeros_like(q)
    out = np.empty((steps, q.size))
    for k in range(steps):
        out[k] = q
        v = filt.step(ref[min(k, len(ref) - 1)] - q)
        q = q + qd * dt + 0.5 * v * dt * dt
        qd = qd + v * dt
    return out


# -- inner loop, eq. (27)-(29) ---------------------------------------------------------------

def test_corrected_eq28_closes_the_double_integrator_into_eq29():
    loop = (youla.inner_controller(TAU) * youla.double_integrator()).feedback()
    assert loop.same_as(youla.inner_closed_loop(TAU))
    np.testing.assert_allclose(loop.poles(), [-1.0 / TAU] * 3, rtol=1e-4)
    assert loop.dc_gain() == pytest.approx(1.0)


def test_eq28_is_the_youla_controller_of_eq29():
    derived = youla.youla_controller(youla.double_integrator(), youla.inner_closed_loop(TAU),
                                     tol=1e-4)
    assert derived.same_as(youla.inner_controller(TAU))


def test_printed_eq28_makes_the_inner_loop_unstable():
    loop = (youla.inner_controller_printed(TAU) * youla.double_integrator()).feedback()
    poles = loop.poles()
    assert not loop.is_stable()
    unstable = poles[poles.real > 0.0]
    # docs/design.md §5: +4.7 +- 56.7j for tau = 0.01.
    np.testing.assert_allclose(sorted(unstable.imag), [-56.65, 56.65], atol=0.05)
    np.testing.assert_allclose(unstable.real, [4.736, 4.736], atol=0.01)
    # and in a sampled run the error grows without bound
    printed = youla.inner_controller_printed(TAU).discretise(DT, 'bilinear')
    q = simulate_inner(printed, [np.ones(1)], 2000)
    assert np.max(np.abs(q[-200:])) > 1e3


@pytest.mark.parametrize('dt', [1e-4, 5e-4, 1e-3, 2e-3])
def test_sampled_inner_design_has_the_mapped_poles_and_type_two(dt):
    plant = youla.double_integrator_discrete(dt)
    assert plant.same_as(youla.double_integrator().discretise(dt, 'zoh'))
    loop = (youla.inner_controller_discrete(TAU, dt) * plant).feedback().minreal(1e-5)
    assert loop.same_as(youla.inner_closed_loop_discrete(TAU, dt), rtol=1e-6)
    np.testing.assert_allclose(loop.poles(), [np.exp(-dt / TAU)] * 3, atol=1e-4)
    assert loop.dc_gain() == pytest.approx(1.0, abs=1e-9)
    # type two: a ramp is followed without steady-state error
    ramp = [np.array([k * dt]) for k in range(3000)]
    q = simulate_inner(youla.inner_controller_discrete(TAU, dt), ramp, 3000, dt)
    assert abs(q[-1, 0] - ramp[-1][0]) < 1e-6


def test_sampled_inner_loop_reproduces_eq29_within_2_percent_at_1khz():
    steps = 300
    q = simulate_inner(youla.inner_controller_discrete(TAU, DT), [np.ones(1)], steps)[:, 0]
    t = np.arange(steps) * DT
    reference = youla.inner_closed_loop(TAU).step(t)
    error = np.max(np.abs(q - reference))
    assert error < 0.02, f'{error:.4f} of the step'
    # Tustin of the continuous eq. (28) misses by more: why the sampled design exists
    tustin = simulate_inner(youla.inner_controller(TAU).discretise(DT, 'bilinear'),
                            [np.ones(1)], steps)[:, 0]
    assert np.max(np.abs(tustin - reference)) > error


def test_sampled_controller_is_close_to_pole_zero_matched_eq28():
    gc = youla.inner_controller_discrete(TAU, DT)
    np.testing.assert_allclose(gc.zeros(), [np.exp(-DT / (3 * TAU))], rtol=1e-3)
    np.testing.assert_allclose(gc.poles(), [np.exp(-3 * DT / TAU)], rtol=0.02)


# -- outer loop, eq. (35)-(41) ---------------------------------------------------------------

@pytest.mark.parametrize('gain', [1.0, 2.17, 932.5])
def test_eq37_to_eq41_give_eq36_and_reduce_to_k_over_gain(gain):
    m_y, t_y, s_y, g_c = youla.outer_channel_design(TAU, WN, ZETA, gain)
    assert m_y.is_stable() and m_y.is_proper()
    assert t_y.same_as(youla.butterworth(WN, ZETA))
    assert g_c.same_as(youla.outer_controller(TAU, WN, ZETA) / gain, rtol=1e-5)
    loop = (g_c * youla.outer_plant_channel(TAU, gain)).feedback().minreal(1e-3)
    assert loop.same_as(youla.butterworth(WN, ZETA), rtol=1e-5)
    assert youla.outer_controller(TAU, WN, ZETA).dc_gain() == np.inf  # integral action


def test_butterworth_poles():
    poles = youla.butterworth(WN, ZETA).poles()
    np.testing.assert_allclose(np.abs(poles), WN)
    np.testing.assert_allclose(-poles.real / np.abs(poles), ZETA)


def test_sampled_outer_design_is_step_invariant_eq36():
    k = youla.outer_controller_discrete(TAU, WN, ZETA, CAMERA_DT)
    assert k.is_proper()
    poles = k.poles()
    assert np.sum(np.isclose(poles, 1.0, atol=1e-9)) == 1  # one integrator
    assert np.all(np.abs(poles[~np.isclose(poles, 1.0, atol=1e-9)]) < 1.0)
    plant = youla.inner_closed_loop(TAU).discretise(CAMERA_DT, 'zoh')
    loop = (k * plant).feedback().minreal(1e-5)
    assert loop.same_as(youla.butterworth(WN, ZETA).discretise(CAMERA_DT, 'zoh'), rtol=1e-5)


def test_bandwidth_rule():
    youla.check_bandwidth_rule(0.01, 10.0)
    with pytest.raises(ValueError, match='tau_in'):
        youla.check_bandwidth_rule(0.01, 100.0)
    with pytest.raises(ValueError):
        youla.check_bandwidth_rule(0.0, 10.0)


# -- feedforward, eq. (44)-(45) --------------------------------------------------------------

def test_eq44_inverts_eq29_up_to_the_double_pole():
    ff = youla.feedforward(TAU)
    cascade = (ff * youla.inner_closed_loop(TAU)).minreal(1e-3)
    tau_f = 0.1 * TAU
    assert cascade.same_as(TransferFunction([1.0], np.poly([-1 / tau_f] * 2) * tau_f ** 2))
    # biproper, high-frequency gain tau^3 / (3 tau tau_f^2) = 33.3 (docs/design.md §5)
    assert ff(1e9j).real == pytest.approx(1.0 / (3 * 0.01), rel=1e-4)


def test_sampled_feedforward_inverts_the_sampled_inner_loop():
    ff = youla.feedforward_discrete(TAU, DT)
    assert ff.is_stable() and ff.dc_gain() == pytest.approx(1.0)
    cascade = (ff * youla.inner_closed_loop_discrete(TAU, DT)).minreal(1e-4)
    p_f = np.exp(-DT / (0.1 * TAU))
    expected = TransferFunction(np.array([0.5, 0.5]) * (1 - p_f) ** 2, np.poly([p_f] * 2), DT)
    assert cascade.same_as(expected, rtol=1e-5)
    # through the sampled inner loop, a step of the target gives no overshoot
    steps = 100
    ffilt = StateSpaceFilter(ff, 1)
    refs = [ffilt.step(np.ones(1)) for _ in range(steps)]
    q = simulate_inner(youla.inner_controller_discrete(TAU, DT), refs, steps)[:, 0]
    assert np.all(np.diff(q) >= -1e-12) and q.max() <= 1.0 + 1e-9
    assert q[20] > 0.999
