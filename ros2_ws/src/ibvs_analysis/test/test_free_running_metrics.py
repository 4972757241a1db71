"""The free-running metrics from their records (pure; no bag, no rclpy)."""

from ibvs_analysis.metrics import free_running_metrics
import numpy as np
import pytest

MS = 1_000_000


def test_latency_from_exposure_to_first_command_and_rtf_held():
    frames = np.arange(0, 100) * 33 * MS
    delays = np.arange(100) * 0.1 * MS + 20 * MS  # 20 ... 29.9 ms
    pairs = np.column_stack([frames + delays.astype(np.int64), frames])
    m = free_running_metrics(pairs, [0.05, 0.04, 0.045])
    assert m['frames_used'] == 100
    assert m['frame_latency_mean_s'] == pytest.approx(delays.mean() * 1e-9)
    assert m['frame_latency_p95_s'] == pytest.approx(np.percentile(delays, 95) * 1e-9)
    assert m['frame_latency_max_s'] == pytest.approx(29.9e-3)
    assert m['real_time_factor_held_min'] == pytest.approx(0.04)
    assert m['real_time_factor_held_mean'] == pytest.approx(0.045)


def test_frames_published_and_the_factor_held_while_servoing():
    """Frames_published beside frames_used; the servoing's factor held."""
    pairs = np.column_stack([np.arange(1, 4) * 40 * MS, np.arange(3) * 33 * MS])
    m = free_running_metrics(pairs, [0.01, 0.05], frames_published=5,
                             servo_rtf={'real_time_factor_servo_mean': '0.049',
                                        'real_time_factor_servo_min_1s': '0.047'})
    assert (m['frames_used'], m['frames_published']) == (3, 5)
    assert m['real_time_factor_servo_mean'] == pytest.approx(0.049)
    assert m['real_time_factor_servo_min_1s'] == pytest.approx(0.047)
    assert m['real_time_factor_held_min'] == pytest.approx(0.01)  # start-up's, kept
    unknown = free_running_metrics(pairs, [])
    assert unknown['frames_published'] is None
    assert unknown['real_time_factor_servo_mean'] is None
    assert unknown['real_time_factor_servo_min_1s'] is None


def test_a_lockstep_run_gains_no_keys():
    assert free_running_metrics(np.zeros((0, 2)), []) == {}
    assert free_running_metrics([], [0.1]) == {}


def test_the_render_device_comes_from_the_simulators_diagnostics():
    """render_device and render_hardware, from /diagnostics strings."""
    from ibvs_analysis.metrics import render_metrics
    assert render_metrics({'render_device': 'llvmpipe (LLVM 15.0.6, 256 bits)',
                           'render_hardware': 'False'}) == {
        'render_device': 'llvmpipe (LLVM 15.0.6, 256 bits)', 'render_hardware': False}
    assert render_metrics({'render_device': 'NVIDIA H100', 'render_hardware': 'True'})[
        'render_hardware'] is True
    assert render_metrics({}) == {}  # physics only: nothing drawn, no keys
