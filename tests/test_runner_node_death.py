"""Killing a node mid-run: the runner stops, names the node and its exit code, leaves nothing."""

import os
import signal
import subprocess
import sys
import time


def test_runner_reports_a_dead_node_and_leaves_no_process(
        installed_workspace, tmp_path, proc_tools):
    cmd = [sys.executable, '-m', 'ibvs_bringup.cli', 'run', 'scenario1', '-o', str(tmp_path),
           '--duration', '30']
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
            # Wait until the simulator runs, so the run is really under way.
            if any('sim_node' in c for c in names.values()) and \
                    (tmp_path / 'logs' / 'sim_node.log').exists():
                time.sleep(2.0)  # let the graph take a few steps
                victim = next(pid for pid, c in names.items() if 'feature_node' in c)
                os.kill(victim, signal.SIGKILL)
            time.sleep(0.2)
        assert victim is not None, 'the run never got under way'
        out, err = runner.communicate(timeout=60.0)
    finally:
        if runner.poll() is None:
            runner.kill()
            runner.communicate()
    assert runner.returncode == 3, (out, err)
    assert 'feature_node' in err and f'code {-signal.SIGKILL}' in err, err
    seen.update(proc_tools.descendants(runner.pid))
    leftovers = [pid for pid in seen if proc_tools.alive(pid)]
    assert not leftovers, [proc_tools.cmdline(p) for p in leftovers]
