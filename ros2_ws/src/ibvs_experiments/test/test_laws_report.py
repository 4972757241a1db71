"""The servo-law table (ibvs_experiments.laws_report) from synthetic runs: no graph, no bag."""

import dataclasses

from ibvs_analysis.metrics import compute_metrics
from ibvs_control.servo_laws import SERVO_LAWS
from ibvs_experiments import laws_report
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
    assert r.peak_speed_ratio == pytest.approx(2.0 / IRB4600.qd_max[2])
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
    # 20 mm off from 0.5 s to the end of the run at 2 s: it stalled there
    assert rows[-1].endswith('| not reached | 20.0 | 1 (0.33x) | no: stalled at 2 s |')
    assert 'within 1 mm and 0.5 deg at the end' in ' '.join(lines)
    assert all(row.endswith('| yes |') for row in rows[:-1])
    for law in ('paper', 'ibvs'):
        assert (tmp_path / f'law_path_{law}.png').stat().st_size > 0
        assert f'![{law}](laws/law_path_{law}.png)' in lines
        assert (tmp_path / f'law_image_{law}.png').stat().st_size > 0
        assert f'![{law} image paths](laws/law_image_{law}.png)' in lines


def with_features(run, shift):
    """Return ``run`` with features moving from (100, 900, 200) + shift to p_bar."""
    n = len(run.position)
    target = np.array([600.0, 560.0, 300.0, 700.0, 660.0, 300.0])
    start = target + shift
    s = np.clip(np.linspace(0.0, 2.0, n) / 0.5, 0.0, 1.0)[:, None]
    return dataclasses.replace(run, features=start + s * (target - start),
                               target_features=target, image_size=(1280, 720))


def test_image_figure_has_a_row_per_scenario_and_a_line_per_marker_and_case(tmp_path):
    runs = [with_features(straight_run('ibvs', case, name, 0.0), shift)
            for case, shift in (('ideal', -50.0), ('limited', 80.0))
            for name in ('scenario1', 'scenario3')]
    runs.append(with_features(straight_run('paper', 'ideal', 'scenario2', 0.0), 10.0))
    fig = laws_report.image_figure(runs, 'ibvs', tmp_path / 'image.png')
    assert (tmp_path / 'image.png').stat().st_size > 0
    axes = np.array(fig.axes).reshape(-1, 2)
    assert axes.shape == (2, 2), 'scenarios 1 and 3 of ibvs, left and right image'
    assert axes[1, 0].get_title() == 'scenario3, left image'
    left, right = axes[0]
    assert len(left.lines) == 4, 'two markers, two cases'
    ideal_m1 = left.lines[0]
    assert ideal_m1.get_linestyle() == '-' and left.lines[2].get_linestyle() == '--'
    # marker 1's u_left and v from the start (shift -50) to p_bar
    np.testing.assert_allclose(ideal_m1.get_xdata()[[0, -1]], [550.0, 600.0])
    np.testing.assert_allclose(ideal_m1.get_ydata()[[0, -1]], [250.0, 300.0])
    np.testing.assert_allclose(right.lines[0].get_xdata()[[0, -1]], [510.0, 560.0])
    assert left.yaxis_inverted(), 'v grows downwards, as in the image'


def sweep_run(law, target, d, f, error_m, t_1mm):
    from ibvs_experiments.calibration_sweep import SweepRun
    return SweepRun(law, target, d, f, error_m, 100 * f, t_1mm)


def test_calibration_figure_plots_each_law_and_target_against_each_error(tmp_path):
    from ibvs_experiments.calibration_sweep import settings
    runs = [sweep_run(law, target, d, f,
                      0.0 if target == 'taught' else d + 20 * f, 0.4 + i / 10
                      if target == 'taught' or d + 20 * f < 1e-3 else float('nan'))
            for target in ('model', 'taught') for i, law in enumerate(('paper', 'pbvs'))
            for d, f in settings() + [(0.005, 0.01)]]
    fig = laws_report.calibration_figure(runs, tmp_path / 'calibration.png')
    assert (tmp_path / 'calibration.png').stat().st_size > 0
    axes = np.array(fig.axes).reshape(3, 2)
    assert axes[2, 0].get_xlabel() == 'camera position error [mm]'
    assert axes[2, 1].get_xlabel() == 'focal length error [%]'
    for ax in axes.ravel():
        labels = [line.get_label() for line in ax.lines]
        assert labels[:4] == ['paper, model target', 'paper, taught target',
                              'pbvs, model target', 'pbvs, taught target']
    model = axes[0, 0].lines[0]   # paper, model target: the error as large as the offset
    np.testing.assert_allclose(model.get_xdata(), [0.0, 2.5, 5.0, 10.0])
    np.testing.assert_allclose(model.get_ydata(), [0.0, 2.5, 5.0, 10.0])
    focal = axes[1, 1].lines[2]   # pbvs, model target: the axis error against focal error
    np.testing.assert_allclose(focal.get_xdata(), [0.0, 0.5, 1.0, 2.0])
    np.testing.assert_allclose(focal.get_ydata(), [0.0, 0.5, 1.0, 2.0])
    assert len(axes[0, 0].lines[0].get_xdata()) == 4, 'the point with both errors left out'
    # never within 1 mm: drawn as x at the top of the time panel, one per such point
    crosses = [c for c in axes[2, 0].collections if len(c.get_offsets())]
    assert sorted(len(c.get_offsets()) for c in crosses) == [3, 3]
    taught = axes[2, 0].lines[3]
    np.testing.assert_allclose(taught.get_ydata(), [0.5] * 4)


def test_noise_figure_has_a_line_per_law_in_each_panel(tmp_path):
    results = {(law, sigma): (k * sigma * 1e-3, 2 * k * sigma)
               for k, law in ((1, 'paper'), (3, 'ibvs')) for sigma in (0.3, 0.0, 1.0)}
    fig = laws_report.noise_figure(results, tmp_path / 'noise.png')
    assert (tmp_path / 'noise.png').stat().st_size > 0
    position, axis = fig.axes
    assert [line.get_label() for line in position.lines] == ['paper', 'ibvs']
    np.testing.assert_allclose(position.lines[1].get_xdata(), [0.0, 0.3, 1.0])
    np.testing.assert_allclose(position.lines[1].get_ydata(), [0.0, 0.9, 3.0])
    np.testing.assert_allclose(axis.lines[0].get_ydata(), [0.0, 0.6, 2.0])


def test_model_only_section_shows_each_sweep_as_table_and_figure(tmp_path):
    from ibvs_experiments.calibration_sweep import settings
    runs = [sweep_run('ibvs', target, d, f, d, 0.5) for target in ('model', 'taught')
            for d, f in settings()]
    noise = {('ibvs', 0.0): (0.0, 0.0), ('ibvs', 0.1): (0.002, 0.4)}
    lines = laws_report.model_only_section(runs, noise, tmp_path / 'laws', 'laws/')
    for name, table_head in (('calibration', '| target | law | no error |'),
                             ('noise', '| law | noise 0 px | noise 0.1 px |')):
        assert (tmp_path / 'laws' / f'{name}.png').stat().st_size > 0
        head = next(i for i, line in enumerate(lines) if line.startswith(table_head))
        link = next(i for i, line in enumerate(lines) if f'](laws/{name}.png)' in line)
        assert head < link, 'the figure follows its table'
    assert '| model | ibvs | 0.00 mm / 0.00 deg | 2.50 mm' in '\n'.join(lines)


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
