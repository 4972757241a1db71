"""No silent hang: a stall in sim time ends the run with a message naming who waits for what."""

import os
import signal
import subprocess
import sys
import time


def test_runner_refuses_a_graph_without_images(installed_workspace, tmp_path):
    """``-p publish_images:=false`` cannot advance sim time: refused before any node starts."""
    proc = subprocess.run(
        [sys.executable, '-m', 'ibvs_bringup.cli', 'run', 'scenario1', '-o', str(tmp_path),
         '--duration', '0.5', '-p', 'publish_images:=false'],
        capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert 'publish_images' in proc.stderr and '/ibvs/q_feedback' in proc.stderr
    assert not (tmp_path / 'logs' / 'sim_node.log').exists()  # nothing was started


def test_runner_reports_a_stall_and_who_waits(installed_workspace, tmp_path, proc_tools):
    """A frozen feature node (SIGSTOP) stalls the lockstep; the runner names the waits."""
    cmd = [sys.executable, '-m', 'ibvs_bringup.cli', 'run', 'scenario1', '-o', str(tmp_path),
           '--duration', '30', '--stall-s', '3']
    runner = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    victim = None
    seen = set()
    try:
        deadline = time.monotonic() + 120.0
        while time.monotonic() < deadline and victim is None:
            assert runner.poll() is None, runner.communicate()
            kids = proc_tools.descendants(runner.pid)
            seen.update(kids)
            names = {pid: proc_tools.cmdline(pid) for pid in kids}
            log = tmp_path / 'logs' / 'sim_node.log'
            if log.exists() and 'starting at t = 0' in log.read_text():
                victim = next(pid for pid, c in names.items() if 'feature_node' in c)
                os.kill(victim, signal.SIGSTOP)
            time.sleep(0.2)
        assert victim is not None, 'the run never got under way'
        out, err = runner.communicate(timeout=90.0)
    finally:
        if runner.poll() is None:
            runner.kill()
            runner.communicate()
    assert runner.returncode == 4, (out, err)
    assert 'no sim-time progress for 3 s' in err, err
    waits = dict(line.strip().split(': ', 1) for line in err.splitlines()
                 if line.startswith('  ') and ': ' in line)
    # The simulator waits for the joint controller, which waits for the feedback of a frame
    # that the frozen feature node never delivers.
    assert '/joint_effort_commands' in waits['sim_node'], err
    assert '/ibvs/q_feedback of frame' in waits['joint_controller_node'], err
    assert 'said nothing about waiting' in waits['feature_node'], err
    seen.update(proc_tools.descendants(runner.pid))
    leftovers = [pid for pid in seen if proc_tools.alive(pid)]
    assert not leftovers, [proc_tools.cmdline(p) for p in leftovers]
