"""Fixtures of the cross-package tests: the shared ones, the installed workspace, a hurt run."""

import os
import signal
import subprocess
import sys
import time

from ibvs_testing.fixtures import context, proc_tools  # noqa: F401 (the shared fixtures)
from ibvs_testing.proc_tools import ProcTools
import pytest


@pytest.fixture(scope='session')
def installed_workspace():
    """Skip unless the workspace is built and sourced (make test does both)."""
    prefix = os.environ.get('AMENT_PREFIX_PATH', '')
    if not prefix:
        pytest.skip('AMENT_PREFIX_PATH is empty: run through make test (colcon build + source)')
    return prefix.split(os.pathsep)[0]


@pytest.fixture
def signalled_run(tmp_path):
    """
    Return run(args, under_way, sig, timeout_s, settle_s=0): a scenario 1 run that is hurt.

    ``ibvs run scenario1`` (30 s of sim time, more options in ``args``) writes to
    ``tmp_path``; once ``under_way(path of sim_node's log)`` holds (within 120 s) and
    ``settle_s`` more seconds have passed, the process of ``victim`` (a node's name in its
    command line, default feature_node; ``'runner'``: the runner itself) gets the signal
    ``sig``. ``sigint_ignored``: the runner starts with SIGINT ignored, as a shell starts
    ``nohup ... &``. run waits up to ``timeout_s`` for the runner to end, checks that no
    process of the run is left, and returns (exit code, stdout, stderr).
    """
    def run(args, under_way, sig, timeout_s, settle_s=0.0, victim='feature_node',
            sigint_ignored=False):
        cmd = [sys.executable, '-m', 'ibvs_experiments.cli', 'run', 'scenario1', '-o',
               str(tmp_path), '--duration', '30', *args]
        ignore = (lambda: signal.signal(signal.SIGINT, signal.SIG_IGN)) if sigint_ignored \
            else None
        runner = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                  text=True, preexec_fn=ignore)
        log = tmp_path / 'logs' / 'lockstep.log'  # the simulator's process
        killed = None
        seen = set()
        try:
            deadline = time.monotonic() + 120.0
            while time.monotonic() < deadline and killed is None:
                assert runner.poll() is None, runner.communicate()
                seen.update(ProcTools.descendants(runner.pid))
                if under_way(log):
                    time.sleep(settle_s)
                    pid = runner.pid if victim == 'runner' else next(
                        pid for pid in ProcTools.descendants(runner.pid)
                        if victim in ProcTools.cmdline(pid))
                    os.kill(pid, sig)
                    killed = pid
                time.sleep(0.2)
            assert killed is not None, 'the run never got under way'
            out, err = runner.communicate(timeout=timeout_s)
        finally:
            if runner.poll() is None:
                runner.kill()
                runner.communicate()
        seen.update(ProcTools.descendants(runner.pid))
        leftovers = [pid for pid in seen if ProcTools.alive(pid)]
        assert not leftovers, [ProcTools.cmdline(p) for p in leftovers]
        return runner.returncode, out, err
    return run
