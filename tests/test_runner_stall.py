"""No silent hang: a stall in sim time ends the run with a message naming who waits for what."""

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
    cause, and each of its nodes as stopped with it (issue 39: it called each of them frozen
    and named no process). The viewers' node, in a process of its own, keeps its heartbeat.
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
