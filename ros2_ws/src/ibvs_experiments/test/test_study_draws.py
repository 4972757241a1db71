"""Study draws: integers, vectors, per-run draws, tasks, values as drawn."""

from ibvs_bringup import scenario
from ibvs_experiments import study, study_spec
from ibvs_experiments.study_spec import parse, StudyError
from ibvs_model import task_sampler
import numpy as np
import pytest

BASE = {'scenario': 'scenario1'}


def _draws(n=40, seed=3, **parameters):
    return {**BASE, 'draws': {'n': n, 'seed': seed, 'parameters': parameters}}


def test_integers_are_inclusive_seeded_integers():
    runs = parse(_draws(camera_seed={'integers': [0, 3]})).runs()
    values = [r.overrides['camera_seed'] for r in runs]
    assert all(type(v) is int for v in values)
    assert set(values) == {0, 1, 2, 3}  # 40 draws: both ends included
    assert values == [r.overrides['camera_seed']
                      for r in parse(_draws(camera_seed={'integers': [0, 3]})).runs()]


def test_a_vector_is_drawn_one_value_per_element():
    lows, highs = [-0.01, 0.0, 0.5], [0.01, 0.002, 0.6]
    runs = parse(_draws(camera_pose_error_xyz_m={'uniform': [lows, highs]})).runs()
    values = np.array([r.overrides['camera_pose_error_xyz_m'] for r in runs])
    assert values.shape == (40, 3)
    assert np.all(values >= lows) and np.all(values < highs)
    assert all(isinstance(x, float) for r in runs
               for x in r.overrides['camera_pose_error_xyz_m'])
    assert len({tuple(v) for v in values}) == 40
    ints = parse(_draws(v={'integers': [[0, 10], [1, 20]]})).runs()
    assert all(0 <= r.swept['v'][0] <= 1 and 10 <= r.swept['v'][1] <= 20 for r in ints)


def test_per_run_draws_are_not_crossed_with_the_grid():
    data = {**BASE, 'grid': {'g': [0, 1, 2]},
            'draws': {'n': 4, 'seed': 1, 'mode': 'per_run',
                      'parameters': {'u': {'uniform': [0.0, 1.0]}}}}
    runs = parse(data).runs()
    assert len(runs) == 12 and [r.swept['g'] for r in runs] == [0] * 4 + [1] * 4 + [2] * 4
    assert len({r.swept['u'] for r in runs}) == 12  # a draw of its own for each run
    crossed = parse({**data, 'draws': {**data['draws'], 'mode': 'crossed'}}).runs()
    assert len({r.swept['u'] for r in crossed}) == 4  # the same 4 at every grid point
    # The first grid point's draws are the same in both modes (one stream, in order).
    assert [r.swept['u'] for r in runs[:4]] == [r.swept['u'] for r in crossed[:4]]


def test_a_drawn_task_sets_start_and_target_and_names_itself():
    data = {**BASE, 'draws': {'n': 3, 'seed': 0, 'task': {'seed': 5}}}
    runs = parse(data).runs()
    expected = task_sampler.tasks(3, 5)
    for run, task in zip(runs, expected):
        assert run.overrides == {k: task[k] for k in study_spec.TASK_PARAMETERS}
        assert run.swept['task'] == task['id'] and \
            run.swept['task_observability'] == task['observability']
    assert parse(data).swept_names()[:2] == ['task', 'task_observability']


@pytest.mark.parametrize('draws, names', [
    ({'parameters': {'v': {'uniform': [[0.0, 1.0], [1.0]]}}},
     ['draws.parameters.v.uniform', 'same length']),
    ({'parameters': {'v': {'uniform': [[0.0, 'x'], [1.0, 2.0]]}}},
     ['draws.parameters.v.uniform[0][1]', 'finite number']),
    ({'parameters': {'v': {'uniform': [[0.0, 3.0], [1.0, 2.0]]}}},
     ['draws.parameters.v.uniform', 'element 1', 'low < high']),
    ({'parameters': {'s': {'integers': [0, 511.82]}}},
     ['draws.parameters.s.integers[1]', 'expected an integer', '511.82']),
    ({'parameters': {'s': {'integers': [5, 4]}}}, ['draws.parameters.s.integers', 'low <= high']),
    ({'mode': 'each', 'parameters': {'s': {'integers': [0, 4]}}}, ['draws.mode', 'per_run']),
    ({'task': {'seed': -1}}, ['draws.task.seed']),
    ({'task': {'seed': 1, 'version': 'workspace-0'}}, ['draws.task.version', 'workspace-0']),
    ({'task': {'seed': 1}, 'parameters': {'start_joints': {'uniform': [[0] * 6, [1] * 6]}}},
     ['draws.parameters.start_joints', 'not both']),
    ({}, ['draws.parameters', 'no parameter']),
])
def test_a_malformed_draw_is_refused_with_its_path(draws, names):
    with pytest.raises(StudyError) as info:
        parse({**BASE, 'draws': {'n': 2, 'seed': 1, **draws}})
    for name in names:
        assert name in str(info.value), str(info.value)


def test_a_draw_a_node_refuses_is_refused_before_any_run_naming_its_path():
    # A float drawn for an integer parameter: the spec is fine, the node's range is not.
    spec = parse(_draws(n=2, feedback_latency_s={'uniform': [-0.2, -0.1]}))
    with pytest.raises(scenario.ScenarioError) as info:
        study.check_spec(spec)
    assert 'feedback_latency_s' in str(info.value)
    assert 'draws.parameters.feedback_latency_s' in str(info.value)


@pytest.mark.parametrize('value', [-1e-05, 1e-05, 2.5e20, 0.1, 3, 'ibvs', True,
                                   [1e-05, -2.0, 0.0], [1, 2], 1.0])
def test_a_value_reaches_a_run_as_drawn(value):
    # What execute_run writes after -p is what the run's parse_override reads back.
    name, parsed = scenario.parse_override(f'x:={study_spec.yaml_value(value)}')
    assert parsed == value and type(parsed) is type(value)
    if isinstance(value, list):
        assert [type(v) for v in parsed] == [type(v) for v in value]


def test_a_task_study_passes_the_nodes_checks():
    study.check_spec(parse({**BASE, 'draws': {'n': 4, 'seed': 0, 'task': {'seed': 2}}}))


def test_a_drawn_float_reaches_the_run_command_as_a_float(tmp_path):
    spec = parse(_draws(n=1, feedback_latency_s={'uniform': [1e-05, 1.1e-05]}))
    run = spec.runs()[0]
    cmd = study.run_command(tmp_path, 'scenario1', {**run.overrides, 'tiny': -1e-05}, 0.3,
                            5.0)
    given = dict(scenario.parse_override(cmd[i + 1]) for i, arg in enumerate(cmd)
                 if arg == '-p')
    assert given == {**run.overrides, 'tiny': -1e-05}
    assert isinstance(given['feedback_latency_s'], float)
