"""
Killing a process of a run: what the runner does, and what is left of the run.

A node of the paper's graph: the runner stops, names the node and its exit code, leaves
nothing. The optional viewer: the run goes on. The runner itself: SIGINT writes the metrics
of what was recorded; after SIGKILL its bag is read as it is, and the next ``ibvs analyse``
removes the shared memory of the killed nodes.
"""

import json
import signal
import subprocess
import sys

from ibvs_bringup import shm
from ibvs_common import contract
from rosbags.highlevel import AnyReader


def test_runner_reports_a_dead_node_and_leaves_no_process(installed_workspace, signalled_run):
    # Once the simulator runs, the run is really under way; let the graph take a few steps.
    code, out, err = signalled_run([], lambda log: log.exists(), signal.SIGKILL, 60.0,
                                   settle_s=2.0)
    assert code == 3, (out, err)
    # The feature node runs in the simulator's process, which the message names with it.
    assert 'node lockstep (nodes feature_node, ' in err, err
    assert f'code {-signal.SIGKILL}' in err, err


def started(log):
    """Whether the simulator has taken its first step (its log says so)."""
    return log.exists() and 'starting at t = 0' in log.read_text()


def simulated(bag):
    """
    Whether the runner's bag already holds a /clock past 0 (sim time has advanced for it).

    The bag is read as it is while it is written (the recorder ends its MCAP file after
    every chunk); the simulator's own first step says nothing of what the runner received,
    and on a loaded machine the bag's first chunks may hold only the start-up's messages.
    """
    try:
        with AnyReader([bag]) as reader:
            clocks = [c for c in reader.connections if c.topic == contract.CLOCK]
            for connection, _, raw in reader.messages(connections=clocks):
                msg = reader.deserialize(raw, connection.msgtype)
                if msg.clock.sec > 0 or msg.clock.nanosec > 0:
                    return True
    except Exception:  # not yet a bag, or a chunk being written: not yet
        return False
    return False


def test_the_viewers_death_is_said_and_the_run_goes_on(installed_workspace, signalled_run,
                                                       tmp_path):
    """SIGKILL of viz_node, an optional viewer, is said and does not abort the run."""
    code, out, err = signalled_run(['--duration', '0.3', '--no-figures'], started,
                                   signal.SIGKILL, 240.0, victim='viz_node')
    assert code == 0, (out, err)
    assert f'the optional process viz_node exited with code {-signal.SIGKILL}' in out, out
    assert 'the run goes on without it' in out
    metrics = json.loads((tmp_path / 'metrics.json').read_text())
    assert metrics['sim_duration_s'] > 0.25, metrics


def test_sigint_writes_the_metrics_also_when_the_runner_ignored_it(
        installed_workspace, signalled_run, tmp_path):
    """
    SIGINT to the runner gives the metrics of what was recorded, and exit code 130.

    Also when the runner was started with SIGINT ignored (as ``nohup ... &`` starts it):
    it must still stop on it, and write metrics.json.
    """
    def under_way(log):
        return started(log) and simulated(tmp_path / 'bag')

    code, out, err = signalled_run(['--no-figures'], under_way, signal.SIGINT, 120.0,
                                   victim='runner', sigint_ignored=True)
    assert code == 130, (out, err)
    assert 'interrupted (SIGINT)' in out and 'Traceback' not in err, (out, err)
    metrics = json.loads((tmp_path / 'metrics.json').read_text())
    assert 0.0 < metrics['sim_duration_s'] < 30.0, metrics


def test_a_killed_runner_leaves_a_readable_bag_and_no_shared_memory(installed_workspace,
                                                                    signalled_run, tmp_path):
    """
    After SIGKILL of the runner, rosbags reads its bag as it is; ``ibvs analyse`` frees its memory.

    Its nodes die with it (PR_SET_PDEATHSIG) and leave their Fast DDS shared memory in
    /dev/shm; the bag's MCAP file ends after its last chunk, and its metadata.yaml, marked
    in progress, lists its topics: a reader of the bag gets every message up to the last
    /clock. The next ``ibvs analyse`` (or run) removes the shared memory and writes the
    bag's exact metadata; the same messages are read after.
    """
    before = shm.names()

    def messages():
        counts, last = {}, 0
        with AnyReader([tmp_path / 'bag']) as reader:
            for connection, stamp, _ in reader.messages():
                counts[connection.topic] = counts.get(connection.topic, 0) + 1
                last = max(last, stamp)
        return counts, last

    def under_way(log):
        return started(log) and simulated(tmp_path / 'bag')

    code, out, err = signalled_run(['--no-figures'], under_way, signal.SIGKILL, 30.0,
                                   settle_s=3.0, victim='runner')  # some sim time recorded
    assert code == -signal.SIGKILL, (out, err)
    assert not (tmp_path / 'metrics.json').exists()
    dead = shm.zombies(new_since=before, min_age_s=0.0)
    assert dead, 'the killed nodes left no shared memory: nothing was tested'
    killed, killed_at = messages()  # the bag as the kill left it
    assert killed.get(contract.CLOCK, 0) >= 2 and killed.get(contract.TOOL_PATH, 0) >= 2, \
        killed
    # No wait: a lock file nobody has open is a dead owner's however young (shm.open_files)
    done = subprocess.run([sys.executable, '-m', 'ibvs_experiments.cli', 'analyse',
                           str(tmp_path / 'bag')], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, (done.stdout, done.stderr)
    assert 'was not closed (its recorder was killed)' in done.stdout, done.stdout
    assert [p for p in dead if p.exists()] == [], 'shared memory of the killed run is left'
    metrics = json.loads((tmp_path / 'metrics.json').read_text())
    assert metrics['sim_duration_s'] > 0.0, metrics
    recovered, recovered_at = messages()
    assert recovered_at == killed_at
    assert {t: recovered[t] for t in killed} == killed, (killed, recovered)
