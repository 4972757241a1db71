"""The free-running metrics from their records (pure; no bag, no rclpy)."""

from ibvs_experiments.analysis import free_running_metrics
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


def test_a_lockstep_run_gains_no_keys():
    assert free_running_metrics(np.zeros((0, 2)), []) == {}
    assert free_running_metrics([], [0.1]) == {}
