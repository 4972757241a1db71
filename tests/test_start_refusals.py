"""
A bad configuration is refused at start with exit code 2 and a message.

Each node's executable, started as ``ros2 run PKG NODE --ros-args ...`` starts it, refuses a
parameter that no node of its process declares (naming the closest), a value of the wrong
type, a parameter file it cannot read or parse, and a ``ROS_DOMAIN_ID`` that ROS would read
as another domain or that lies outside the safe range; ``ibvs run`` refuses the same
domains, a broken ``IBVS_ROS_DOMAINS``, an output directory it cannot write and a
cross-parameter rule of the nodes, before any node starts.
"""

import importlib
import os
from pathlib import Path
import subprocess
import sys

from ibvs_bringup import domains, scenario
from ibvs_common import dds
from ibvs_common.node_main import file_parameter_names, ros_parameter_args
from ibvs_common.params import Param, ParameterError
from ibvs_experiments import cli
import pytest

#: (package, executable) of every node executable, and compose holding the lockstep pair.
EXECUTABLES = (('ibvs_sim', 'sim_node'), ('ibvs_vision', 'feature_node'),
               ('ibvs_control', 'adaptive_feedback_node'), ('ibvs_control', 'feedforward_node'),
               ('ibvs_control', 'joint_controller_node'), ('ibvs_viz', 'viz_node'),
               ('ibvs_sim', 'robot_state_node'))
#: Values of ROS_DOMAIN_ID refused: rcl reads -1 and 010 as other domains, 102-232 are
#: outside the safe range, 233 and 1000 overflow Fast DDS's ports, '' is domain 0 to rcl.
BAD_DOMAINS = ('-1', 'abc', '102', '233', '1000', '', '010', ' 7')


def executable(prefix, package, name):
    path = Path(prefix) / 'lib' / package / name
    if not path.is_file():
        pytest.skip(f'{path} is not installed')
    return str(path)


def start(command, env=None, timeout_s=60.0):
    """
    Run ``command`` to its end; return (exit code, output).

    ``timeout_s`` only guards against a hang (a node that started instead of refusing spins
    until stopped); how fast a refusal comes is ``make bench``'s, not a test's, to say.
    """
    done = subprocess.run(command, capture_output=True, text=True, timeout=timeout_s,
                          env=env, stdin=subprocess.DEVNULL)
    return done.returncode, done.stdout + done.stderr


def test_domain_ids_are_plain_numbers_within_the_safe_range():
    assert dds.domain_id({}) is None
    for good in ('0', '7', '101'):
        assert dds.domain_id({'ROS_DOMAIN_ID': good}) == int(good)
    for bad in BAD_DOMAINS:
        with pytest.raises(dds.DomainError, match='ROS_DOMAIN_ID'):
            dds.domain_id({'ROS_DOMAIN_ID': bad})
        with pytest.raises(dds.DomainError, match='ROS_DOMAIN_ID'):
            domains.claim({'ROS_DOMAIN_ID': bad}, pool=(0, 0))
    with pytest.raises(domains.DomainError, match=domains.POOL_ENV):
        domains.pool({domains.POOL_ENV: '5-300'})
    with pytest.raises(domains.DomainError, match=domains.POOL_ENV):
        domains.claim({domains.POOL_ENV: 'a-b'})


def test_parameter_arguments_are_read_as_rcl_reads_them(tmp_path):
    argv = ['node', 'x', '-p', 'outside:=1', '--ros-args', '-r', 'a:=b', '-p', 'one:=1',
            '--param', 'feature_node:two:=2', '--params-file', 'f.yaml', '--', '-p', 'no:=3']
    assert ros_parameter_args(argv) == (['one', 'two'], ['f.yaml'])
    good = tmp_path / 'good.yaml'
    good.write_text('/**:\n  ros__parameters: {shared: 1}\n'
                    'feature_node:\n  ros__parameters: {mine: 2}\n')
    assert file_parameter_names(str(good)) == ['mine']
    for text, why in (('/**:\n  ros__parameters: {a: [1,\n', 'not valid YAML'),
                      ('just text\n', 'expected'), ('/**: {a: 1}\n', 'expected')):
        good.write_text(text)
        with pytest.raises(ParameterError, match=why):
            file_parameter_names(str(good))
    with pytest.raises(ParameterError, match='cannot read it'):
        file_parameter_names(str(tmp_path / 'missing.yaml'))


