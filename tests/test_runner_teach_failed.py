"""
A taught target the camera cannot see: the run ends at once as a failed teach.

vsbench-2's task 165 places the tool where the arm's upper arm hides its markers from the
camera: the feature node measures nothing on the teach pair. Run as a study runs a graph
run (:func:`ibvs_experiments.study.run_command`, an ``ibvs run`` with the default stall
bound), it ends with its own exit code, said as a failed teach, and the study files it
under 'teach failed', not as a stalled graph.
"""

import os

from ibvs_analysis import study_table
from ibvs_experiments import runner, study, vsbench, vsbench_tasks
import pytest

#: The task whose markers are hidden at the target (vsbench-2, the paper's law).
TASK = 165


@pytest.mark.slow
def test_a_teach_that_measures_no_target_ends_the_run_as_a_failed_teach(
        installed_workspace, tmp_path):
    bench = vsbench_tasks.load('vsbench-2')
    task = bench['tasks'][TASK]
    assert task['index'] == TASK
    overrides = vsbench.graph_overrides(task, 'paper', bench['conditions'],
                                        bench['graph']['resolution'])
    assert overrides['target_features_source'] == 'taught'
    run_dir = tmp_path / 'run'
    run_dir.mkdir()
    cmd = study.run_command(run_dir, bench['graph']['scenario'], overrides,
                            bench['duration_s'], runner.STALL_S)
    record = study.attempt_until_settled(
        cmd, dict(os.environ, PYTHONUNBUFFERED='1'), run_dir)
    log = (run_dir / 'runner.log').read_text()
    assert record['exit_code'] == runner.EXIT_TEACH_FAILED, log
    assert 'run failed: teach failed at sim time 0.000 s: feature_node' in log, log
    assert 'stalled' not in log, log
    assert study_table.miss_category(record) == 'teach failed', record['reason']
