"""
What a newcomer meets: a folder per run, help that names every option, no stray folder.

No graph is started: ``runner.run_scenario`` is replaced where a command would run one.
"""

from pathlib import Path

from ibvs_bringup.scenario import ScenarioError
from ibvs_experiments import cli
import pytest
import yaml


@pytest.fixture
def runs(monkeypatch, tmp_path):
    """Run ``cli.main`` in ``tmp_path``; return the output folders ``run_scenario`` got."""
    monkeypatch.chdir(tmp_path)
    outs = []

    def run_scenario(name, out, overrides, duration_s, **options):
        outs.append(Path(out))
        return cli.runner.RunResult(Path(out), Path(out) / 'bag', {}, True, [])

    monkeypatch.setattr(cli.runner, 'run_scenario', run_scenario)
    return outs


def test_a_run_without_o_writes_to_a_folder_named_after_its_command_line(
        runs, capsys, monkeypatch):
    monkeypatch.setattr(cli, 'cmd_video', lambda args: 0)  # the demo's film: not here
    assert cli.main(['run', 'scenario1', '--duration', '0.5', '--no-figures']) == 0
    assert cli.main(['run', 'scenario2', '-p', 'feedback_latency_s:=0.067', '-p',
                     'actuators:=limited', '--no-figures']) == 0
    assert cli.main(['run', 'scenario1', '-o', 'mine', '--no-figures']) == 0
    assert cli.main(['demo', '--no-figures']) == 0
    assert runs[:4] == [Path('results/runs/scenario1_0.5s'),
                        Path('results/runs/scenario2_actuators=limited_feedback_latency_s=0.067'),
                        Path('mine'), Path('results/scenario1')]
    assert 'running scenario1 -> results/runs/scenario1_0.5s' in capsys.readouterr().out


def test_run_folder_names_are_readable_distinct_and_bounded():
    folder = cli.run_folder
    assert folder('scenario1') == Path('results/runs/scenario1')
    assert folder('scenario1') != Path('results/scenario1')  # make demo's
    # The same run (order of -p, a value given twice) gives the same folder.
    assert folder('scenario2', ['a:=1', 'b:=x']) == folder('scenario2', ['b:=y', 'a:=1', 'b:=x'])
    assert folder('scenario2', ['a:=1']) != folder('scenario2', ['a:=2'])
    assert folder('scenario1', [], 0.5) != folder('scenario1', [], 0.25)
    assert folder('/some/where/my.yaml', ['target_position:=[-1.0, 0.2, 0.3]', 'x:=a/b'], 2) \
        == Path('results/runs/my_target_position=-1.0,0.2,0.3_x=a_b_2s')
    long_a = folder('scenario1', [f'p{i}:={i}' for i in range(40)])
    long_b = folder('scenario1', [f'p{i}:={i + 1}' for i in range(40)])
    assert len(long_a.name) == cli.RUN_NAME_MAX and long_a != long_b
    assert long_a.name.startswith('scenario1_p0=0_p1=1_p10=10')


def test_analyse_of_a_missing_bag_makes_no_folder(monkeypatch, tmp_path, capsys):
    monkeypatch.chdir(tmp_path)
    assert cli.main(['analyse', 'results/nope/bag']) == 2
    assert 'no bag at results/nope/bag' in capsys.readouterr().err
    assert not (tmp_path / 'results').exists()


def help_of(capsys, *argv):
    with pytest.raises(SystemExit):
        cli.main([*argv, '--help'])
    return ' '.join(capsys.readouterr().out.split())


def test_help_names_every_scenario_and_option_with_its_default(capsys):
    assert 'real_cell' in help_of(capsys, 'run')
    top = help_of(capsys)
    for option in ('--no-laws', '--retry-failed', '--quick', '--stall-s'):
        assert option in top, option
    study = help_of(capsys, 'study')
    assert '--retry-failed' in study
    assert f'--stall-s STALL_S wall seconds without sim-time progress that fail a run ' \
           f'(default {cli.runner.STALL_S})' in study
    with pytest.raises(SystemExit):
        cli.main(['study', 'x', '--stall-s', '0'])
    assert 'seconds > 0' in capsys.readouterr().err


def test_the_simulators_duration_s_is_the_runs_duration_and_stays_with_the_runner(tmp_path):
    # duration_s stops a simulator started by hand; in a run the runner stops the graph
    # itself, so the nodes do not get it (a simulator stopped early would stall the run).
    run = cli.runner.prepare('scenario1', tmp_path / 'a', {'duration_s': 0.7})
    assert run.duration_s == 0.7
    written = yaml.safe_load(run.params_file.read_text())['/**']['ros__parameters']
    assert 'duration_s' not in written
    assert cli.runner.resolve('scenario1', {'duration_s': 0.7}, 0.7)[1] == 0.7
    with pytest.raises(ScenarioError, match='give one of them'):  # which one would it be?
        cli.runner.resolve('scenario1', {'duration_s': 0.7}, 0.2)
    assert cli.runner.resolve('scenario1', {'duration_s': 0.0})[1] == 3.0
    with pytest.raises(ScenarioError, match='duration_s'):
        cli.runner.resolve('scenario1', {'duration_s': -1.0})


def test_a_run_refused_by_the_runners_checks_leaves_no_folder(monkeypatch, tmp_path, capsys):
    monkeypatch.chdir(tmp_path)
    for argv in (['-p', 'duration_s:=0.7', '--duration', '0.2'],
                 ['-p', 'publish_images:=false']):
        assert cli.main(['run', 'scenario1', *argv]) == 2
        assert capsys.readouterr().err.startswith('error:')
    assert not (tmp_path / 'results').exists()
