"""
What a new user meets first: refusals before any node.

Each bad command ends with one ``error:`` line and exit code 2 within a second, not a
traceback and not a graph started for nothing.
"""

import dataclasses
from pathlib import Path

from ibvs_bringup import domains, graph_params
from ibvs_bringup.scenario import ScenarioError
from ibvs_experiments import cli, study
import pytest


def run(capsys, *argv):
    code = cli.main(list(argv))
    return code, capsys.readouterr().err


def test_a_misspelt_parameter_is_refused_with_the_nearest_names(capsys):
    code, err = run(capsys, 'run', 'scenario1', '-p', 'camera_rate_hzz:=30', '-o', '/tmp/x')
    assert code == 2
    assert "'camera_rate_hzz': no node of the graph declares it" in err
    assert "'camera_rate_hz'" in err
    with pytest.raises(ScenarioError, match='stale_timeout_s'):
        graph_params.check({'stale_timeout': 1.0})


def test_bad_commands_end_with_an_error_line_and_code_2(capsys, tmp_path):
    code, err = run(capsys, 'run', 'scenario1', '-p', 'servo_law:=bogus')
    assert code == 2 and err.startswith('error:') and 'servo_law' in err
    broken = tmp_path / 'broken.yaml'
    broken.write_text('/**:\n  ros__parameters: {tau_in: [0.01\n')
    out = tmp_path / 'results'
    code, err = run(capsys, 'run', str(broken), '-o', str(out))
    assert code == 2 and str(broken) in err and 'Traceback' not in err
    code, err = run(capsys, 'run', 'nosuchscenario', '-o', str(out))
    assert code == 2 and err.startswith('error:') and 'nosuchscenario' in err
    assert not out.exists()  # a refused run leaves no output directory behind
    code, err = run(capsys, 'run', 'scenario1', '-o', '/proc/ibvs-results')
    assert code == 2 and err.startswith('error:')
    for duration in ('-1', '0'):
        with pytest.raises(SystemExit) as exit_:
            cli.main(['run', 'scenario1', '--duration', duration])
        assert exit_.value.code == 2
        assert 'seconds > 0' in capsys.readouterr().err


def test_the_pre_check_uses_the_nodes_parser(capsys):
    for value in ('0', '"false"', 'yes please'):
        code, err = run(capsys, 'run', 'scenario1', '-p', f'publish_images:={value}')
        assert code == 2 and "parameter 'publish_images'" in err and 'not a boolean' in err
    graph_params.check({'publish_images': True, 'camera_rate_hz': 30})  # a float takes an int


def test_every_node_of_the_graph_description_has_its_parameters_checked():
    # viz_node's own parameters were once refused as "no node declares it".
    graph_params.check({'marker_rate_hz': 5.0, 'frustum_depth_m': 2.0})
    with pytest.raises(ScenarioError, match='marker_rate_hz'):
        graph_params.check({'marker_rate_hz': -1.0})
    from ibvs_bringup.graph import GRAPH
    assert 'marker_rate_hz' in graph_params.declared(GRAPH)
    without_viz = dataclasses.replace(
        GRAPH, nodes=tuple(n for n in GRAPH.nodes if n.name != 'viz_node'))
    assert 'marker_rate_hz' not in graph_params.declared(without_viz)


def test_shipped_scenarios_pass_the_check():
    from ibvs_bringup import scenario
    for name in scenario.SCENARIOS:
        graph_params.check(scenario.load_parameters(name), name)


def test_domains_stay_in_the_safe_range_set_by_one_variable():
    assert domains.SAFE_RANGE == (0, 101)
    assert domains.pool({}) == (0, 101)
    assert domains.pool({domains.POOL_ENV: '40-60'}) == (40, 60)
    for bad in ('101-199', '170-199', '5', 'a-b'):
        with pytest.raises(ValueError):
            domains.pool({domains.POOL_ENV: bad})
    low, high = study.DOMAIN_IDS
    assert 0 <= low <= high <= 101
    makefile = (Path(__file__).resolve().parents[4] / 'Makefile')
    if makefile.is_file():
        assert 'export IBVS_ROS_DOMAINS' in makefile.read_text()


