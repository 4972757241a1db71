"""The workspace benchmark's definition, summary statistics and per-run metrics (no ROS)."""

import json
import math

from ibvs_experiments import vsbench, vsbench_report, vsbench_tasks
from ibvs_model import IRB4600
import numpy as np
import pytest
from scipy import stats


def _same(committed, written, path='$'):
    """Assert two parsed JSON values equal: exactly, floats to 1e-9 relative (see below)."""
    if isinstance(committed, float) or isinstance(written, float):
        assert written == pytest.approx(committed, rel=1e-9, abs=1e-12), path
    elif isinstance(committed, dict):
        assert isinstance(written, dict) and committed.keys() == written.keys(), path
        for key in committed:
            _same(committed[key], written[key], f'{path}.{key}')
    elif isinstance(committed, list):
        assert isinstance(written, list) and len(committed) == len(written), path
        for i, (a, b) in enumerate(zip(committed, written)):
            _same(a, b, f'{path}[{i}]')
    else:
        assert committed == written, path


@pytest.mark.parametrize('version, n', [('vsbench-2', vsbench_tasks.TASKS),
                                        ('vsbench-3', 40)])
def test_the_committed_benchmark_file_is_what_its_definition_writes(version, n):
    # The tasks' derived figures (IK, Jacobians' singular values) go through LAPACK and
    # libm, whose last bits differ between machines and builds: every text and integer must
    # be the same, every float the same to 1e-9 relative (the seeds and draws that decide a
    # task are integers or come out of numpy's generator, identical everywhere). vsbench-3
    # renders each target it draws: its first 40 tasks, a prefix of the file (the header's
    # draw counts are those of all 500).
    path = vsbench_tasks.benchmark_path(version)
    committed = json.loads(path.read_text())
    written = json.loads(vsbench_tasks.dumps(vsbench_tasks.definition(n, version)))
    if n < vsbench_tasks.TASKS:
        written['tasks_definition'].pop('draws')
        written['tasks_definition'].pop('n')
        committed = {**committed, 'tasks': committed['tasks'][:n],
                     'tasks_definition': {k: v for k, v in committed['tasks_definition'].items()
                                          if k not in ('draws', 'n')}}
    _same(committed, written)
    data = vsbench_tasks.load(version)
    assert data['version'] == version
    assert len(data['tasks']) == vsbench_tasks.TASKS
    assert len({t['id'] for t in data['tasks']}) == vsbench_tasks.TASKS


def test_the_newest_version_is_the_default_and_keeps_what_its_own_teach_can_serve():
    data = vsbench_tasks.load()
    assert data['version'] == vsbench_tasks.VERSION == 'vsbench-3'
    bound = data['tasks_definition']['margins']['min_observability_px_rad']
    assert bound == pytest.approx(0.826, abs=1e-3)  # the bound of the 10-frame teach
    observability = [t['observability'] for t in data['tasks']]
    assert min(observability) >= bound
    # a third of the tasks lies below the one-frame bound vsbench-2 refused them at
    assert sum(o < 2.6 for o in observability) > 100
    assert all(t['id'].startswith('workspace-3/1/') for t in data['tasks'])
    # the rendered line of sight refused targets, and said why
    draws = data['tasks_definition']['draws']
    assert sum(v for k, v in draws.items() if 'rendered target' in k) >= 6


def test_a_shorter_definition_is_a_prefix_of_the_longer_one():
    assert vsbench_tasks.definition(7)['tasks'] == vsbench_tasks.definition(12)['tasks'][:7]


def test_the_imperfections_stay_within_their_bounds():
    draws = vsbench_tasks.imperfections(400)
    xyz = np.array([d['camera_pose_error_xyz_m'] for d in draws])
    rpy = np.array([d['camera_pose_error_rpy_deg'] for d in draws])
    focal = np.array([d['focal_length_error'] for d in draws])
    assert np.abs(xyz).max() <= vsbench_tasks.POSITION_ERROR_M
    assert np.abs(rpy).max() <= vsbench_tasks.ROTATION_ERROR_DEG
    assert np.abs(focal - 1.0).max() <= vsbench_tasks.FOCAL_ERROR
    # uniform over the whole range, not a corner of it
    assert np.abs(xyz).max() > 0.9 * vsbench_tasks.POSITION_ERROR_M
    assert all(isinstance(d['camera_seed'], int) for d in draws)
    assert len({d['camera_seed'] for d in draws}) == len(draws)


def test_a_file_of_another_version_is_refused(tmp_path):
    path = tmp_path / 'b.json'
    path.write_text('{"version": "vsbench-0", "tasks": []}')
    with pytest.raises(ValueError, match='vsbench-0'):
        vsbench_tasks.load(path)


