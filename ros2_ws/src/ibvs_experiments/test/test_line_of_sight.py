"""workspace-3's line of sight: the targets the camera cannot see are refused, no others."""

import json
from pathlib import Path

from ibvs_experiments.line_of_sight import RenderedLineOfSight
from ibvs_model import default_model, task_sampler
import numpy as np
import pytest

BENCHMARK = Path(__file__).parents[1] / 'benchmarks' / 'vsbench-2.json'
#: vsbench-2's targets whose markers the forearm hides or the detector does not find.
HIDDEN = (165, 193, 203, 224, 238, 253)
#: Targets the camera sees though the forearm's capsule (ibvs_model.capsules, radius
#: 0.12 m) crosses a lens's line to P1 at them, and the first three.
SEEN = (0, 1, 2, 162, 184, 380)


@pytest.fixture(scope='module')
def check():
    with RenderedLineOfSight() as los:
        yield los


@pytest.fixture(scope='module')
def targets():
    tasks = json.loads(BENCHMARK.read_text())['tasks']
    return {t['index']: np.asarray(t['target_joints']) for t in tasks}


def test_the_targets_whose_markers_are_hidden_are_refused(check, targets):
    for index in HIDDEN:
        assert check(targets[index]) is not None, f'vsbench-2 task {index}'


def test_targets_the_camera_sees_are_kept(check, targets):
    for index in SEEN:
        assert check(targets[index]) is None, f'vsbench-2 task {index}'


def test_workspace_3_keeps_targets_below_the_one_frame_bound_that_its_own_admits():
    bound = task_sampler.observability_bound(10)
    assert bound == pytest.approx(0.826, abs=1e-3)
    assert task_sampler.observability_bound(1) == pytest.approx(2.61, abs=0.01)
    tasks = task_sampler.tasks(40, 1, version='workspace-3', line_of_sight=lambda q: None)
    weak = [t for t in tasks if t['observability'] < 2.6]
    assert weak and all(t['observability'] >= bound for t in tasks)
    assert all(t['id'].startswith('workspace-3/1/') for t in tasks)
    # workspace-2 refuses each of them: the same draws, the one-frame bound
    for t in weak:
        assert task_sampler.target_check(default_model(),
                                         t['target_joints']) is not None


def test_each_version_takes_its_own_check():
    with pytest.raises(ValueError, match='workspace-3 needs a line_of_sight'):
        task_sampler.tasks(1, 1, version='workspace-3')
    with pytest.raises(ValueError, match='needs a line_of_sight'):
        task_sampler.tasks(1, 1, line_of_sight=lambda q: None)
    with pytest.raises(ValueError, match='version must be one of'):
        task_sampler.tasks(1, 1, version='workspace-9')


def test_the_task_writer_writes_a_workspace_3_set_with_its_definition(tmp_path, capsys):
    from ibvs_experiments import tasks
    out = tmp_path / 'tasks.json'
    assert tasks.main(['-n', '3', '--seed', '1', '--version', 'workspace-3', '-o',
                       str(out)]) == 0
    data = json.loads(out.read_text())
    assert data['definition']['version'] == 'workspace-3'
    assert data['definition']['margins']['min_observability_px_rad'] == \
        task_sampler.observability_bound(10)
    assert [t['id'] for t in data['tasks']] == [f'workspace-3/1/{k}' for k in range(3)]
    assert 'wrote 3 tasks of workspace-3' in capsys.readouterr().out
