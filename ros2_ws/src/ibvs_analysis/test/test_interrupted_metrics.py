"""A run that SIGINT stopped is no success, however close to the target it was."""

from ibvs_analysis.metrics import compute_metrics, interrupted_outcome
import numpy as np


def converged_metrics():
    """Return the metrics of a run that reaches the target and stays there."""
    t = np.arange(0.0, 1.0, 1e-3)
    start, target = np.array([1.0, 0.2, 1.0]), np.array([0.8, 0.2, 0.9])
    position = start + np.outer(1 - np.exp(-20 * t), target - start)
    rotation = np.repeat(np.eye(3)[None], len(t), axis=0)
    tf = np.eye(4)
    tf[:3, 3] = target
    metrics = compute_metrics(t, position, rotation, tf)
    assert metrics['success'] and metrics['miss_reason'] is None
    return metrics


def test_an_interrupted_run_misses_and_says_why():
    metrics = interrupted_outcome(converged_metrics(), {'interrupted': True,
                                                        'duration_s': 3.0})
    assert metrics['success'] is False
    assert metrics['miss_reason'].startswith('interrupted (SIGINT) at 0.999 s of sim time: ')
    assert 'final ' in metrics['miss_reason'] and ' deg' in metrics['miss_reason']


def test_a_run_that_ran_its_time_keeps_its_outcome():
    for run_info in ({}, {'interrupted': False}):
        assert interrupted_outcome(converged_metrics(), run_info) == \
            converged_metrics()
