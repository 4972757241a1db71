"""The report runs each distinct graph run once: studies that name the same run share it."""

import dataclasses
import json

from ibvs_experiments import laws_report, report
from ibvs_experiments.study_spec import Spec


def index_of(spec, **swept):
    """Return the index of the run of ``spec`` whose swept values include ``swept``."""
    return next(run.index for run in spec.runs() if swept.items() <= run.swept.items())


def test_run_identity_resolves_defaults_and_tells_different_runs_apart():
    plain = report.run_identity('scenario1', {}, None)
    # the law study's paper run with ideal actuators: every value the file's or the default
    assert report.run_identity('scenario1', {'actuators': 'ideal', 'feedback_latency_s': 0,
                                             'servo_law': 'paper'}, 3.0) == plain
    assert report.run_identity('scenario1', {}, 2.0) != plain
    assert report.run_identity('scenario1', {'l2_scale': 0.9}, None) != plain
    # a law with its feedforward, as the law study sets it (without: refused, test_param_rules)
    assert report.run_identity('scenario1', {'servo_law': 'ibvs', 'feedforward_method': 'hold'},
                               None) != plain
    assert report.run_identity('scenario2', {}, None) != plain


def test_the_report_runs_the_scenario_runs_that_other_studies_repeat_once():
    specs = report.load_specs() + laws_report.specs()
    by_name = {spec.name: spec for spec in specs}
    to_run, shared = report.shared_runs(specs)
    sweep = by_name[report.SWEEP_STUDY]
    expected = {(report.SWEEP_STUDY, index_of(sweep, l2_scale=1.0)): ('scenario1', 0),
                (report.SWEEP_STUDY, index_of(sweep, l4_scale=1.0)): ('scenario1', 0)}
    # The law study's paper runs with ideal actuators are the scenario studies' runs (one
    # renderer: nothing tells them apart), so they run once.
    for n in (1, 2, 3):
        laws = by_name[f'laws_ideal_scenario{n}']
        paper_run = next(run.index for run in laws.runs()
                         if run.overrides['servo_law'] == 'paper')
        expected[(laws.name, paper_run)] = (f'scenario{n}', 0)
    assert 'renderer' not in laws_report.overrides_for('paper', 'ideal')
    assert shared == expected
    assert sum(len(s.runs()) for s in to_run) == \
        sum(len(s.runs()) for s in specs) - len(expected)
    kept = {spec.name: spec for spec in to_run}
    assert set(kept) == set(by_name), 'each study keeps runs of its own'
    for name, spec in by_name.items():
        # the runs kept name the same overrides as before: their cache keys do not change
        left = [run.overrides for run in spec.runs() if (name, run.index) not in shared]
        assert [run.overrides for run in kept[name].runs()] == left
        if not any(study == name for study, _ in shared):
            assert kept[name] == spec


def test_a_run_that_draws_its_figures_is_not_replaced_by_one_that_does_not():
    bare = Spec(name='bare', scenario='scenario1')
    drawn = dataclasses.replace(bare, name='drawn', run_figures=True)
    again = dataclasses.replace(bare, name='again')
    to_run, shared = report.shared_runs([bare, drawn, again])
    assert [s.name for s in to_run] == ['bare', 'drawn']
    assert shared == {('again', 0): ('drawn', 0)}
    drawn_draws = dataclasses.replace(drawn, name='draws',
                                      draws={'n': 1, 'seed': 0, 'parameters': {}})
    assert report.shared_runs([drawn, drawn_draws])[1] == {}, 'studies with draws run whole'


def test_every_run_gets_a_record_and_the_sweep_reads_scenario_1_at_its_nominal_points():
    specs = report.load_specs() + laws_report.specs()
    to_run, shared = report.shared_runs(specs)
    # each run that runs ends at its own error: 1, 2, 3 ... um in run order
    errors = iter(1e-6 * (i + 1) for i in range(1000))
    ran = {spec.name: [{'study': spec.name, 'index': run.index, 'swept': run.swept,
                        'overrides': run.overrides, 'status': 'ok',
                        'run_dir': f'/runs/{spec.name}/{run.index}',
                        'metrics': {'final_position_error_m': next(errors)}}
                       for run in spec.runs()] for spec in to_run}
    assert ran['scenario1'][0]['metrics']['final_position_error_m'] == 1e-6
    records = report.with_shared(specs, ran, shared)
    for spec in specs:
        assert [r['index'] for r in records[spec.name]] == [run.index for run in spec.runs()]
        assert [r['swept'] for r in records[spec.name]] == [run.swept for run in spec.runs()]
    rows = report.sweep_rows(records[report.SWEEP_STUDY])
    nominal = [r for r in rows if r['scale'] == 1.0]
    assert [r['link'] for r in nominal] == ['L2', 'L4']
    assert all(r['final_position_error_m'] == 1e-6 for r in nominal), "scenario 1's run"
    others = [r['final_position_error_m'] for r in rows if r['scale'] != 1.0]
    assert len(set(others)) == len(others) == len(rows) - 2 and 1e-6 not in others
    law_runs = {r['overrides']['servo_law']: r for r in records['laws_ideal_scenario2']}
    # the law study's own run, and its paper run: scenario 2's
    assert law_runs['ibvs']['run_dir'].startswith('/runs/laws_ideal_scenario2/')
    assert 'same_as' not in law_runs['ibvs']
    assert law_runs['paper']['run_dir'].startswith('/runs/scenario2/')


