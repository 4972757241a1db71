"""``make vsbench`` end to end, tiny: 2 tasks through the model loop, one 0.3 s graph run."""

import csv
import json

from ibvs_experiments import cli, study
import pytest


def test_a_tiny_benchmark_writes_its_report(installed_workspace, tmp_path, monkeypatch):
    monkeypatch.setenv('IBVS_ROS_DOMAINS', '-'.join(map(str, study.DOMAIN_IDS)))
    out = tmp_path / 'results'
    code = cli.main(['vsbench', '--tasks', '2', '--graph-tasks', '1', '--laws', 'paper',
                     '--duration', '0.1', '--workers', '2', '--parallel', '1',
                     '-o', str(out), '--studies', str(tmp_path / 'studies')])
    assert code == 0
    with open(out / 'vsbench_runs.csv') as f:
        rows = list(csv.DictReader(f))
    assert [(r['source'], r['task']) for r in rows] == [
        ('model', 'workspace-2/1/0'), ('model', 'workspace-2/1/1'),
        ('graph', 'workspace-2/1/0')]
    # 0.1 s from a start up to 20 deg per joint away: no run succeeds, each says why
    assert all(r['success'] == 'False' and r['miss_reason'] for r in rows)
    assert all(r['limit_violations'] == '0' and r['collisions'] == '0' for r in rows)
    report = (out / 'vsbench.md').read_text()
    assert '| model | paper | 2 | 0 (0 %)' in report
    assert '| graph | paper | 1 | 0 (0 %)' in report
    data = json.loads((out / 'vsbench.json').read_text())
    assert data['agreement'][0]['tasks'] == 1
    assert (out / 'vsbench_success_vs_start_distance.png').stat().st_size > 0
    assert (out / 'vsbench_success_vs_start_angle.png').stat().st_size > 0
    # graph and model start from the same pose: the same start distance
    start = float(rows[2]['start_distance_m'])
    assert float(rows[0]['start_distance_m']) == pytest.approx(start, abs=1e-6)
