"""The one success criterion (ibvs_analysis.convergence) and why a run misses it."""

from pathlib import Path
import re
from types import SimpleNamespace

from ibvs_analysis import convergence, study_table
from ibvs_analysis.metrics import compute_metrics
import numpy as np
import pytest

SRC = Path(__file__).resolve().parents[2]
DOCS = Path(__file__).resolve().parents[4] / 'docs'
#: A study as its table reads it (ibvs_experiments.study_spec.Spec): nothing swept.
SPEC = SimpleNamespace(name='s', scenario='scenario1', description='', draws=None,
                       swept_names=lambda: [])


def run_metrics(end_error_m=0.0, axis_deg=0.0, approach_s=0.5, duration_s=2.0, modes=None,
                image_px=None):
    """Return the metrics of a tool moving straight 1 m in ``approach_s``, ending off."""
    t = np.linspace(0.0, duration_s, 401)
    target = np.eye(4)
    target[:3, 3] = [1.0, 0.0, 0.0]
    s = np.clip(t / approach_s, 0.0, 1.0)[:, None]
    position = s * (target[:3, 3] + [end_error_m, 0.0, 0.0])
    angle = np.radians(axis_deg) * s[:, 0]
    rotation = np.array([[[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]]
                         for a in angle])
    mode_t, names = (t[::10], [modes(x) for x in t[::10]]) if modes else ((), ())
    return compute_metrics(t, position, rotation, target, mode_t, names,
                           final_image_error_px=image_px)


def test_one_criterion_of_1_mm_and_half_a_degree():
    s = convergence.SUCCESS
    assert (s.position_m, s.axis_deg) == (1e-3, 0.5)
    assert s.describe() == '1 mm and 0.5 deg'
    assert s.final({'final_position_error_m': 1e-3, 'final_tool_axis_error_deg': 0.5})
    assert not s.final({'final_position_error_m': 1e-4}), 'no axis error: not within'
    assert not s.final({'final_position_error_m': 1e-4, 'final_tool_axis_error_deg': 0.51})
    assert not s.final({'final_position_error_m': None, 'final_tool_axis_error_deg': 0.0})
    assert not convergence.HOLD.within(float('nan'), 0.0)
    # the stopping rule settles well inside the criterion; the 1 mm metric is its distance
    assert convergence.HOLD.position_m < s.position_m and convergence.HOLD.axis_deg < s.axis_deg
    assert convergence.REACHED == convergence.Convergence(s.position_m)


def test_success_is_defined_once_in_the_sources():
    # Every tolerance is built in convergence.py; no module writes its own.
    built = [(p, line) for p in SRC.rglob('*.py') if 'test' not in p.parts
             for line in p.read_text().splitlines() if re.search(r'\bConvergence\(', line)
             and not line.lstrip().startswith(('class ', '#', '"""', '``'))]
    assert {p.name for p, _ in built} == {'convergence.py'}, built
    assert sum('SUCCESS = ' in line for _, line in built) == 1


def test_docs_state_the_criterion_as_it_is():
    # A page that names a success criterion names this one, not one of the older three.
    for page in DOCS.glob('*.md'):
        text = page.read_text()
        for wrong in ('1 mm and 0.1 deg', '1 mm and 0.2 deg', '1 mm / 0.1 deg'):
            assert wrong not in text, f'{page.name}: {wrong!r}'


def test_metrics_say_success_and_why_not():
    good = run_metrics(end_error_m=2e-4, axis_deg=0.3)
    assert good['success'] and good['miss_reason'] is None
    assert good['time_to_success_s'] == pytest.approx(0.5, abs=0.01)
    assert good['final_feature_mode'] is None
    # 0.6 deg off at the end: within 1 mm, outside the axis tolerance, resting there
    tilted = run_metrics(axis_deg=0.6)
    assert not tilted['success'] and tilted['time_to_1mm_s'] is not None
    assert tilted['time_to_success_s'] is None
    assert tilted['miss_reason'].startswith('stalled at 2 s: final 0 mm, 0.6 deg, outside '
                                            '1 mm and 0.5 deg')
    # still on its way at the end of the run
    late = run_metrics(approach_s=4.0)
    assert late['miss_reason'].startswith('timed out at 2 s, still approaching: final 500 mm')
    # the feedback ran on estimates at the end
    lost = run_metrics(end_error_m=0.01, modes=lambda x: 'measured' if x < 1.0 else 'estimated')
    assert lost['final_feature_mode'] == 'estimated'
    assert lost['miss_reason'].startswith("features lost (the last frame's features were "
                                          'estimated); final 10 mm')


