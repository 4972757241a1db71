"""
The runner's own faults: its stop is not the graph's; killed, what it leaves is cleaned up.

Ctrl-Z of ``ibvs run`` (SIGTSTP, then ``fg``: SIGCONT) stops its graph with it, and the run
completes as if never stopped; a runner stopped alone (SIGSTOP) tells its stop from the
graph's and hears the graph again. Killed before sim time advanced, it leaves no shared
memory once ``ibvs analyse`` has run, and no traceback.
"""

import os
import signal
import subprocess
import sys
import time

from ibvs_bringup import shm
from ibvs_common import contract
from ibvs_testing.proc_tools import ProcTools
import numpy as np
import pytest
from rosbags.highlevel import AnyReader


def _started(log):
    return log.exists() and 'starting at t = 0' in log.read_text()


def _until(condition, runner, what, deadline_s=120.0):
    deadline = time.monotonic() + deadline_s  # a hang guard
    while not condition():
        assert runner.poll() is None, runner.communicate()
        assert time.monotonic() < deadline, what
        time.sleep(0.05)


def _stopped_run(tmp_path, stop, stop_s):
    """
    Run scenario 1 for 3 s of sim time, stopping the runner with ``stop`` for ``stop_s``.

    The stop comes once the simulator has taken its first step; ``stop_s`` (wall time) is
    the stop itself, not a budget. The stall limit stays its default. Return (exit code,
    stdout, stderr).
    """
    cmd = [sys.executable, '-m', 'ibvs_experiments.cli', 'run', 'scenario1', '-o',
           str(tmp_path), '--duration', '3', '--no-figures']
    runner = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _until(lambda: _started(tmp_path / 'logs' / 'lockstep.log'), runner,
               'the run never got under way')
        os.kill(runner.pid, stop)
        time.sleep(stop_s)
        os.kill(runner.pid, signal.SIGCONT)  # what `fg` sends
        out, err = runner.communicate(timeout=300)
    finally:
        if runner.poll() is None:
            os.kill(runner.pid, signal.SIGCONT)
            runner.kill()
            runner.communicate()
    return runner.returncode, out, err


def test_ctrl_z_stops_the_graph_with_the_runner_and_the_run_completes_whole(
        installed_workspace, tmp_path):
    # Ctrl-Z sends SIGTSTP to the terminal's foreground job: the runner alone, its nodes
    # being in process groups of their own. Stopped well beyond the heartbeat bound (3 s).
    code, out, err = _stopped_run(tmp_path, signal.SIGTSTP, 10.0)
    assert code == 0, (out, err)
    assert 'stopped by Ctrl-Z with its graph' in out, out
    assert (tmp_path / 'metrics.json').is_file()
    # The graph did not run on without its recorder: every /clock of the run is in the bag.
    with AnyReader([tmp_path / 'bag']) as reader:
        clocks = [t for c, t, _ in reader.messages() if c.topic == contract.CLOCK]
    assert clocks and clocks[-1] >= 2_900_000_000, clocks[-3:]
    assert max(np.diff(clocks)) <= 100_000_000, 'a /clock is missing'


# Known to fail now and then on a loaded 2-core machine: continued after SIGSTOP, the runner
# sometimes never hears the graph's /clock again (the graph runs on past the run's end, the
# runner reports a stall). Not yet understood; one rerun meanwhile (docs/testing.md).
@pytest.mark.flaky(reruns=1)
def test_a_runner_stopped_alone_completes_its_run(installed_workspace, tmp_path):
    # SIGSTOP of the runner only (kill -STOP, a debugger): the graph runs on meanwhile, and
    # the runner, continued, hears it again (its participant has no shared memory).
    code, out, err = _stopped_run(tmp_path, signal.SIGSTOP, 8.0)
    assert code == 0, (out, err)
    assert 'the runner itself did not run for ' in out and 'stopped alone' in out, out
    assert (tmp_path / 'metrics.json').is_file()


def test_a_runner_killed_before_sim_time_leaves_no_shared_memory_and_no_traceback(
        installed_workspace, tmp_path):
    before = shm.names()
    cmd = [sys.executable, '-m', 'ibvs_experiments.cli', 'run', 'scenario1', '-o',
           str(tmp_path), '--duration', '3', '--no-figures']
    runner = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    seen = set()
    try:
        def nodes_up():
            seen.update(ProcTools.descendants(runner.pid))
            return (tmp_path / 'logs' / 'lockstep.log').exists()
        _until(nodes_up, runner, 'the nodes never started')
        runner.kill()
        runner.communicate(timeout=60)
    finally:
        if runner.poll() is None:
            runner.kill()
            runner.communicate()
    deadline = time.monotonic() + 30.0  # its nodes die with it (PR_SET_PDEATHSIG)
    while any(ProcTools.alive(p) for p in seen):
        assert time.monotonic() < deadline, [ProcTools.cmdline(p) for p in seen]
        time.sleep(0.05)
    dead = shm.zombies(new_since=before, min_age_s=0.0)
    assert dead, 'the killed run left no shared memory (the runner has its own): nothing tested'
    done = subprocess.run([sys.executable, '-m', 'ibvs_experiments.cli', 'analyse',
                           str(tmp_path / 'bag')], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode in (0, 2), (done.stdout, done.stderr)
    assert 'Traceback' not in done.stderr, done.stderr
    if done.returncode == 2:
        assert done.stderr.startswith('error: nothing to analyse: '), done.stderr
    assert [p for p in dead if p.exists()] == [], 'shared memory of the killed run is left'