def test_build_report_runs_a_shared_run_once_and_shows_it_in_every_study(tmp_path,
                                                                         monkeypatch):
    from ibvs_experiments import study
    metrics = dict.fromkeys(('time_to_1mm_s', 'settling_time_2pct_s', 'max_overshoot_m',
                             'final_tool_axis_error_deg', 'time_estimated_s',
                             'lowest_tool_z_m'), 0.0)
    asked = []

    def run_studies(specs, out_dir, **_):
        asked.extend(specs)
        records = {}
        for spec in specs:
            records[spec.name] = []
            for run in spec.runs():
                # scenario 1 ends 1 mm off, every other run its index + 1 um
                error = 1e-3 if spec.name == 'scenario1' else 1e-6 * (run.index + 1)
                records[spec.name].append(
                    {'study': spec.name, 'index': run.index, 'swept': run.swept,
                     'overrides': run.overrides, 'status': 'ok',
                     'run_dir': str(tmp_path / 'studies' / spec.name / 'runs' / str(run.index)),
                     'metrics': {**metrics, 'final_position_error_m': error,
                                 'initial_position_error_m': 2.0, 'wall_duration_s': 7.5,
                                 'real_time_factor': 0.4}})
        return records

    monkeypatch.setattr(study, 'run_studies', run_studies)
    report.build_report(tmp_path, quick=True)
    runs = sum(len(spec.runs()) for spec in asked)
    assert runs == 3 + 2 * len(report.QUICK_SCALES) - 2, 'the sweep at 100 % is scenario 1'
    sweep = json.loads((tmp_path / 'report.json').read_text())['sweep']
    s1 = json.loads((tmp_path / 'report.json').read_text())['scenarios']['scenario1']
    assert len(sweep) == 2 * len(report.QUICK_SCALES)
    nominal = [r['final_position_error_m'] for r in sweep if r['scale'] == 1.0]
    assert nominal == [s1['final_position_error_m']] * 2
    table = (tmp_path / 'studies' / f'{report.SWEEP_STUDY}_quick' / 'table.md').read_text()
    assert f'{2 * len(report.QUICK_SCALES)} runs' in table
    text = (tmp_path / 'report.md').read_text()
    assert '2 of them made by another study' in text
    # the report says what it is: the claims name their actuators, timings stand apart
    assert '| claim (paper) | paper | measured here | actuators | verdict |' in text
    results, timings = text.split('## Machine timings')
    assert 'wall_duration_s' not in results and '| scenario1 | 7.5 | 0.4 |' in timings
    assert 'Source: graph runs (bags)' in results
    assert "not run with the IRB 4600's limits" in results  # --quick runs no law study


class _FakeSweeps:
    """What ModelOnlySweeps uses of ibvs_experiments.calibration_sweep, with tagged answers."""

    TARGET_SOURCES = ('model', 'taught')

    @staticmethod
    def sweep(laws, targets):
        return [(target, law, point) for target in targets for law in laws for point in (0, 1)]

    @staticmethod
    def noise_sweep(laws):
        return {(law, sigma): (sigma, -sigma) for law in laws for sigma in (0.0, 0.3)}


def test_the_model_only_jobs_give_the_sweeps_in_their_own_order_whatever_order_they_end():
    from ibvs_control.servo_laws import SERVO_LAWS
    model_only = report.ModelOnlySweeps()
    model_only._sweep = _FakeSweeps
    jobs = model_only.jobs()
    assert len(jobs) == len(SERVO_LAWS) * (len(_FakeSweeps.TARGET_SOURCES) + 1)
    for job in reversed(jobs):  # Ray hands them back in any order
        job.done(job.func(*job.args))
    assert model_only.calibration() == _FakeSweeps.sweep(SERVO_LAWS, _FakeSweeps.TARGET_SOURCES)
    assert list(model_only.noise().items()) == list(_FakeSweeps.noise_sweep(SERVO_LAWS).items())
