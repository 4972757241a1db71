"""The runner's own pause is not the graph's: its heartbeat clocks start again."""

from types import SimpleNamespace

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from ibvs_experiments.runner import HEARTBEAT_S, Monitor


class _Node:

    def create_subscription(self, *args):
        return None


def _heard(monitor, node):
    monitor._on_diagnostics(DiagnosticArray(status=[DiagnosticStatus(name=f'{node}: x')]))


def test_restarted_clocks_count_every_node_heard_and_still_judge_after():
    now = [100.0]
    monitor = Monitor(_Node(), SimpleNamespace(), None, clock=lambda: now[0])
    nodes = ['sim_node', 'feature_node']
    for node in nodes:
        _heard(monitor, node)
    now[0] += 70.0  # the runner was stopped: it heard nobody
    assert monitor.silent(nodes) == nodes
    monitor.restart_clocks()
    assert monitor.silent(nodes) == []
    _heard(monitor, 'sim_node')  # one goes on, one does not
    now[0] += HEARTBEAT_S + 0.5
    _heard(monitor, 'sim_node')
    assert monitor.silent(nodes) == ['feature_node']


class _Process:
    """A stand-in for a node's process: the signals sent to its group, and whether it ended."""

    def __init__(self, code=None):
        self.code, self.sent = code, []

    def poll(self):
        return self.code

    def send_signal(self, sig):
        self.sent.append(sig)


def test_ctrl_z_stops_the_graph_with_the_runner_and_its_continuation_continues_both():
    import os
    import signal
    import subprocess
    from ibvs_experiments.runner import stops_with_the_runner
    running, ended = _Process(), _Process(code=0)
    with stops_with_the_runner([running, ended]) as job:
        os.kill(os.getpid(), signal.SIGCONT)  # a continuation with nothing stopped
        assert running.sent == [] and job.count == 0
        # What `fg` does for the shell: SIGCONT to this process, once it is stopped.
        helper = subprocess.Popen(['sh', '-c', f'sleep 1; kill -CONT {os.getpid()}'])
        os.kill(os.getpid(), signal.SIGTSTP)  # Ctrl-Z: this process stops until continued
        helper.wait(timeout=60)
        assert job.count == 1
        assert running.sent == [signal.SIGSTOP, signal.SIGCONT]
        assert ended.sent == []  # nothing to stop
    assert signal.getsignal(signal.SIGTSTP) == signal.SIG_DFL
