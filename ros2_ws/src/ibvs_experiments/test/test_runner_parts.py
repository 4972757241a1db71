"""The runner's parts without a graph: prepare a run, and watch one made of stand-ins."""

from pathlib import Path
import time

from ibvs_bringup.scenario import ScenarioError
from ibvs_bringup.supervision import NodeDied
from ibvs_experiments import runner
import numpy as np
import pytest
import yaml


def test_prepare_checks_and_writes_before_anything_starts(tmp_path):
    run = runner.prepare('scenario1', tmp_path / 'run', {'lambda_0': 6.0}, duration_s=0.25)
    assert run.duration_s == 0.25 and run.params['scenario_name'] == 'scenario1'
    written = yaml.safe_load(Path(run.params_file).read_text())['/**']['ros__parameters']
    assert written['lambda_0'] == 6.0
    assert 'scenario_name' not in written and 'run_duration_s' not in written
    assert run.log_dir.is_dir() and run.bag_path == tmp_path / 'run' / 'bag'
    assert run.target.shape == (4, 4)
    with pytest.raises(ScenarioError):
        runner.prepare('scenario1', tmp_path / 'refused', {'no_such_parameter': 1})
    assert not (tmp_path / 'refused').exists()


class _Monitor:
    """What watch reads of a Monitor: sim time advanced by the executor, a fixed error."""

    def __init__(self, error_m, step_ns):
        self.sim_ns, self.error_m, self.axis_deg = 0, error_m, 0.0
        self.started_wall, self.step_ns = 0.0, step_ns
        self.within_since_ns = None

    def poll(self):
        self.sim_ns += self.step_ns

    update_convergence = runner.Monitor.update_convergence

    def stalled_sim_s(self):
        return self.sim_ns * 1e-9

    def waits(self, procs, since, stopped=None):
        return {'sim_node': 'waiting for /joint_effort_commands'}

    def silent(self, nodes):
        return ()

    def busy_now(self):
        return {}

    def teach_failed(self):
        return None


class _Executor:

    def spin_until_future_complete(self, future, timeout_sec):
        pass


class _Process:

    def __init__(self, code=None, name='lockstep', nodes=('sim_node',)):
        self.name, self.nodes, self.log_path, self.code = name, nodes, '/x', code

    def poll(self):
        return self.code

    def stopped(self):
        return []


def _watch(monitor, procs=(), **kwargs):
    run = runner.Prepared({'scenario_name': 's'}, 0.5, None, None, None, None, None)
    return runner.watch(run, _Executor(), monitor, list(procs), time.monotonic(), lambda _: None,
                        **kwargs)


def test_watch_ends_at_the_time_limit_and_says_whether_it_converged():
    done = _watch(_Monitor(0.9e-3, 100_000_000), [_Process()])
    assert done.converged and done.died is None and done.stalled is None
    assert done.wall_duration_s is not None
    assert not _watch(_Monitor(1.1e-3, 100_000_000)).converged


def test_watch_ends_early_once_the_tool_has_held_still():
    monitor = _Monitor(0.5e-4, 10_000_000)
    assert _watch(monitor, converge_hold_s=0.1).converged
    assert np.isclose(monitor.sim_ns * 1e-9, 0.11)  # 0.1 s held from 0.01 s, not 0.5 s


def test_watch_names_a_node_that_died_and_a_stall():
    died = _watch(_Monitor(0.0, 1), [_Process(code=-9)]).died
    assert isinstance(died, NodeDied) and died.node == 'lockstep' and died.returncode == -9
    stalled = _watch(_Monitor(0.0, 0), stall_s=0.0).stalled
    assert isinstance(stalled, runner.RunStalled)
    assert stalled.waits == {'sim_node': 'waiting for /joint_effort_commands'}


