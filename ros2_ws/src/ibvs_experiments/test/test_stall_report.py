"""
The stall report names what holds the run and dates what it quotes.

The frozen node, the node busy in a callback (not the nodes that wait behind it in its
process), and a stopped process.
"""

import os
import signal
import sys
import time
from types import SimpleNamespace

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from ibvs_bringup.supervision import NodeProcess
from ibvs_common.node_main import WATCHDOG
from ibvs_experiments.runner import HEARTBEAT_S, Monitor, RunStalled, stopped_processes
from ibvs_testing.proc_tools import ProcTools


class _Node:

    def create_subscription(self, *args):
        return None


def _status(node, **values):
    return DiagnosticArray(status=[DiagnosticStatus(
        name=f'{node}: x', values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])])


def test_the_report_names_the_node_whose_heartbeat_stopped(tmp_path):
    now = [100.0]
    monitor = Monitor(_Node(), SimpleNamespace(), None, clock=lambda: now[0])
    monitor.sim_ns = 500_000_000  # the last /clock: 0.5 s
    monitor._on_diagnostics(_status('adaptive_feedback_node', waiting_for='nothing'))
    now[0] += 5.0  # it froze; the others go on reporting
    monitor._on_diagnostics(_status('feature_node', waiting_for='nothing'))
    monitor._on_diagnostics(_status('sim_node', sim_time_s=0.567))
    procs = [SimpleNamespace(nodes=(n,), log_path=tmp_path / f'{n}.log')
             for n in ('feature_node', 'adaptive_feedback_node', 'sim_node')]
    nodes = [p.nodes[0] for p in procs]
    assert monitor.silent(nodes) == ['adaptive_feedback_node']
    waits = monitor.waits(procs, 0.0)
    assert waits['adaptive_feedback_node'].startswith('HEARTBEAT STOPPED')
    assert '(status 5.0 s old)' in waits['adaptive_feedback_node']
    assert '(status 0.0 s old)' in waits['feature_node']
    assert not waits['feature_node'].startswith('HEARTBEAT')
    report = RunStalled('no progress', monitor.stalled_sim_s(), waits, monitor.silent(nodes))
    assert 'at sim time 0.567 s' in str(report)
    assert 'heartbeat stopped: adaptive_feedback_node' in str(report)
    assert HEARTBEAT_S < 5.0


def _watchdog(node, callback, seconds):
    return DiagnosticArray(status=[DiagnosticStatus(
        name=f'{node}: {WATCHDOG}', message=f'busy in {node} {callback} for {seconds} s',
        values=[KeyValue(key='busy_callback', value=callback)])])


def test_the_report_names_the_busy_node_not_those_behind_it(tmp_path):
    """
    A busy detection freezes its whole process; not every node of it is called frozen.

    The process's watchdog names the callback: that node is the cause, the others of its
    process wait behind it, and a node of another process keeps its own account.
    """
    now = [100.0]
    monitor = Monitor(_Node(), SimpleNamespace(), None, clock=lambda: now[0])
    for node in ('feature_node', 'sim_node', 'viz_node'):
        monitor._on_diagnostics(_status(node, waiting_for='nothing'))
    now[0] += 5.0
    monitor._on_diagnostics(_status('viz_node', waiting_for='nothing'))
    monitor._on_diagnostics(_watchdog('feature_node', 'FeatureNode._on_images', 4.5))
    assert monitor.busy_now() == {
        'feature_node': 'busy in feature_node FeatureNode._on_images for 4.5 s'}
    lockstep = SimpleNamespace(name='lockstep', nodes=('feature_node', 'sim_node'),
                               log_path=tmp_path / 'lockstep.log')
    viz = SimpleNamespace(name='viz_node', nodes=('viz_node',), log_path=tmp_path / 'v.log')
    waits = monitor.waits([lockstep, viz], 0.0)
    assert waits['feature_node'].startswith('BUSY: busy in feature_node '
                                            'FeatureNode._on_images for 4.5 s')
    assert waits['sim_node'].startswith('waits behind feature_node (the process lockstep')
    assert not waits['viz_node'].startswith(('BUSY', 'waits behind', 'HEARTBEAT'))
    report = str(RunStalled('no progress', 0.1, waits, (),
                            ['busy in feature_node FeatureNode._on_images for 4.5 s']))
    assert 'cause: busy in feature_node FeatureNode._on_images' in report
    assert 'heartbeat stopped' not in report
    # The watchdog's word is not the node's heartbeat, and it goes stale.
    assert monitor.diagnostics['feature_node'] == {'waiting_for': 'nothing'}
    now[0] += HEARTBEAT_S + 1.0
    assert monitor.busy_now() == {}


def _until(condition, what, deadline_s=30.0):
    end = time.monotonic() + deadline_s
    while not condition():
        assert time.monotonic() < end, what
        time.sleep(0.01)


def test_a_stopped_process_is_named_as_stopped(tmp_path):
    """A SIGSTOP'd process (or a worker it waits for) is named from outside: it says nothing."""
    proc = NodeProcess.of_command(
        [sys.executable, '-c', 'import subprocess, sys, time; '
         'subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"]); '
         'time.sleep(60)'], 'lockstep', tmp_path / 'lockstep.log', ('sim_node', 'feature_node'))
    try:
        assert stopped_processes([proc]) == {}
        # The worker, once it runs its own command: between fork and exec a child still
        # shows its parent's command line (seen under load).
        _until(lambda: any('subprocess' not in ProcTools.cmdline(c)
                           for c in ProcTools.children(proc.proc.pid)), 'the worker')
        child = ProcTools.children(proc.proc.pid)[0]
        os.kill(child, signal.SIGSTOP)  # a worker the process waits for
        _until(lambda: stopped_processes([proc]), 'the worker stopped')
        assert stopped_processes([proc])['lockstep'].startswith(
            f'waits for its child {sys.executable} -c import time')
        assert f'(pid {child}), which is stopped (state T' in stopped_processes([proc])['lockstep']
        os.kill(proc.proc.pid, signal.SIGSTOP)
        _until(lambda: stopped_processes([proc])['lockstep'].startswith('is stopped'), 'it')
        text = stopped_processes([proc])['lockstep']
        assert text.startswith(f'is stopped (pid {proc.proc.pid}, state T in /proc')
        monitor = Monitor(_Node(), SimpleNamespace(), None, clock=lambda: 0.0)
        waits = monitor.waits([proc], 0.0, stopped_processes([proc]))
        assert waits['sim_node'].startswith('STOPPED: its process lockstep is stopped (pid')
        os.kill(child, signal.SIGKILL)
    finally:
        proc.stop(timeout_s=2.0)
