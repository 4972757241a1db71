"""No silent hang: a stall in sim time ends the run with a message naming who waits for what."""

import os
import signal
import subprocess
import sys


def test_runner_refuses_a_graph_without_images(installed_workspace, tmp_path):
    """``-p publish_images:=false`` cannot advance sim time: refused before any node starts."""
    proc = subprocess.run(
        [sys.executable, '-m', 'ibvs_experiments.cli', 'run', 'scenario1', '-o', str(tmp_path),
         '--duration', '0.5', '-p', 'publish_images:=false'],
        capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert 'publish_images' in proc.stderr and '/ibvs/q_feedback' in proc.stderr
    assert not (tmp_path / 'logs' / 'lockstep.log').exists()  # nothing was started


def test_runner_reports_a_stall_and_who_waits(installed_workspace, signalled_run):
    """
    A frozen lockstep process (SIGSTOP) stalls the run; the runner names it as stopped.

    The paper's nodes share the simulator's process (ibvs_bringup.graph): freezing the
    feature node freezes them all. None of them can say anything, not even its process's
    watchdog; the runner sees the process stopped (state T in /proc) and names it as the
    cause, and each of its nodes as stopped with it (not each of them as frozen with no
    process named). The viewers' node, in a process of its own, keeps its heartbeat.
    """
    code, out, err = signalled_run(
        ['--stall-s', '6'], lambda log: log.exists() and 'starting at t = 0' in log.read_text(),
        signal.SIGSTOP, 90.0)
    assert code == 4, (out, err)
    assert 'no sim-time progress for 6 s' in err, err
    assert 'cause: process lockstep is stopped (pid ' in err, err
    assert 'heartbeat stopped' not in err.splitlines()[0], err
    waits = dict(line.strip().split(': ', 1) for line in err.splitlines()
                 if line.startswith('  ') and ': ' in line)
    for node in ('feature_node', 'adaptive_feedback_node', 'feedforward_node',
                 'joint_controller_node', 'sim_node'):
        assert waits[node].startswith('STOPPED: its process lockstep is stopped'), err
    # Its own process goes on: what it says depends on how far step 0 got before the stop.
    assert not waits['viz_node'].startswith(('HEARTBEAT STOPPED', 'STOPPED')), err


#: A test hook (``sitecustomize``, imported by every Python process of the run): the feature
#: node's fourth camera_info callback, at the run's first frame, runs busy for 8 s, as
#: a detection of a noisy frame can without the detector's budget.
BUSY_HOOK = """
import importlib.abc
import importlib.util
import sys
import time


class _Hook(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name != 'ibvs_vision.feature_node':
            return None
        sys.meta_path.remove(self)
        spec = importlib.util.find_spec(name)
        execute = spec.loader.exec_module

        def exec_module(module):
            execute(module)
            original, calls = module.FeatureNode._on_image, []

            def _on_image(self, *args):
                calls.append(1)
                if len(calls) == 4:
                    end = time.monotonic() + 8.0
                    while time.monotonic() < end:
                        sum(range(1000))
                return original(self, *args)
            module.FeatureNode._on_image = _on_image
        spec.loader.exec_module = exec_module
        return spec


sys.meta_path.insert(0, _Hook())
"""


def test_runner_names_the_busy_node_not_those_behind_it(installed_workspace, tmp_path):
    """
    A callback busy for seconds is named as the cause; its process's other nodes wait.

    A noisy frame's detection can hold the feature node for seconds; the report must not
    call all five nodes of its process frozen. Here a test hook makes one of its callbacks
    busy for 8 s (not a real detection); the run stalls after 4 s.
    """
    hook = tmp_path / 'hook'
    hook.mkdir()
    (hook / 'sitecustomize.py').write_text(BUSY_HOOK)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(hook)] + [p for p in os.environ.get('PYTHONPATH', '').split(os.pathsep) if p]))
    proc = subprocess.run(
        [sys.executable, '-m', 'ibvs_experiments.cli', 'run', 'scenario1', '-o',
         str(tmp_path / 'run'), '--duration', '5', '--no-figures', '--stall-s', '4'],
        capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 4, (proc.stdout, proc.stderr)
    head = next(line for line in proc.stderr.splitlines() if line.startswith('run stalled'))
    assert 'cause: busy in feature_node FeatureNode._on_image for ' in head, proc.stderr
    assert 'heartbeat stopped' not in head, proc.stderr
    waits = dict(line.strip().split(': ', 1) for line in proc.stderr.splitlines()
                 if line.startswith('  ') and ': ' in line)
    assert waits['feature_node'].startswith('BUSY: busy in feature_node'), proc.stderr
    for node in ('adaptive_feedback_node', 'feedforward_node', 'joint_controller_node',
                 'sim_node'):
        assert waits[node].startswith('waits behind feature_node (the process lockstep'), \
            proc.stderr