def test_watch_ends_at_once_on_a_failed_teach():
    monitor = _Monitor(0.0, 0)  # sim time stands: the frames wait for the target features
    monitor.teach_failed = lambda: ('feature_node', 'marker missing: marker 1 (P1)')
    done = _watch(monitor, stall_s=3600.0)
    assert done.stalled is None and isinstance(done.teach_failed, runner.TeachFailed)
    assert done.teach_failed.node == 'feature_node' and 'marker 1 (P1)' in str(done.teach_failed)


def test_watch_goes_on_without_an_optional_viewer_once_the_simulator_runs():
    """SIGKILL of viz_node, a viewer nothing waits for, does not abort the run."""
    said = []
    run = runner.Prepared({'scenario_name': 's'}, 0.5, None, None, None, None, None)
    viewer = _Process(code=-9, name='viz_node', nodes=('viz_node',))
    done = runner.watch(run, _Executor(), _Monitor(0.0, 100_000_000), [viewer, _Process()],
                        time.monotonic(), said.append)
    assert done.died is None and done.lost == {'viz_node': -9}
    assert any('the optional process viz_node exited with code -9' in s for s in said)
    # Before the simulator's first step it waits for the viewer's subscriptions: fatal then.
    monitor = _Monitor(0.0, 100_000_000)
    monitor.started_wall = None
    died = runner.watch(run, _Executor(), monitor, [viewer], time.monotonic(),
                        said.append).died
    assert isinstance(died, NodeDied) and died.node == 'viz_node'
    assert not runner.optional(_Process()) and runner.optional(viewer)


def test_the_metrics_are_handed_over_before_the_figures_are_drawn(monkeypatch, tmp_path):
    # ibvs run prints the metrics as soon as they are written (start to metrics);
    # matplotlib's seconds come after.
    order = []
    run_data = type('Run', (), {'params': {}, 'run_info': {}, 'joints': ([],),
                                'joint_limits': None})()
    from ibvs_analysis import plots, results
    monkeypatch.setattr(results.analysis, 'analyse_bag',
                        lambda bag: (run_data, {'sim_duration_s': 1.0}))
    monkeypatch.setattr(results, 'target_features', lambda run: None)
    monkeypatch.setattr(plots, 'write_all', lambda *a: order.append('figures'))

    def on_metrics(metrics):
        assert (tmp_path / 'metrics.json').is_file()
        order.append(('metrics', metrics['real_time_factor']))

    results.write_results(tmp_path / 'bag', tmp_path, 2.0, True, on_metrics)
    assert order == [('metrics', 0.5), 'figures']
    order.clear()
    results.write_results(tmp_path / 'bag', tmp_path, 2.0, False, on_metrics)
    assert order == [('metrics', 0.5)]


class _StartingMonitor(_Monitor):
    """No /clock for the first 5 looks, then sim time stands for 5 looks, then moves."""

    def __init__(self):
        super().__init__(1.0, 0)
        self.started_wall, self.looks = None, 0

    def poll(self):
        self.looks += 1
        if self.looks > 5:
            self.started_wall = 0.0
        if self.looks > 10:
            self.sim_ns += 100_000_000


def test_progress_says_starting_once_then_prints_only_when_sim_time_moved(monkeypatch):
    # make demo printed 'sim 0.000/3.00 s ... - mm' seven times while the nodes started.
    from ibvs_bringup import launcher
    monkeypatch.setattr(launcher, 'PROGRESS_S', 0.0)
    lines = []
    run = runner.Prepared({'scenario_name': 's'}, 0.5, None, None, None, None, None)
    runner.watch(run, _Executor(), _StartingMonitor(), [], time.monotonic(), lines.append)
    assert lines[0] == ('  [s] starting: the nodes start up; the simulator takes step 0 once '
                        'every reader of it is there')
    sims = [line.split('sim ')[1].split('/')[0].strip() for line in lines[1:]]
    assert sims == ['0.000', '0.100', '0.200', '0.300', '0.400', '0.500'], lines
