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
