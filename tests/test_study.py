"""A study through local Ray: short runs over two parameters, one failing, resumed from cache."""

import csv
import json
import os
from pathlib import Path
import signal
import statistics
import subprocess
import sys
import time

from ibvs_experiments import study, study_spec
import pytest
import yaml

#: Domain IDs of the study's runs: clear of the 1-100 that the suite derives from PIDs.
DOMAINS = study.DOMAIN_IDS  # IBVS_ROS_DOMAINS, within the safe 0-101


#: What the studies' runs render: under test is the study (Ray, domains, cache, failures,
#: Ctrl-C), not the images, so the cheapest frames that still close the loop (VGA).
CHEAP_FRAMES = {'resolution': 'VGA'}


def grid_spec(directory, name, duration_s, grid):
    """Write the scenario 1 grid study ``name`` as ``directory``/``name``.yaml; return its path."""
    path = directory / f'{name}.yaml'
    path.write_text(yaml.safe_dump({'name': name, 'scenario': 'scenario1',
                                    'duration_s': duration_s, 'parameters': CHEAP_FRAMES,
                                    'grid': grid}, sort_keys=False))
    return path


def _ray_processes(proc_tools):
    """Return the PIDs of Ray's own daemons (raylet, gcs_server) below this process."""
    return [pid for pid in proc_tools.descendants(os.getpid())
            if any(name in proc_tools.cmdline(pid) for name in ('raylet', 'gcs_server'))]


@pytest.mark.slow
def test_grid_study_records_a_failure_and_resumes_from_cache(
        installed_workspace, tmp_path, proc_tools):
    # A robot with L2 and L4 at 30 % cannot reach scenario 1's start pose: the simulator
    # refuses at start (exit 2; every rule between parameters is refused before any run,
    # so a run that fails has to fail in its nodes), the other grid point runs. Two
    # products (their union) sweep both parameters with one run that fails and one that
    # runs, at the same time.
    spec = study_spec.load(grid_spec(tmp_path, 'grid', 0.3,
                                     [{'l2_scale': [1.0], 'l4_scale': [1.0]},
                                      {'l2_scale': [0.3], 'l4_scale': [0.3]}]))
    out = tmp_path / 'studies'
    # A job beside the runs (as the report's model-only sweeps), and each record as it comes.
    answers, seen = [], []
    job = study.Job('mean', statistics.fmean, ([1.0, 2.0],), answers.append)
    records = study.run_studies([spec], out, parallel=2, domains=DOMAINS, jobs=[job],
                                on_record=seen.append)['grid']
    assert answers == [1.5]
    assert sorted(r['index'] for r in seen) == [0, 1] and all('status' in r for r in seen)

    assert [r['swept'] for r in records] == [
        {'l2_scale': 1.0, 'l4_scale': 1.0}, {'l2_scale': 0.3, 'l4_scale': 0.3}]
    status = [r['status'] for r in records]
    assert status == ['ok', 'failed'], [r.get('reason') for r in records]
    failed = records[1]
    assert 'unreachable' in failed['reason'] and 'exited with code 2' in failed['reason']
    assert (Path(failed['run_dir']) / 'runner.log').is_file()
    # A study's runs write metrics and bag, not their own figures (run_figures: false).
    assert (Path(records[0]['run_dir']) / 'metrics.json').is_file()
    assert not list(Path(records[0]['run_dir']).glob('*.png'))
    assert any((Path(failed['run_dir']) / 'logs').glob('*.log'))
    assert len({r['domain_id'] for r in records}) >= 1
    assert all(DOMAINS[0] <= r['domain_id'] <= DOMAINS[1] for r in records)

    with open(out / 'grid' / 'table.csv') as f:
        rows = list(csv.DictReader(f))
    assert [row['status'] for row in rows] == status
    assert [float(row['l2_scale']) for row in rows] == [1.0, 0.3]
    assert [float(row['l4_scale']) for row in rows] == [1.0, 0.3]
    assert float(rows[0]['final_position_error_m']) == \
        records[0]['metrics']['final_position_error_m']
    assert float(rows[0]['wall_s']) > 0.0
    assert rows[1]['final_position_error_m'] == '' and 'unreachable' in rows[1]['reason']
    table = (out / 'grid' / 'table.md').read_text()
    assert table.count('| failed |') == 1 and table.count('| ok |') == 1
    for figure in ('error_vs_l2_scale.png', 'error_vs_l4_scale.png', 'success_rate.png'):
        assert (out / 'grid' / figure).stat().st_size > 0
    assert not _ray_processes(proc_tools)

    # Again: nothing runs, every record (the failure included) comes from the cache.
    stamps = {r['run_dir']: (Path(r['run_dir']) / 'run.json').stat().st_mtime_ns
              for r in records}
    again = study.run_studies([spec], out, parallel=2, domains=DOMAINS, jobs=[job],
                              on_record=seen.append)['grid']
    assert all(r['cached'] for r in again)
    assert answers == [1.5, 1.5] and len(seen) == 4  # the job in this process, no Ray
    assert [r['status'] for r in again] == status
    assert [r.get('metrics') for r in again] == [r.get('metrics') for r in records]
    assert stamps == {r['run_dir']: (Path(r['run_dir']) / 'run.json').stat().st_mtime_ns
                      for r in again}
    # Retrying failures plans that one alone (run_studies runs what plan returns, as above;
    # running it again here would cost a Ray start and a run, and test nothing more).
    planned, todo = study.plan([spec], out, retry_failed=True)
    assert [r.get('cached', False) for r in planned['grid']] == [True, False]
    assert [record['key'] for _, record in todo] == [failed['key']]
    assert json.loads((Path(failed['run_dir']) / 'run.json').read_text())['status'] == \
        'failed'