def test_a_study_spec_is_checked_against_the_declared_names(capsys, tmp_path):
    for grid, expected in (('{l2_scal: [0.5, 1.0]}', "'l2_scal'"),
                           ('{l2_scale: [0.5, 99.0]}', "'l2_scale' = 99.0")):
        spec = tmp_path / 'bad.yaml'
        spec.write_text(f'scenario: scenario1\ngrid: {grid}\n')
        code, err = run(capsys, 'study', str(spec), '-o', str(tmp_path / 'out'))
        assert code == 2 and expected in err, err
        assert not (tmp_path / 'out').exists()


def test_a_study_with_failed_runs_exits_non_zero(capsys, tmp_path, monkeypatch):
    spec = tmp_path / 'one.yaml'
    spec.write_text('scenario: scenario1\ngrid: {l2_scale: [1.0]}\n')
    monkeypatch.setattr(study, 'run_studies',
                        lambda specs, *a, **k: {specs[0].name: [{'status': 'failed'}]})
    code, err = run(capsys, 'study', str(spec), '-o', str(tmp_path / 'out'))
    assert code == 1 and '1 run(s) of one failed' in err


def test_help_is_plain_text_and_setup_files_have_no_tests_require(capsys):
    with pytest.raises(SystemExit):
        cli.main(['--help'])
    out = capsys.readouterr().out
    assert '``' not in out and ':mod:' not in out and ':func:' not in out
    src = Path(__file__).resolve().parents[2]
    for setup in src.glob('*/setup.py'):
        assert 'tests_require' not in setup.read_text(), setup


def test_a_report_with_failed_runs_ends_with_an_error_line_not_a_traceback(capsys, monkeypatch):
    from ibvs_experiments import report
    asked = {}

    def failing(out_dir, **kwargs):
        asked.update(kwargs)
        raise report.ReportRunsFailed(['laws_limited_scenario2#3: run stalled: ...'])

    monkeypatch.setattr(report, 'build_report', failing)
    code, err = run(capsys, 'report', '-o', 'unused', '--retry-failed')
    assert code == 1 and asked['retry_failed'] is True
    assert err.startswith('error: 1 report run(s) failed') and 'Traceback' not in err
    assert 'laws_limited_scenario2#3' in err and '--retry-failed' in err


@pytest.mark.parametrize('extra, figures, filmed', [
    ((), True, True), (('--no-figures',), False, True), (('--no-video',), True, False)])
def test_demo_runs_scenario1_and_films_that_run(monkeypatch, capsys, tmp_path, extra, figures,
                                                filmed):
    # `make demo` once failed at once ('Namespace' object has no attribute 'figures'): the
    # demo's arguments must be all that `ibvs run` reads. The graph itself is not started.
    # The film is the demo run's own, written from that run's folder, not from a run of its
    # own; its camera images are not recorded (the film renders them again from the run's
    # joint states, tests/test_viz_bag.py).
    calls, films = [], []

    def run_scenario(name, out, overrides, duration_s, **options):
        calls.append((name, Path(out), overrides, duration_s, options))
        return cli.runner.RunResult(Path(out), Path(out) / 'bag', {}, True, [])

    monkeypatch.setattr(cli.runner, 'run_scenario', run_scenario)
    monkeypatch.setattr(cli, 'cmd_video', lambda args: films.append(args.run_dir) or 0)
    out = tmp_path / 'demo'
    assert cli.main(['demo', '-o', str(out), *extra]) == 0
    (name, first, overrides, duration, options), = calls
    assert (name, first, overrides['actuators'], duration) == ('scenario1', out, 'ideal', None)
    assert options['figures'] is figures and not options['record_overlays']
    assert options['record_images'] is False
    assert films == ([out] if filmed else [])


def test_a_study_is_checked_against_the_rules_between_parameters(capsys, tmp_path):
    spec = tmp_path / 'gains.yaml'
    spec.write_text('scenario: scenario1\ngrid: {omega_n: [10.0, 1000.0]}\n')
    code, err = run(capsys, 'study', str(spec), '-o', str(tmp_path / 'out'))
    assert code == 2 and "run 1: parameter 'omega_n' = 1000.0 is invalid" in err, err
    spec.write_text('scenario: scenario1\ngrid: {lockstep: [true, false]}\n')
    code, err = run(capsys, 'study', str(spec), '-o', str(tmp_path / 'out'))
    assert code == 2 and "parameter 'lockstep' is retired: the time mode follows from " \
        'command_interface' in err, err
    with pytest.raises(ScenarioError, match='quaternion'):
        graph_params.check_rules({'camera_pose': [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 2.0]})
    graph_params.check_rules({'command_interface': 'position'})
