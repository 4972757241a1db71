"""
The runner's own faults: its stop is not the graph's; killed, what it leaves is cleaned up.

Ctrl-Z of ``ibvs run`` (SIGSTOP, then ``fg``: SIGCONT) ended a good run with exit code 4,
every node's heartbeat called stopped. After SIGKILL of the runner before sim time
advanced, ``ibvs analyse`` ended with a traceback.
"""

import os
import signal
import subprocess
import sys
import time

from ibvs_bringup import shm
from ibvs_testing.proc_tools import ProcTools
import pytest


def _started(log):
    return log.exists() and 'starting at t = 0' in log.read_text()


def _until(condition, runner, what, deadline_s=120.0):
    deadline = time.monotonic() + deadline_s  # a hang guard
    while not condition():
        assert runner.poll() is None, runner.communicate()
        assert time.monotonic() < deadline, what
        time.sleep(0.05)


@pytest.mark.xfail(strict=False, reason=(
    'known: under make test\'s load the run stopped for 8 s has ended as "graph stalled" '
    '(exit 4) in two of four fresh-clone runs; it passes alone'))
def test_a_stopped_and_continued_runner_completes_its_run(installed_workspace, tmp_path):
    # Stopped well beyond the heartbeat bound (3 s), which called every node stopped. The
    # stall limit stays its default: on a loaded machine the graph, which kept running while
    # the runner was stopped, may take seconds to drain its backlog to the runner (the
    # runner's restart of its heartbeat clocks: test_runner_own_pause).
    cmd = [sys.executable, '-m', 'ibvs_experiments.cli', 'run', 'scenario1', '-o',
           str(tmp_path), '--duration', '3', '--no-figures']
    runner = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        _until(lambda: _started(tmp_path / 'logs' / 'lockstep.log'), runner,
               'the run never got under way')
        os.kill(runner.pid, signal.SIGSTOP)
        time.sleep(8.0)  # the stop itself, not a budget
        os.kill(runner.pid, signal.SIGCONT)
        out, err = runner.communicate(timeout=300)
    finally:
        if runner.poll() is None:
            os.kill(runner.pid, signal.SIGCONT)
            runner.kill()
            runner.communicate()
    assert runner.returncode == 0, (out, err)
    assert 'the runner itself did not run for ' in out, out
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
