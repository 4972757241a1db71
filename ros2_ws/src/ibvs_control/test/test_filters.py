"""Properties of the state-space filter run many samples at once (no ROS)."""

from ibvs_control import youla
from ibvs_control.filters import RECURRENCE_SAMPLES, StateSpaceFilter
import numpy as np
import pytest


def _rested(tau_in, dt, q0):
    f = StateSpaceFilter(youla.feedforward_discrete(tau_in, dt, youla.FEEDFORWARD_RATIO), 6)
    f.reset(rest_input=q0)
    return f


@pytest.mark.parametrize('tau_in', [0.01, 0.5])
def test_held_outputs_are_the_recurrence_bit_for_bit_then_to_within_its_rounding(tau_in):
    q0 = np.linspace(-0.5, 0.5, 6)
    u = q0 + np.linspace(0.3, -0.9, 6)
    stepped, held = _rested(tau_in, 1e-3, q0), _rested(tau_in, 1e-3, q0)
    samples = RECURRENCE_SAMPLES + 3000
    by_step = np.array([stepped.step(u) for _ in range(samples)])
    # in uneven blocks, one of them across the switch to the compiled recurrence
    blocks = [held.held_outputs(u, n) for n in (1, 999, RECURRENCE_SAMPLES - 1500, 2500, 1000)]
    by_block = np.concatenate(blocks)
    np.testing.assert_array_equal(by_block[:RECURRENCE_SAMPLES], by_step[:RECURRENCE_SAMPLES])
    # past it both are the same recurrence, ordered differently: rounding apart
    np.testing.assert_allclose(by_block, by_step, rtol=0, atol=1e-9 + 1e-6 * tau_in)
    assert held.steps == stepped.steps == samples
    np.testing.assert_allclose(held.x, stepped.x, rtol=1e-9)
    np.testing.assert_array_equal(held.last_output, by_block[-1])
    # and the state carries on as step() would from there
    np.testing.assert_allclose(held.step(u), stepped.step(u), rtol=0, atol=1e-6)


def test_held_outputs_converge_to_the_dc_gain_times_the_input():
    q0, u = np.zeros(6), np.full(6, 1.2)
    f = _rested(1.0, 1e-3, q0)
    out = f.held_outputs(u, 60_000)
    np.testing.assert_allclose(out[-1], f.tf.dc_gain() * u, atol=1e-6)
    assert not np.allclose(out[0], out[-1], atol=0.1)
