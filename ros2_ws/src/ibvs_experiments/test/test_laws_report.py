"""The servo-law table (ibvs_experiments.laws_report) from synthetic runs: no graph, no bag."""

from ibvs_control.servo_laws import SERVO_LAWS
from ibvs_experiments import laws_report
from ibvs_experiments.analysis import compute_metrics
from ibvs_model import IRB4600
import numpy as np
import pytest


def straight_run(law, case, name, end_error, qdot_peak=1.0, n=200):
    """Return a LawRun of a tool moving straight to 1 m away from the start, ending off."""
    t = np.linspace(0.0, 2.0, n)
    target = np.eye(4)
    target[:3, 3] = [1.0, 0.0, 0.0]
    s = np.clip(t / 0.5, 0.0, 1.0)[:, None]
    position = s * (target[:3, 3] + [end_error, 0.0, 0.0])
    metrics = compute_metrics(t, position, np.tile(np.eye(3), (n, 1, 1)), target,
                              scenario=name)
    qdot = np.zeros((n, 6))
    qdot[n // 2, 2] = -qdot_peak
    params = {**laws_report.CASES[case], 'servo_law': law, 'scenario_name': name}
    return laws_report.summarise(params, metrics, qdot, position, target)


def test_plan_covers_every_law_scenario_and_case_ideal_first(tmp_path):
    plan = laws_report.plan(tmp_path)
    assert len(plan) == len(SERVO_LAWS) * 3 * 2
    assert len({str(run_dir) for _, run_dir, _ in plan}) == len(plan)
    cases = [o['actuators'] for _, _, o in plan]
    assert cases == sorted(cases), 'ideal before limited'
    for _, _, overrides in plan:
        law = overrides['servo_law']
        assert (overrides.get('feedforward_method') == 'hold') == (law in ('ibvs', 'pbvs'))
        assert ('feedforward_ratio' in overrides) == (law == 'switching')
        assert overrides['feedback_latency_s'] == (0.067 if overrides['actuators'] ==
                                                   'limited' else 0.0)


def test_summary_of_a_run():
    r = straight_run('pbvs', 'limited', 'scenario2', 0.0, qdot_peak=2.0)
    assert (r.law, r.case, r.scenario) == ('pbvs', 'limited', 'scenario2')
    assert r.peak_joint_speed == 2.0
    assert r.peak_speed_share == pytest.approx(2.0 / IRB4600.qd_max[2])
    assert r.converged
    overshooting = straight_run('paper', 'ideal', 'scenario1', 0.004)
    assert overshooting.metrics['max_overshoot_m'] == pytest.approx(0.004)
    assert not overshooting.converged, 'ends 4 mm past the target'
    assert laws_report.case_of({'actuators': 'limited', 'feedback_latency_s': 0.1}) == \
        'limited, 0.1 s latency'


def test_table_and_figures(tmp_path):
    runs = [straight_run(law, 'ideal', name, 0.0) for law in ('paper', 'ibvs')
            for name in laws_report.SCENARIOS]
    runs.append(straight_run('ibvs', 'limited', 'scenario1', 0.02))
    lines = laws_report.section(runs, tmp_path, 'laws/')
    rows = [line for line in lines if line.startswith('| ideal') or line.startswith('| lim')]
    assert len(rows) == len(runs)
    assert rows[-1].endswith('| not reached | 20.0 | 1 (0.33) | no |')
    assert '1 mm and 0.5 deg at the end' in ' '.join(lines)
    assert all(row.endswith('| yes |') for row in rows[:-1])
    for law in ('paper', 'ibvs'):
        assert (tmp_path / f'law_path_{law}.png').stat().st_size > 0
        assert f'![{law}](laws/law_path_{law}.png)' in lines


def test_specs_put_every_law_of_a_case_and_scenario_in_one_study():
    specs = laws_report.specs()
    assert len(specs) == 2 * len(laws_report.SCENARIOS)
    for spec in specs:
        case = spec.name.split('_')[1]
        assert spec.duration_s == laws_report.DURATIONS_S[case]
        runs = spec.runs()
        assert [r.overrides['servo_law'] for r in runs] == list(SERVO_LAWS)
        for run in runs:
            assert run.overrides == laws_report.overrides_for(run.overrides['servo_law'], case)


def test_convergence_definitions_keep_their_tolerances():
    # The numbers the table, the studies, the report and the runner were made with.
    from ibvs_experiments import convergence as c
    assert (c.HOLD.position_m, c.HOLD.axis_deg) == (1e-4, 0.01)
    assert (c.AT_END.position_m, c.AT_END.axis_deg) == (1e-3, float('inf'))
    assert (c.ACCEPTANCE.position_m, c.ACCEPTANCE.axis_deg) == (1e-3, 0.1)
    assert (c.LAW_TABLE.position_m, c.LAW_TABLE.axis_deg) == (1e-3, 0.5)
    assert c.REACHED.position_m == 1e-3
    assert not c.ACCEPTANCE.final({'final_position_error_m': 1e-4})  # no axis: not within
    assert c.ACCEPTANCE.final({'final_position_error_m': 1e-3, 'final_tool_axis_error_deg': 0.1})
    assert not c.HOLD.within(float('nan'), 0.0)