@pytest.mark.parametrize('package,name', EXECUTABLES)
def test_an_executable_refuses_an_undeclared_parameter_at_start(installed_workspace,
                                                                package, name):
    node = executable(installed_workspace, package, name)
    code, out = start([node, '--ros-args', '-p', 'stale_timeout_ss:=1'])
    assert code == 2, out
    assert "'stale_timeout_ss'" in out and 'declares it' in out
    if name != 'sim_node':  # the simulator does not declare it: its nearest differs
        assert "'stale_timeout_s'" in out
    assert 'Traceback' not in out, out


#: How the wrong-typed value of a double the scenario file sets comes, per executable: a
#: ``-p`` after the file (a string, an array, a boolean), or a file after it.
WRONG_TYPES = ('abc', '[1.0]', 'true', 'file', 'abc', '[1.0]', 'file')


@pytest.mark.parametrize('index', range(len(EXECUTABLES)))
def test_an_executable_refuses_a_wrong_type_over_its_parameter_file(installed_workspace,
                                                                    tmp_path, index):
    # rcl's merge keeps the file's double and drops a later value of another type: the
    # executable reads the arguments itself and refuses before rclpy does so.
    package, name = EXECUTABLES[index]
    node = executable(installed_workspace, package, name)
    scenario1 = scenario.scenario_path('scenario1')
    given = scenario.load_parameters(scenario1)
    declared = {p.name: p for p in importlib.import_module(f'{package}.{name}').PARAMS}
    param = next(n for n, v in given.items()
                 if isinstance(v, float) and isinstance(declared.get(n, Param(n, '', '')
                                                                     ).default, float))
    how = WRONG_TYPES[index]
    if how == 'file':
        mine = tmp_path / 'mine.yaml'
        mine.write_text(f'{name}:\n  ros__parameters: {{{param}: fast}}\n')
        extra, value = ['--params-file', str(mine)], 'fast'
    else:
        extra, value = ['-p', f'{param}:={how}'], how
    code, out = start([node, '--ros-args', '--params-file', str(scenario1), *extra])
    assert code == 2, out
    assert f"parameter '{param}' = " in out and 'it must be a double' in out, out
    assert (str(mine) if how == 'file' else f'-p {param}:={value}') in out, out
    assert 'Traceback' not in out, out


def test_compose_refuses_a_name_neither_of_its_nodes_declares(installed_workspace):
    compose = executable(installed_workspace, 'ibvs_bringup', 'compose')
    code, out = start([compose, 'sim_node', 'joint_controller_node', '--ros-args',
                       '-p', 'command_interfacee:=position'])
    assert code == 2 and "did you mean 'command_interface'" in out, out


#: The retired parameters, each with a value it took, and the words of its refusal.
RETIRED_GIVEN = [
    ('lockstep', 'false', "parameter 'lockstep' is retired: the time mode follows from "
                          "command_interface ('effort': lockstep, 'position': free-running)"),
    ('renderer', 'opengl', "parameter 'renderer' is retired: the simulator renders with "
                           'OpenGL (ibvs_sim.gl_renderer)'),
]


@pytest.mark.parametrize('name, value, message', RETIRED_GIVEN, ids=[r[0] for r in RETIRED_GIVEN])
def test_an_executable_refuses_a_retired_parameter_naming_what_replaces_it(
        installed_workspace, tmp_path, name, value, message):
    compose = executable(installed_workspace, 'ibvs_bringup', 'compose')
    code, out = start([compose, 'sim_node', 'joint_controller_node', '--ros-args',
                       '-p', f'{name}:={value}'])
    assert code == 2 and f'-p {name}:={value}: {message}' in out, out
    assert 'Traceback' not in out, out
    # Under /** too, which a node's name check leaves to ibvs run: nobody reads it.
    shared = tmp_path / 'shared.yaml'
    shared.write_text(f'/**:\n  ros__parameters: {{{name}: {value}}}\n')
    node = executable(installed_workspace, 'ibvs_vision', 'feature_node')
    code, out = start([node, '--ros-args', '--params-file', str(shared)])
    assert code == 2 and f'parameter file {shared}: {message}' in out, out


