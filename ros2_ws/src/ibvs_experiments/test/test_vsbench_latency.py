"""The workspace benchmark's latency axis and time-optimal bound (model loop, no ROS)."""

from ibvs_control.controllers import limited_time_optimal_s
from ibvs_control.governor import JERK_RISE_S
from ibvs_experiments import vsbench, vsbench_report, vsbench_tasks
from ibvs_model import IRB4600, task_sampler
import numpy as np
import pytest


def _row(task, law, success, latency, error=0.0, source='model', **extra):
    return {'task': task, 'law': law, 'success': success, 'source': source,
            'latency_s': latency, 'latency_error_s': error,
            'miss_reason': '' if success else 'stalled', 'time_to_1mm_s': 1.0,
            'time_optimal_s': 0.6, 'time_to_1mm_over_optimal_s': 0.4, 'overshoot_m': 0.001,
            'ripple_m': 2e-4, 'min_limit_distance_rad': 0.3, **extra}


def test_the_mismodelled_points_join_the_axis_only_at_their_latency():
    points = vsbench.latency_points(vsbench.LATENCY_AXIS)
    assert points[:len(vsbench.LATENCY_AXIS)] == [(x, 0.0) for x in vsbench.LATENCY_AXIS]
    assert points[len(vsbench.LATENCY_AXIS):] == list(vsbench.MISMODELLED)
    assert vsbench.latency_points((0.0, 0.2)) == [(0.0, 0.0), (0.2, 0.0)]


def test_the_axis_counts_each_point_and_a_law_fails_where_its_rate_first_drops():
    # paper: 100 % up to 0.2 s, 90 % at 0.3 s; a mis-modelled point at 0.133 s that fails
    # does not count (the law's latency was wrong there, not too long)
    rows = []
    for latency, wins in ((0.0, 20), (0.133, 20), (0.2, 19), (0.3, 18)):
        rows += [_row(f't{i}', 'paper', i < wins, latency) for i in range(20)]
    rows += [_row(f't{i}', 'paper', i < 5, 0.133, 0.02) for i in range(20)]
    rows += [_row(f't{i}', 'paper', True, 0.133, source='graph') for i in range(3)]
    axis = vsbench_report.latency_axis(rows)
    assert [(e['source'], e['latency_s'], e['latency_error_s']) for e in axis] == [
        ('model', 0.0, 0.0), ('model', 0.133, 0.0), ('model', 0.133, 0.02),
        ('model', 0.2, 0.0), ('model', 0.3, 0.0), ('graph', 0.133, 0.0)]
    by = {(e['source'], e['latency_s'], e['latency_error_s']): e for e in axis}
    assert by[('model', 0.2, 0.0)]['successes'] == 19
    assert by[('model', 0.2, 0.0)]['rate'] == 0.95
    assert (by[('model', 0.3, 0.0)]['ci_low'], by[('model', 0.3, 0.0)]['ci_high']) == \
        vsbench_report.wilson(18, 20)
    assert by[('model', 0.0, 0.0)]['excess_s'] == pytest.approx(0.4)
    assert vsbench_report.first_failing(axis) == {('model', 'paper'): 0.3,
                                                  ('graph', 'paper'): None}
    lines = vsbench_report.latency_table(axis)
    assert any('| model | paper | 133 | +20 | 20 | 5 (25 %)' in line for line in lines)
    assert '- model loop, `paper`: 300 ms' in lines


def test_a_point_selects_its_rows_whatever_the_floats_rounding():
    rows = [_row('a', 'paper', True, 0.1 + 0.2), _row('b', 'paper', True, 0.3, 0.02)]
    assert [r['task'] for r in vsbench_report.at_point(rows, 0.3)] == ['a']
    assert [r['task'] for r in vsbench_report.at_point(rows, 0.3, 0.02)] == ['b']


def test_the_bound_is_toppras_move_plus_at_most_one_jerk_rise():
    # The model loop's 'limited' plant: rated speeds and the accelerations the torque
    # limits buy on M = I (the governor caps them at full speed in one rise), jerk
    # a / JERK_RISE_S. TOPP-RA (a test-only peer) has no jerk limit: Ruckig's bound is its
    # straight line's optimum plus what ramping the acceleration costs, about one rise
    # (half of it at each of the move's two ends), never less.
    ta = pytest.importorskip('toppra', reason='TOPP-RA is pinned in requirements-test.txt')
    speed = np.asarray(IRB4600.qd_max, dtype=float)
    acceleration = np.minimum(np.asarray(vsbench.ACCELERATION_LIMITS), speed / JERK_RISE_S)
    for task in task_sampler.tasks(20, seed=7):
        q0 = np.asarray(task['start_joints'], dtype=float)
        q1 = np.asarray(task['target_joints'], dtype=float)
        path = ta.SplineInterpolator([0.0, 1.0], np.vstack([q0, q1]))
        limits = [ta.constraint.JointVelocityConstraint(np.vstack([-speed, speed]).T),
                  ta.constraint.JointAccelerationConstraint(
                      np.vstack([-acceleration, acceleration]).T)]
        peer = float(ta.algorithm.TOPPRA(
            limits, path, gridpoints=np.linspace(0.0, 1.0, 2000),
            parametrizer='ParametrizeConstAccel').compute_trajectory(0.0, 0.0).duration)
        ours = limited_time_optimal_s(q0, q1, vsbench.ACCELERATION_LIMITS)
        assert peer - 1e-3 <= ours <= peer + JERK_RISE_S + 3e-3, (task['id'], ours, peer)


def test_a_model_run_records_its_point_and_never_beats_its_bound():
    task = vsbench_tasks.load()['tasks'][0]
    conditions = {**vsbench.CONDITIONS, 'feedback_latency_s': 0.133}
    right = vsbench.model_run(task, 'switching', conditions, duration_s=2.0)
    assert (right['latency_s'], right['latency_error_s']) == (0.133, 0.0)
    bound = limited_time_optimal_s(task['start_joints'], task['target_joints'],
                                   vsbench.ACCELERATION_LIMITS)
    assert right['time_optimal_s'] == bound
    assert right['time_to_1mm_over_optimal_s'] == pytest.approx(
        right['time_to_1mm_s'] - bound)
    # the plant's speed and torque are clipped to the same limits (without the jerk the
    # bound assumes: a rise at each end), so no run is within 1 mm sooner
    assert right['time_to_1mm_over_optimal_s'] > -2 * JERK_RISE_S
    wrong = vsbench.model_run(task, 'switching', conditions, duration_s=2.0,
                              latency_error_s=0.02)
    assert wrong['latency_error_s'] == 0.02
    assert wrong['time_optimal_s'] == bound
    # the latency the law assumes changes the run, not the task
    assert wrong['final_position_error_m'] != right['final_position_error_m']
    assert wrong['start_distance_m'] == right['start_distance_m']


def test_ideal_actuators_have_no_bound():
    task = vsbench_tasks.load()['tasks'][0]
    assert vsbench.time_optimal_s(task, {'actuators': 'ideal'}) is None