def test_a_study_row_records_why_a_run_missed():
    spec = SPEC
    ok = {'index': 0, 'swept': {}, 'status': 'ok', 'run_dir': 'a',
          'metrics': run_metrics(end_error_m=0.005)}
    failed = {'index': 1, 'swept': {}, 'status': 'failed', 'run_dir': 'b', 'metrics': None,
              'reason': 'run stalled: no sim-time progress for 60 s of wall time'}
    rows = study_table.table_rows(spec, [ok, failed])
    assert [r['success'] for r in rows] == [False, False]
    assert rows[0]['reason'].startswith('stalled at 2 s: final 5 mm')
    assert rows[1]['reason'] == 'run failed: run stalled: no sim-time progress for 60 s of ' \
        'wall time'
    assert [r['miss_reason'] for r in rows] == ['stalled', 'graph stalled']


def test_miss_reason_sorts_each_kind_of_miss_into_its_category():
    def finished(**kw):
        return {'status': 'ok', 'metrics': run_metrics(**kw)}

    def failed(reason):
        return {'status': 'failed', 'metrics': None, 'reason': reason}

    assert study_table.miss_category(finished(end_error_m=0.0)) == ''
    assert study_table.miss_category(finished(end_error_m=0.005)) == 'stalled'
    assert study_table.miss_category(finished(approach_s=4.0)) == 'timed out'
    assert study_table.miss_category(finished(
        end_error_m=0.01, modes=lambda x: 'measured' if x < 1.0 else 'estimated')) == \
        'lost features'
    assert study_table.miss_category(failed("error: parameter 'omega_n' = 30.0 is invalid: "
                                            '...; exited with code 2')) == 'refused'
    assert study_table.miss_category(failed('run failed: node sim_node died (exit -11)')) == \
        'node died'
    assert study_table.miss_category(failed('run stalled: no sim-time progress')) == \
        'graph stalled'
    assert study_table.miss_category(failed('something else')) == 'failed'
    # The table shows the free-running columns only where a run has them.
    spec = SPEC
    free = {'index': 0, 'swept': {}, 'status': 'ok', 'run_dir': 'a',
            'metrics': {**run_metrics(end_error_m=0.0), 'frame_latency_mean_s': 0.05,
                        'real_time_factor_held_min': 0.9, 'frames_used': 12}}
    lockstep = {'index': 1, 'swept': {}, 'status': 'ok', 'run_dir': 'b',
                'metrics': run_metrics(end_error_m=0.0)}
    rows = study_table.table_rows(spec, [free, lockstep])
    assert rows[0]['frame_latency_mean_s'] == 0.05 and rows[1]['frames_used'] is None
    assert 'stale_holds' not in rows[0]
    assert 'frame_latency_mean_s' not in study_table.table_rows(spec, [lockstep])[0]


def test_a_stall_with_a_small_image_error_far_off_is_a_local_minimum():
    # classic IBVS in scenario 1: 0.41 px of image error, 25 mm and 45 deg off, at rest
    metrics = run_metrics(end_error_m=0.025, axis_deg=45.0, image_px=0.41)
    assert not metrics['success'] and metrics['final_image_error_px'] == 0.41
    reason = metrics['miss_reason']
    assert reason.startswith('local minimum of the image error at 2 s: image error 0.41 px, '
                             'yet the tool is 25.0 mm and 45.0 deg from the target; final '), \
        reason
    assert study_table.reason_category(reason, failed=False) == 'local minimum'
    # the image says far too, or the features sit on their target: another stall
    for image_px in (5.0, 0.01, None):
        reason = run_metrics(end_error_m=0.025, axis_deg=45.0, image_px=image_px)['miss_reason']
        assert reason.startswith('stalled at 2 s'), (image_px, reason)
    # near the target, a stall is a stall; still approaching is not a minimum
    assert run_metrics(end_error_m=0.005, image_px=0.41)['miss_reason'].startswith('stalled')
    assert run_metrics(approach_s=4.0, axis_deg=45.0, image_px=0.41)['miss_reason'] \
        .startswith('timed out')
    # a success is one whatever the image error says
    assert run_metrics(image_px=0.41)['success']


def test_the_local_minimums_far_bounds_lie_well_beyond_success():
    from ibvs_control import minimum_watch
    assert minimum_watch.FAR_POSITION_M >= 10.0 * convergence.SUCCESS.position_m
    assert minimum_watch.FAR_AXIS_DEG >= 10.0 * convergence.SUCCESS.axis_deg