def _as_from_a_terminal():
    """
    Child-side: SIGINT unblocked and at its default, as a terminal's shell starts a command.

    A blocked or ignored signal survives exec, and the pytest worker that starts the study
    has run other tests' rclpy contexts and signal handling before: under ``make test``
    the study then never saw the SIGINT (seen: it ran to the end and exited 0).
    """
    signal.pthread_sigmask(signal.SIG_UNBLOCK, [signal.SIGINT])
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.slow
def test_ctrl_c_stops_every_run_leaves_nothing_and_keeps_finished_runs(
        installed_workspace, tmp_path, proc_tools):
    """SIGINT to the study's process group, as a terminal's Ctrl-C sends it, mid-run."""
    spec_path = grid_spec(tmp_path, 'two', 0.2, {'l2_scale': [1.0, 0.9, 0.8]})
    out = tmp_path / 'studies'
    cmd = [sys.executable, '-m', 'ibvs_experiments.cli', 'study', str(spec_path), '-o', str(out),
           '--parallel', '1', '--domains', f'{DOMAINS[0]}-{DOMAINS[1]}']
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True, preexec_fn=_as_from_a_terminal)
    seen = set()
    try:
        deadline = time.monotonic() + 600.0
        interrupted = False
        while time.monotonic() < deadline and not interrupted:
            assert proc.poll() is None, proc.communicate()
            seen.update(proc_tools.descendants(proc.pid))
            finished = list(out.glob('two/runs/*/run.json'))
            running = [p for p in out.glob('two/runs/*/logs/lockstep.log')
                       if not (p.parents[1] / 'run.json').exists()]
            if finished and running:
                time.sleep(1.0)
                seen.update(proc_tools.descendants(proc.pid))
                os.killpg(proc.pid, signal.SIGINT)
                interrupted = True
            time.sleep(0.2)
        assert interrupted, 'the study never had a finished and a running run'
        output, _ = proc.communicate(timeout=120.0)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    assert proc.returncode == 130, (output, 'this process: SIGINT',
                                    signal.getsignal(signal.SIGINT), 'blocked',
                                    signal.pthread_sigmask(signal.SIG_BLOCK, []))
    assert 'interrupted' in output
    leftovers = [pid for pid in seen if proc_tools.alive(pid)]
    assert not leftovers, [proc_tools.cmdline(p) for p in leftovers]
    done = [json.loads(p.read_text()) for p in out.glob('two/runs/*/run.json')]
    assert done and all(r['status'] == 'ok' for r in done)
    # Started again, the finished runs come from the cache and only the others would run.
    records, todo = study.plan([study_spec.load(spec_path)], out)
    assert {r['key'] for r in records['two'] if r.get('cached')} == {r['key'] for r in done}
    assert len(todo) == 3 - len(done)


@pytest.mark.slow
def test_a_study_of_drawn_tasks_runs_each_task_with_its_values_as_drawn(
        installed_workspace, tmp_path):
    # Two runs, each its own draw (per_run): a workspace task, an integer seed and a vector
    # of tiny floats (1e-05 is a string to YAML 1.1 unless written as a float).
    path = tmp_path / 'tasks.yaml'
    path.write_text(yaml.safe_dump({
        'name': 'tasks', 'scenario': 'scenario1', 'duration_s': 0.3,
        'parameters': CHEAP_FRAMES,
        'draws': {'n': 2, 'seed': 4, 'mode': 'per_run', 'task': {'seed': 3},
                  'parameters': {
                      'camera_seed': {'integers': [0, 1000]},
                      'camera_pose_error_xyz_m': {'uniform': [[-2e-05] * 3, [-1e-05] * 3]}}}},
        sort_keys=False))
    spec = study_spec.load(path)
    out = tmp_path / 'studies'
    records = study.run_studies([spec], out, parallel=2, domains=DOMAINS)['tasks']
    assert [r['status'] for r in records] == ['ok', 'ok'], [r.get('reason') for r in records]
    for record, run in zip(records, spec.runs()):
        assert record['niceness'] == study.WORKER_NICENESS
        given = yaml.safe_load((Path(record['run_dir']) / 'params.yaml').read_text())
        given = given['/**']['ros__parameters']
        for name in ('start_joints', 'target_position', 'target_rotation', 'camera_seed',
                     'camera_pose_error_xyz_m'):
            assert given[name] == run.overrides[name], name
        assert all(isinstance(v, float) for v in given['camera_pose_error_xyz_m'])
        assert isinstance(given['camera_seed'], int)
        # The run started at the task's start: its initial error is the task's.
        start_error = record['metrics']['initial_position_error_m']
        assert start_error > 0.02
    with open(out / 'tasks' / 'table.csv') as f:
        rows = list(csv.DictReader(f))
    assert [row['task'] for row in rows] == [r['swept']['task'] for r in records]
    assert all(float(row['task_observability']) > 0 for row in rows)
    assert all(row['miss_reason'] in ('', 'timed out') for row in rows)  # 0.3 s: no success
    assert not (out / 'tasks' / 'error_vs_camera_seed.png').exists()
    assert (out / 'tasks' / 'error_vs_task_observability.png').stat().st_size > 0
