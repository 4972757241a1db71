"""A study's run is attempted again when a node died, and only then (no Ray, no graph)."""

import io
import json
import os
import sys

from ibvs_experiments import runner, study
import pytest

#: A stand-in for ``ibvs run``: the exit code of each attempt, in turn, from argv; it writes
#: its logs as a run does, and metrics.json when it ends with 0.
STAND_IN = """
import json, sys
from pathlib import Path
run_dir, codes = Path(sys.argv[1]), [int(c) for c in sys.argv[2].split(',')]
count = run_dir / 'count'
n = int(count.read_text()) if count.exists() else 0
count.write_text(str(n + 1))
(run_dir / 'logs').mkdir(exist_ok=True)
(run_dir / 'logs' / 'lockstep.log').write_text(f'attempt {n + 1}')
code = codes[min(n, len(codes) - 1)]
if code == 0:
    (run_dir / 'metrics.json').write_text(json.dumps({'final_position_error_m': 1e-4}))
else:
    print(f'run failed: node lockstep exited with code -11 during attempt {n + 1}')
sys.exit(code)
"""


def _run(tmp_path, codes):
    cmd = [sys.executable, '-c', STAND_IN, str(tmp_path), ','.join(map(str, codes))]
    return study.attempt_until_settled(cmd, dict(os.environ), tmp_path)


def test_a_node_death_is_attempted_again_and_both_attempts_are_kept(tmp_path):
    record = _run(tmp_path, [runner.EXIT_NODE_DIED, 0])
    assert record['status'] == 'ok' and record['attempts'] == 2
    assert record['metrics'] == {'final_position_error_m': 1e-4}
    assert record['earlier_failures'] == [
        'run failed: node lockstep exited with code -11 during attempt 1']
    assert 'attempt 1' in (tmp_path / 'runner.attempt1.log').read_text()
    assert (tmp_path / 'logs.attempt1' / 'lockstep.log').read_text() == 'attempt 1'
    assert (tmp_path / 'logs' / 'lockstep.log').read_text() == 'attempt 2'
    assert record['wall_s'] > 0.0 and json.dumps(record)


def test_a_second_death_fails_the_run_with_both_reasons(tmp_path):
    record = _run(tmp_path, [runner.EXIT_NODE_DIED])
    assert record['status'] == 'failed' and record['attempts'] == study.NODE_DEATH_ATTEMPTS
    assert 'attempt 2' in record['reason']
    assert len(record['earlier_failures']) == study.NODE_DEATH_ATTEMPTS - 1
    # Run again (ibvs study --retry-failed): the earlier study's attempts make way.
    (tmp_path / 'count').unlink()
    again = _run(tmp_path, [runner.EXIT_NODE_DIED, 0])
    assert again['status'] == 'ok' and again['attempts'] == 2
    assert (tmp_path / 'logs.attempt1' / 'lockstep.log').read_text() == 'attempt 1'


@pytest.mark.parametrize('code', [2, 4])
def test_a_refused_or_stalled_run_is_not_attempted_again(tmp_path, code):
    # 2: a refused configuration, 4: a stall; both would come back the same.
    record = _run(tmp_path, [code, 0])
    assert record['status'] == 'failed' and record['attempts'] == 1
    assert record['earlier_failures'] == [] and record['exit_code'] == code
    assert (tmp_path / 'count').read_text() == '1'


def test_the_progress_line_says_a_run_was_attempted_again():
    out = io.StringIO()
    progress = study.Progress(total=1, cached=0, out=out)
    progress.update('laws#2', {'status': 'ok', 'metrics': {'final_position_error_m': 2e-4},
                               'earlier_failures': ['run failed: sim_node exited with -11']})
    out = out.getvalue()
    assert '1/1' in out and '0.200 mm' in out
    assert 'attempt 1 of laws#2, run again: a node died: run failed: sim_node exited' in out


def test_progress_names_the_varied_parameters_and_its_eta_leaves_start_up_out(monkeypatch):
    # A label names the swept values ('laws_limited_scenario2#2' alone does not say
    # servo_law=ibvs), and the ETA leaves Ray's start-up out and counts the runs going at
    # once (elapsed time per run finished, as if one run went at a time, is far too long).
    assert study.run_label({'study': 'laws_limited_scenario2', 'index': 2,
                            'swept': {'servo_law': 'ibvs', 'l2_scale': 0.5}}) == \
        'laws_limited_scenario2#2 (servo_law=ibvs, l2_scale=0.5)'
    assert study.run_label({'study': 's', 'index': 0, 'swept': {}}) == 's#0'
    clock = [100.0]
    monkeypatch.setattr(study.time, 'monotonic', lambda: clock[0])
    out = io.StringIO()
    progress = study.Progress(total=11, cached=1, out=out, parallel=2)
    clock[0] += 60.0  # Ray's start-up and the first runs: 60 s before the first ends
    ok = {'status': 'ok', 'metrics': {'final_position_error_m': 1e-4}}
    progress.update('s#1 (a=1)', {**ok, 'wall_s': 30.0})
    assert progress.eta() == 30.0 * 5  # 9 runs left, 2 at once: 5 rounds of 30 s
    assert 'ETA 2:30  s#1 (a=1): 0.100 mm' in out.getvalue()
    progress.update('s#2', {**ok, 'wall_s': 40.0})
    assert progress.eta() == 35.0 * 4
