"""Finding 12 of issue 26: the stall report names the frozen node and dates what it quotes."""

from types import SimpleNamespace

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from ibvs_experiments.runner import HEARTBEAT_S, Monitor, RunStalled


class _Node:

    def create_subscription(self, *args):
        return None


def _status(node, **values):
    return DiagnosticArray(status=[DiagnosticStatus(
        name=f'{node}: x', values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])])


def test_finding12_the_report_names_the_node_whose_heartbeat_stopped(tmp_path):
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