@pytest.mark.parametrize('name, value, message', RETIRED_GIVEN, ids=[r[0] for r in RETIRED_GIVEN])
def test_ibvs_run_refuses_a_retired_parameter_before_any_node(capsys, monkeypatch, tmp_path,
                                                              name, value, message):
    code, err = refused(capsys, monkeypatch, tmp_path, {}, '-p', f'{name}:={value}')
    assert code == 2 and f'-p: {message}' in err and 'Traceback' not in err, err
    mine = tmp_path / 'mine.yaml'  # a scenario file of one's own
    mine.write_text(scenario.scenario_path('scenario1').read_text()
                    + f'    {name}: {value}\n')
    code = cli.main(['run', str(mine), '--duration', '0.1', '-o', str(tmp_path / 'out')])
    err = capsys.readouterr().err
    assert code == 2 and message in err and 'Traceback' not in err, err
    assert not (tmp_path / 'out').exists()


def test_an_executable_refuses_a_wrong_type_and_a_bad_parameter_file(
        installed_workspace, tmp_path):
    node = executable(installed_workspace, 'ibvs_control', 'joint_controller_node')
    code, out = start([node, '--ros-args', '-p', 'camera_rate_hz:=abc'])
    assert code == 2 and "'camera_rate_hz' = 'abc' is invalid: not a number" in out, out
    broken = tmp_path / 'broken.yaml'
    broken.write_text('/**:\n  ros__parameters: {tau_in: [0.01\n')
    misspelt = tmp_path / 'misspelt.yaml'
    misspelt.write_text('joint_controller_node:\n  ros__parameters: {camera_rate_hzz: 30.0}\n')
    for path, said in ((tmp_path / 'missing.yaml', 'cannot read it'),
                       (broken, 'not valid YAML'), (misspelt, "did you mean 'camera_rate_hz'")):
        code, out = start([node, '--ros-args', '--params-file', str(path)])
        assert code == 2 and (str(path) in out or 'camera_rate_hzz' in out), out
        assert said in out and 'Traceback' not in out, out
    code, out = start([node, '--ros-args', '-r', 'no_rule'])
    assert code == 2 and 'the ROS arguments were refused' in out and 'Traceback' not in out


def test_an_executable_refuses_a_domain_ros_must_not_use(installed_workspace):
    node = executable(installed_workspace, 'ibvs_vision', 'feature_node')
    for bad in ('-1', '233'):
        code, out = start([node], env=dict(os.environ, ROS_DOMAIN_ID=bad))
        assert code == 2 and f"ROS_DOMAIN_ID='{bad}'" in out and 'Traceback' not in out, out


def refused(capsys, monkeypatch, tmp_path, env, *args):
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    code = cli.main(['run', 'scenario1', '--duration', '0.1', '-o', str(tmp_path / 'out'),
                     *args])
    return code, capsys.readouterr().err


def test_ibvs_run_refuses_bad_domains_before_anything(capsys, monkeypatch, tmp_path):
    for bad in BAD_DOMAINS:
        code, err = refused(capsys, monkeypatch, tmp_path, {'ROS_DOMAIN_ID': bad})
        assert code == 2 and 'ROS_DOMAIN_ID' in err and 'Traceback' not in err, err
    monkeypatch.delenv('ROS_DOMAIN_ID')
    code, err = refused(capsys, monkeypatch, tmp_path, {domains.POOL_ENV: '5-300'})
    assert code == 2 and domains.POOL_ENV in err, err
    assert not (tmp_path / 'out').exists()


def test_a_broken_domain_pool_ends_any_ibvs_command_with_code_2(installed_workspace):
    code, out = start([sys.executable, '-m', 'ibvs_experiments.cli', 'run', 'scenario1'],
                      env=dict(os.environ, IBVS_ROS_DOMAINS='a-b'))
    assert code == 2 and "IBVS_ROS_DOMAINS='a-b'" in out and 'Traceback' not in out, out


