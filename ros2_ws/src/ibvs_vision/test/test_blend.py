"""The bumpless switch between measured and estimated features (section 2.3, eq. 46)."""

from ibvs_vision.blend import BLENDING, BumplessSwitch, ESTIMATED, MEASURED
import numpy as np
import pytest

DT = 33_333_333  # ns: 30 Hz frames, sim time in integer nanoseconds


def test_estimate_alone_is_published_bit_for_bit():
    switch = BumplessSwitch(0.2)
    rng = np.random.default_rng(0)
    for n in range(10):
        estimate = rng.uniform(0.0, 1000.0, 6)
        out = switch.update(n * DT, None, estimate)
        assert np.array_equal(out, estimate)
        assert switch.mode == ESTIMATED
    assert switch.last_switch_ns is None and switch.switches == 0


def test_a_switch_holds_then_fades_the_offset_linearly():
    blend = 0.2
    switch = BumplessSwitch(blend)
    estimate = np.arange(6.0)
    measured = estimate + np.array([3.0, -2.0, 1.0, 0.5, 0.0, -4.0])
    outs = [switch.update(n * DT, None, estimate) for n in range(3)]
    for n in range(3, 15):
        outs.append(switch.update(n * DT, measured, estimate))
        t = (n - 3) * DT * 1e-9
        weight = max(0.0, 1.0 - t / blend)
        # out = measured + (previous output - measured) * (1 - t / blend)
        assert np.allclose(outs[-1], measured + weight * (estimate - measured), atol=1e-6)
        assert switch.mode == (BLENDING if weight > 0.0 else MEASURED)
    assert np.array_equal(outs[3], outs[2])  # the switch frame holds
    assert np.array_equal(outs[-1], measured)  # then exactly the measurement
    assert switch.last_switch_ns == 3 * DT
    steps = np.abs(np.diff(outs, axis=0))
    assert np.all(steps <= np.abs(measured - estimate) * DT * 1e-9 / blend + 1e-12)


def test_per_frame_change_is_bounded_whatever_the_sources_do():
    """|out_k - out_k-1| <= |source_k - source_k-1| + |offset| dt / blend_time, always."""
    blend = 0.15
    switch = BumplessSwitch(blend)
    rng = np.random.default_rng(1)
    estimate = rng.uniform(0.0, 500.0, 6)
    bias = rng.normal(0.0, 5.0, 6)
    seen = rng.random(200) < 0.5
    prev_out = prev_src = prev_est = None
    offset = np.zeros(6)
    for n in range(200):
        estimate = estimate + rng.normal(0.0, 0.3, 6)
        measured = estimate + bias + rng.normal(0.0, 0.05, 6) if seen[n] else None
        source = measured if measured is not None else estimate
        out = switch.update(n * DT, measured, estimate)
        if prev_out is not None:
            if switch.last_switch_ns == n * DT:
                # The switch frame moves as the model predicts, nothing more.
                assert np.allclose(out, prev_out + estimate - prev_est, atol=1e-9)
                offset = out - source
            else:
                bound = np.abs(source - prev_src) + np.abs(offset) * DT * 1e-9 / blend + 1e-9
                assert np.all(np.abs(out - prev_out) <= bound)
        prev_out, prev_src, prev_est = out, source, estimate
    assert switch.switches > 20


def test_a_moving_arm_is_followed_across_switches_without_lag():
    """
    Follow fast motion with the markers seen every other seven frames.

    The output stays between the estimate and the measurement (they differ by the model
    error) and never lags behind both.
    """
    switch = BumplessSwitch(0.2)
    bias = np.array([2.0, 2.0, -1.0, 3.0, 3.0, -1.5])
    velocity = np.array([300.0, 300.0, -100.0, 310.0, 310.0, -90.0])  # px/s
    for n in range(120):
        estimate = 100.0 + velocity * n * DT * 1e-9
        measured = estimate + bias if (n // 7) % 2 else None
        out = switch.update(n * DT, measured, estimate)
        low, high = np.minimum(estimate, estimate + bias), np.maximum(estimate, estimate + bias)
        assert np.all(out >= low - 1e-9) and np.all(out <= high + 1e-9), n
    assert switch.switches >= 15


def test_a_switch_back_during_a_blend_starts_from_the_current_output():
    switch = BumplessSwitch(0.3)
    estimate, measured = np.zeros(6), np.full(6, 10.0)
    switch.update(0, None, estimate)
    switch.update(DT, measured, estimate)
    mid = switch.update(4 * DT, measured, estimate)
    assert switch.mode == BLENDING and 0.0 < mid[0] < 10.0
    back = switch.update(5 * DT, None, estimate)
    assert np.array_equal(back, mid)
    assert switch.source == ESTIMATED and switch.switches == 2
    later = switch.update(6 * DT, None, estimate)
    assert np.allclose(later, mid * (1.0 - DT * 1e-9 / 0.3))


def test_zero_blend_time_switches_outright():
    switch = BumplessSwitch(0.0)
    estimate, measured = np.zeros(6), np.ones(6)
    switch.update(0, None, estimate)
    assert np.array_equal(switch.update(DT, measured, estimate), measured)
    assert switch.mode == MEASURED and switch.last_switch_ns == DT


def test_bad_arguments():
    with pytest.raises(ValueError, match='blend_time_s'):
        BumplessSwitch(-0.1)
    with pytest.raises(ValueError, match='blend_time_s'):
        BumplessSwitch(float('nan'))
    with pytest.raises(ValueError, match='neither'):
        BumplessSwitch(0.2).update(0, None, None)


def test_hold_model_error_keeps_the_last_seen_error_while_estimated():
    """With hold_model_error the estimate carries the model error of the last measurement."""
    switch = BumplessSwitch(0.2, hold_model_error=True)
    error = np.array([3.0, -2.0, 1.0, 0.5, 0.0, -4.0])
    estimates = [np.arange(6.0) + n for n in range(40)]
    for n in range(3):  # measured: the model is off by `error`
        assert np.array_equal(switch.update(n * DT, estimates[n] + error, estimates[n]),
                              estimates[n] + error)
    for n in range(3, 20):  # lost: F(q_T) + the error, however long
        out = switch.update(n * DT, None, estimates[n])
        assert np.allclose(out, estimates[n] + error, atol=1e-12)
        assert switch.mode == ESTIMATED
    # Seen again (the model error has changed): from there on the usual fade.
    later = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0])
    out = switch.update(20 * DT, estimates[20] + later, estimates[20])
    assert np.allclose(out, estimates[20] + error) and switch.mode == BLENDING
    for n in range(21, 40):
        out = switch.update(n * DT, estimates[n] + later, estimates[n])
    assert np.array_equal(out, estimates[39] + later) and switch.mode == MEASURED
    # Never seen: nothing to hold, the paper's estimate exactly.
    fresh = BumplessSwitch(0.2, hold_model_error=True)
    assert np.array_equal(fresh.update(0, None, estimates[0]), estimates[0])