@pytest.mark.parametrize('seed', range(5))
def test_the_wilson_interval_is_scipys_and_holds_the_rate(seed):
    rng = np.random.default_rng(seed)
    for _ in range(40):
        n = int(rng.integers(1, 600))
        k = int(rng.integers(0, n + 1))
        low, high = vsbench_report.wilson(k, n)
        ci = stats.binomtest(k, n).proportion_ci(0.95, method='wilson')
        assert (low, high) == (ci.low, ci.high)
        assert 0.0 <= low <= k / n <= high <= 1.0
        # more runs at the same rate: a narrower interval
        low2, high2 = vsbench_report.wilson(4 * k, 4 * n)
        assert high2 - low2 < high - low
    assert all(math.isnan(v) for v in vsbench_report.wilson(0, 0))


def _row(task, law, success, source='model', **extra):
    return {'task': task, 'law': law, 'success': success, 'source': source,
            'miss_reason': '' if success else 'stalled', 'time_to_1mm_s': 1.0,
            'overshoot_m': 0.001, 'path_length_ratio': 1.2, 'peak_speed_ratio': 0.5,
            'interventions': 2, 'limit_violations': 0, 'collisions': 0,
            'min_limit_distance_rad': 0.3, 'min_self_clearance_m': 0.2,
            'min_scene_clearance_m': 0.1, **extra}


@pytest.mark.parametrize('seed', range(4))
def test_the_summary_counts_each_law_and_takes_its_interval_from_scipy(seed):
    rng = np.random.default_rng(seed)
    rows = [_row(f't{i}', law, bool(rng.random() < p), source)
            for source in ('model', 'graph') for law, p in (('paper', 0.9), ('ibvs', 0.3))
            for i in range(int(rng.integers(1, 80)))]
    for s in vsbench_report.summarise(rows):
        group = [r for r in rows if r['source'] == s['source'] and r['law'] == s['law']]
        wins = sum(r['success'] for r in group)
        assert (s['runs'], s['successes']) == (len(group), wins)
        assert s['rate'] == wins / len(group)
        assert (s['ci_low'], s['ci_high']) == vsbench_report.wilson(wins, len(group))
        assert sum(s['miss_classes'].values()) == len(group) - wins
        assert s['interventions'] == 2 * len(group)


def test_model_and_graph_agree_when_they_match_and_not_when_they_are_far_apart():
    same = [_row(f't{i}', 'paper', i % 10 != 0, s) for s in ('model', 'graph')
            for i in range(100)]
    (entry,) = vsbench_report.agreement(same)
    assert entry['agree'] and entry['same_verdict'] == 100 and entry['tasks'] == 100
    apart = [_row(f't{i}', 'paper', s == 'model' or i < 20, s) for s in ('model', 'graph')
             for i in range(100)]
    (entry,) = vsbench_report.agreement(apart)
    assert not entry['agree'] and entry['graph']['successes'] == 20
    # only the tasks both ran are compared
    extra = same + [_row('only-model', 'paper', False, 'model')]
    assert vsbench_report.agreement(extra)[0]['tasks'] == 100


def test_run_metrics_count_limit_violations_and_path_length():
    task = vsbench_tasks.load()['tasks'][0]
    q0, q1 = np.array(task['start_joints']), np.array(task['target_joints'])
    s = np.linspace(0.0, 1.0, 200)[:, None]
    q = q0 + s * (q1 - q0)
    t = np.linspace(0.0, 2.0, 200)
    row = vsbench.run_metrics(task, 'paper', t, q)
    assert row['success'] and row['limit_violations'] == 0 and row['collisions'] == 0
    assert row['path_length_ratio'] >= 1.0 - 1e-9
    assert row['min_limit_distance_rad'] > 0.0
    assert row['peak_speed_ratio'] > 0.0
    # past joint 1's upper limit in 3 samples: 3 violations, a negative distance
    q_bad = q.copy()
    q_bad[50:53, 0] = IRB4600.q_max[0] + 0.01
    bad = vsbench.run_metrics(task, 'paper', t, q_bad)
    assert bad['limit_violations'] == 3
    assert bad['min_limit_distance_rad'] == pytest.approx(-0.01)


def test_graph_overrides_carry_the_task_and_its_imperfections():
    bench = vsbench_tasks.load()
    spec = vsbench.graph_spec(bench, 2, ('paper', 'ibvs'))
    runs = spec.runs()
    assert len(runs) == 4
    first = runs[0].overrides
    task = bench['tasks'][0]
    for name in ('start_joints', 'target_position', 'camera_pose_error_xyz_m',
                 'camera_seed', 'focal_length_error'):
        assert first[name] == task[name]
    assert first['resolution'] == 'HD720' and first['safety_envelope'] is True
    assert runs[1].overrides['servo_law'] == 'ibvs'
    assert runs[1].overrides['feedforward_method'] == 'hold'


