"""``make vsbench`` end to end, tiny: 2 tasks at 2 latencies in the model loop, 1 in the graph."""

import csv
import json

from ibvs_experiments import cli, study
import pytest


def test_a_tiny_benchmark_writes_its_report(installed_workspace, tmp_path, monkeypatch):
    monkeypatch.setenv('IBVS_ROS_DOMAINS', '-'.join(map(str, study.DOMAIN_IDS)))
    out = tmp_path / 'results'
    code = cli.main(['vsbench', '--tasks', '2', '--graph-tasks', '1', '--laws', 'paper',
                     '--duration', '0.1', '--workers', '2', '--parallel', '1',
                     '--latencies', '0.067,0.2', '--graph-latency-tasks', '1',
                     '-o', str(out), '--studies', str(tmp_path / 'studies')])
    assert code == 0
    with open(out / 'vsbench_runs.csv') as f:
        rows = list(csv.DictReader(f))
    assert [(r['source'], r['task'], r['latency_s']) for r in rows] == [
        ('model', 'workspace-3/1/0', '0.067'), ('model', 'workspace-3/1/1', '0.067'),
        ('model', 'workspace-3/1/0', '0.2'), ('model', 'workspace-3/1/1', '0.2'),
        ('graph', 'workspace-3/1/0', '0.067'), ('graph', 'workspace-3/1/0', '0.2')]
    # every run of limited actuators carries the task's bound
    assert all(float(r['time_optimal_s']) > 0.1 for r in rows)
    # 0.1 s from a start up to 20 deg per joint away: no run succeeds, each says why
    assert all(r['success'] == 'False' and r['miss_reason'] for r in rows)
    assert all(r['limit_violations'] == '0' and r['collisions'] == '0' for r in rows)
    report = (out / 'vsbench.md').read_text()
    assert '| model | paper | 2 | 0 (0 %)' in report
    assert '| graph | paper | 1 | 0 (0 %)' in report
    assert '| model | paper | 200 | +0 | 2 | 0 (0 %)' in report
    assert '| graph | paper | 200 | +0 | 1 | 0 (0 %)' in report
    data = json.loads((out / 'vsbench.json').read_text())
    assert data['agreement'][0]['tasks'] == 1
    assert [e['latency_s'] for e in data['latency_agreement']] == [0.067, 0.2]
    assert (out / 'vsbench_latency.png').stat().st_size > 0
    assert (out / 'vsbench_success_vs_start_distance.png').stat().st_size > 0
    assert (out / 'vsbench_success_vs_start_angle.png').stat().st_size > 0
    # graph and model start from the same pose: the same start distance
    start = float(rows[4]['start_distance_m'])
    assert float(rows[0]['start_distance_m']) == pytest.approx(start, abs=1e-6)
