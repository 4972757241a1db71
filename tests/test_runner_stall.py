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
    A frozen lockstep process (SIGSTOP) stalls the run; the runner ends it and names each node.

    The paper's nodes share the simulator's process (ibvs_bringup.graph): freezing the
    feature node freezes them all. None of them can say what it waits for; each is named
    as frozen (its /diagnostics heartbeat stopped) or, if no heartbeat of it had come yet,
    as silent; the viewers' node, in a process of its own, keeps its heartbeat.
    """
    code, out, err = signalled_run(
        ['--stall-s', '6'], lambda log: log.exists() and 'starting at t = 0' in log.read_text(),
        signal.SIGSTOP, 90.0)
    assert code == 4, (out, err)
    assert 'no sim-time progress for 6 s' in err, err
    waits = dict(line.strip().split(': ', 1) for line in err.splitlines()
                 if line.startswith('  ') and ': ' in line)
    for node in ('feature_node', 'adaptive_feedback_node', 'feedforward_node',
                 'joint_controller_node', 'sim_node'):
        assert waits[node].startswith('HEARTBEAT STOPPED') or \
            waits[node].startswith('said nothing about waiting'), err
    # (A node whose first heartbeat had not reached the runner before the stop is silent.)
    # Its own process goes on: what it says depends on how far step 0 got before the stop.
    assert not waits['viz_node'].startswith('HEARTBEAT STOPPED'), err
