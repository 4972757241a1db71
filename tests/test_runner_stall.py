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
    A frozen lockstep process (SIGSTOP) stalls the run; the runner names the frozen nodes.

    The paper's nodes share the simulator's process (ibvs_bringup.graph): freezing the
    feature node freezes them all, and their /diagnostics heartbeats stop. The stall
    bound leaves each heartbeat more than HEARTBEAT_S old when the runner reports.
    """
    code, out, err = signalled_run(
        ['--stall-s', '6'], lambda log: log.exists() and 'starting at t = 0' in log.read_text(),
        signal.SIGSTOP, 90.0)
    assert code == 4, (out, err)
    assert 'no sim-time progress for 6 s' in err, err
    frozen = err.split('heartbeat stopped: ', 1)[1].split(' (', 1)[0].split(', ')
    assert {'feature_node', 'adaptive_feedback_node', 'joint_controller_node'} <= set(frozen), err
    waits = dict(line.strip().split(': ', 1) for line in err.splitlines()
                 if line.startswith('  ') and ': ' in line)
    assert waits['feature_node'].startswith('HEARTBEAT STOPPED'), err
    assert 'viz_node' not in frozen, err  # its own process goes on