def test_ibvs_run_refuses_an_output_it_cannot_write(capsys, monkeypatch, tmp_path):
    read_only = tmp_path / 'read_only'
    read_only.mkdir()
    read_only.chmod(0o555)
    # root writes into a directory of mode 555: sysfs's root refuses even root.
    target = '/sys' if os.geteuid() == 0 else str(read_only)
    code = cli.main(['run', 'scenario1', '--duration', '0.1', '-o', target])
    err = capsys.readouterr().err
    assert code == 2 and 'cannot write the results' in err, err


def test_ibvs_run_applies_the_nodes_cross_parameter_rules_before_any_node(capsys, monkeypatch,
                                                                          tmp_path):
    code, err = refused(capsys, monkeypatch, tmp_path, {}, '-p', 'omega_n:=1000.0')
    assert code == 2 and "'omega_n' = 1000.0 is invalid with tau_in" in err, err
    code, err = refused(capsys, monkeypatch, tmp_path, {}, '-p',
                        'camera_pose:=[1.0, 0.0, 0.0, 0.0, 0.0, 0.5, 0.5]')
    assert code == 2 and "'camera_pose'" in err and 'quaternion' in err, err
    assert not (tmp_path / 'out' / 'logs').exists()  # refused before any node started


def test_ibvs_run_builds_every_node_config_before_any_node(capsys, monkeypatch, tmp_path):
    # Refused by the feature node's config (its detector's Hough radii) and the simulator's
    # (a camera outage in lockstep) as they are built, not by a rule: exit 2, no output.
    code, err = refused(capsys, monkeypatch, tmp_path, {}, '-p', 'hough_min_radius_px:=40')
    assert code == 2 and "'hough_max_radius_px' = 40 is invalid" in err, err
    code, err = refused(capsys, monkeypatch, tmp_path, {}, '-p', 'camera_outage_s:=[0.1, 0.2]')
    assert code == 2 and "'camera_outage_s'" in err and 'lockstep' in err, err
    assert 'Traceback' not in err
    assert not (tmp_path / 'out').exists()


def test_ibvs_run_refuses_a_bad_joint_order_before_any_node(capsys, monkeypatch, tmp_path):
    # The ros2_control controller's joints (free-running): each joint once, or no run.
    code, err = refused(capsys, monkeypatch, tmp_path, {}, '-p', 'command_interface:=position',
                        '-p', f"joints:=[{', '.join(['joint_1'] * 6)}]")
    assert code == 2 and "parameter 'joints'" in err and 'exactly once' in err, err
    assert not (tmp_path / 'out' / 'logs').exists()  # refused before any node started


def test_a_rate_near_zero_is_refused_by_its_range_not_by_a_crash(
        capsys, monkeypatch, tmp_path, installed_workspace):
    # A rate's period must be whole nanoseconds a timer holds: 1e-300 Hz has none.
    for text in ('1e-300', '1.0e-300', '0.5'):
        code, err = refused(capsys, monkeypatch, tmp_path, {}, '-p', f'camera_rate_hz:={text}')
        assert code == 2 and "'camera_rate_hz' =" in err and 'allowed: [1, 100]' in err, err
        assert 'Traceback' not in err
    for name in ('marker_rate_hz', 'clock_rate_hz', 'joint_state_rate_hz', 'command_rate_hz'):
        code, err = refused(capsys, monkeypatch, tmp_path, {}, '-p', f'{name}:=1e-300')
        assert code == 2 and f"'{name}' = 1e-300 is invalid: out of range" in err, err
    assert not (tmp_path / 'out').exists()
    node = executable(installed_workspace, 'ibvs_control', 'joint_controller_node')
    code, out = start([node, '--ros-args', '-p', 'camera_rate_hz:=1e-300'])
    assert code == 2 and "'camera_rate_hz' = 1e-300 is invalid: out of range" in out, out
    assert 'Traceback' not in out