def test_scenario3_start_reaches_shifted_targets_without_the_over_the_head_branch():
    # From scenario 3's start, targets shifted 0.3-0.4 m from the paper's have an IK branch
    # over the arm's top (q2 -46..-60 deg, q3 -152..-172 deg); the IK's reach cone
    # (ibvs_model.ik_branch) keeps the front one. With limited actuators the arm makes the
    # synchronised move along the straight joint-space line to it: the tool passes the
    # target only as far as that line's own bend does, never further (the feedback, designed
    # for the 67 ms latency, adds nothing to it).
    from ibvs_analysis.metrics import compute_metrics
    from ibvs_control.closed_loop import LoopConfig, simulate
    from ibvs_model import forward_kinematics_batch, IRB4600, paper
    rng = np.random.default_rng(38)
    for k in range(6):
        shift = rng.normal(size=3)
        shift *= rng.uniform(0.3, 0.4) / np.linalg.norm(shift)
        target = paper.target_pose()
        target[:3, 3] += shift
        config = LoopConfig.for_law('paper', scenario=3, actuators='limited',
                                    feedback_latency_s=0.067, lambda_0=6.0,
                                    torque_limits=vsbench.ACCELERATION_LIMITS)
        result = simulate(config, 5.0, target=target)
        assert np.degrees(result.q_target[1]) > 0.0 and np.degrees(result.q_target[2]) > 0.0
        task = {'id': f'shifted/{k}', 'index': k, 'observability': 0.0,
                'target_position': list(target[:3, 3]),
                'target_rotation': list(target[:3, :3].ravel()),
                'start_joints': list(result.q_true[0]), 'target_joints': list(result.q_target)}
        row = vsbench.run_metrics(task, 'paper', result.t, result.q_true)
        # the straight joint-space line from the true start to the true goal
        start = result.q_true[0]
        line = start + np.linspace(0.0, 1.0, 2001)[:, None] * (
            result.q_target + (start - result.q[0]) - start)
        poses = forward_kinematics_batch(line, IRB4600)
        bend = compute_metrics(np.linspace(0.0, 1.0, 2001), poses[:, :3, 3], poses[:, :3, :3],
                               target, np.zeros(0), [])['max_overshoot_m']
        assert row['overshoot_m'] <= bend + 5e-4, (k, shift, row['overshoot_m'], bend)
        assert row['overshoot_m'] <= 0.025, (k, shift, row['overshoot_m'])
        assert row['success'], (k, row)


def test_the_model_loops_acceleration_limits_are_the_first_targets_rounded_down():
    computed = vsbench.acceleration_limits()
    limits = np.asarray(vsbench.ACCELERATION_LIMITS)
    assert np.all(limits[:5] <= computed[:5])
    # rounded down to two significant figures, not further
    assert np.all(limits[:5] >= 0.9 * computed[:5])


def test_the_sampler_margins_are_those_of_their_sources():
    # ibvs_model cannot import ibvs_control or ibvs_experiments: its two measured margins
    # are copies, tied here to what they stand for (task_sampler's module docstring).
    from ibvs_analysis.convergence import SUCCESS
    from ibvs_control.envelope import LOWER_SINGULARITY_THRESHOLD
    from ibvs_model.task_sampler import Margins
    margins = Margins()
    assert margins.max_condition_number == LOWER_SINGULARITY_THRESHOLD
    bound = 3 * vsbench.FEATURE_NOISE_PX['HD720'] / math.radians(SUCCESS.axis_deg)
    assert margins.min_observability_px_rad == pytest.approx(bound, abs=0.05)


def test_a_graph_runs_local_minimum_is_its_own_miss_class():
    row = {'success': False, 'intervention_codes': {},
           'miss_reason_text': 'local minimum of the image error at 6 s: image error 0.41 px, '
                               'yet the tool is 25.3 mm and 45.1 deg from the target; final '
                               '25.3 mm, 45.1 deg, outside 1 mm and 0.5 deg'}
    assert vsbench.miss_class(row, last_limit_distance=1.0) == 'local minimum'
    # next to a joint limit it is still the image's minimum, not the limit's stall
    assert vsbench.miss_class(row, last_limit_distance=0.0) == 'local minimum'
    row['miss_reason_text'] = 'stalled at 6 s: final 25.3 mm, 45.1 deg, outside 1 mm and 0.5 deg'
    assert vsbench.miss_class(row, last_limit_distance=0.0) == 'limit'
