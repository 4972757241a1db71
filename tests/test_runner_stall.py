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
    """A frozen feature node (SIGSTOP) stalls the lockstep; the runner names the waits."""
    code, out, err = signalled_run(
        ['--stall-s', '3'], lambda log: log.exists() and 'starting at t = 0' in log.read_text(),
        signal.SIGSTOP, 90.0)
    assert code == 4, (out, err)
    assert 'no sim-time progress for 3 s' in err, err
    waits = dict(line.strip().split(': ', 1) for line in err.splitlines()
                 if line.startswith('  ') and ': ' in line)
    # The simulator waits for the joint controller, which waits for the feedback of a frame
    # that the frozen feature node never delivers.
    assert '/joint_effort_commands' in waits['sim_node'], err
    assert '/ibvs/q_feedback of frame' in waits['joint_controller_node'], err
    assert 'said nothing about waiting' in waits['feature_node'], err
