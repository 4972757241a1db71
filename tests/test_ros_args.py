"""
``--ros-args`` values are read as rcl reads them; a wrong type is refused however it comes.

:mod:`ibvs_common.ros_args` types a ``-p`` value or a parameter file's value as rcl does and
merges them as rclpy does; each is compared here with what rclpy itself gives a node. The
refusals a node's executable makes from it (:func:`ibvs_common.node_main.check_arguments`)
and those of ``ibvs run`` / ``ibvs cell`` follow.
"""

import math

from ibvs_bringup import scenario
from ibvs_common import node_main, ros_args
from ibvs_common.params import Param, ParameterError
from ibvs_control.joint_controller_node import JointControllerNode
from ibvs_experiments import cli
from ibvs_vision.feature_node import FeatureNode
import pytest
import rclpy
from rclpy.node import Node

#: Texts whose type rcl and PyYAML (or Python) read differently, and the usual forms.
TEXTS = ('1e-300', '1.0e-300', '1E5', '0x10', '010', '08', 'yes', 'Y', 'n', 'Off', 'yES', '~',
         'null', '.inf', '-.inf', '.nan', 'inf', 'nan', '+1', '1_000', "'3'", '"5"', '!!str 5',
         '1:2', 'abc', '3.', '.5', '2001-01-01', '0o17', '1e-400', '1e-310', '1e400',
         '0x1p3', '99999999999999999999', '9223372036854775807', '[1.0, 2.0]', '[1, 2]',
         '[a, b]', '[true, false]', '[1e-300]', '0x', '1.0.0', 'e5')


def rclpy_values(args, name='n'):
    """Return {parameter: value} that rclpy gives a node ``name`` started with ``args``."""
    ctx = rclpy.Context()
    rclpy.init(args=['x', '--ros-args', *args], context=ctx)
    try:
        node = Node(name, context=ctx, automatically_declare_parameters_from_overrides=True)
        try:
            return {key: p.value for key, p in node._parameters.items()
                    if key not in ('use_sim_time', 'start_type_description_service')}
        finally:
            node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)


def same(a, b):
    """Return whether ``a`` and ``b`` are the same value of the same type (NaN is NaN)."""
    if isinstance(a, list):
        return isinstance(b, list) and len(a) == len(b) and all(map(same, a, b))
    if isinstance(a, float) and math.isnan(a):
        return isinstance(b, float) and math.isnan(b)
    return type(a) is type(b) and a == b


def test_a_value_is_typed_as_rcl_types_it():
    args = [arg for i, text in enumerate(TEXTS) for arg in ('-p', f'p{i}:={text}')]
    given = rclpy_values(args)
    for i, text in enumerate(TEXTS):
        mine = ros_args.parse_rule(f'p{i}:={text}')[2]
        got = given[f'p{i}']
        got = list(got) if not isinstance(got, (str, bool, int, float)) else got
        assert same(mine, got), (text, mine, got)


def test_sections_and_later_values_merge_as_rclpy_merges_them(tmp_path):
    first = tmp_path / 'first.yaml'
    first.write_text('/**:\n  ros__parameters: {a: 1, b: 0.5, c: abc, d: true, e: 1.5}\n'
                     'n:\n  ros__parameters: {f: 2.5}\nother:\n  ros__parameters: {g: 1.0}\n')
    second = tmp_path / 'second.yaml'
    second.write_text('/**:\n  ros__parameters: {e: 7.5, f: 9.5}\n')
    args = ['--params-file', str(first), '-p', 'a:=2.0', '-p', 'b:=[1.0]', '-p', 'c:=3.0',
            '-p', 'd:=5', '--params-file', str(second), '-p', 'n:g:=4.0']
    expected = rclpy_values(args)
    parsed = ros_args.parse(['x', '--ros-args', *args])
    merged = {name: given.kept()[0] for name, given in parsed.for_node('/n').items()}
    assert merged == expected
    # What rclpy keeps is not always what was given last: the two differ for a, b and d.
    last = {name: given.last()[0] for name, given in parsed.for_node('/n').items()}
    assert {name for name in last if last[name] != merged[name]} == {'a', 'b', 'd'}
    assert 'g' not in ros_args.parse(['x', '--ros-args', '--params-file', str(first)]
                                     ).for_node('/n')


def refusal(classes, *args):
    try:
        node_main.check_arguments(classes, ['x', '--ros-args', *args])
    except ParameterError as exc:
        return str(exc)
    return None


def test_a_wrong_type_is_refused_from_a_file_a_rule_or_both(tmp_path):
    scenario1 = str(scenario.scenario_path('scenario1'))
    joint = [JointControllerNode]
    said = refusal(joint, '--params-file', scenario1, '-p', 'camera_rate_hz:=abc')
    assert "'camera_rate_hz' = 'abc'" in said and 'it must be a double' in said, said
    assert '-p camera_rate_hz:=abc' in said
    said = refusal([FeatureNode], '--params-file', scenario1, '-p', 'stale_timeout_s:=[1.0]')
    assert "'stale_timeout_s' = [1.0]" in said and 'it must be a double' in said, said
    mine = tmp_path / 'mine.yaml'
    mine.write_text('joint_controller_node:\n  ros__parameters: {camera_rate_hz: fast}\n')
    said = refusal(joint, '--params-file', scenario1, '--params-file', str(mine))
    assert "'camera_rate_hz' = 'fast'" in said and f'parameter file {mine}' in said, said
    # A later value of the right type replaces a wrong one: what the node gets is right.
    assert refusal(joint, '--params-file', str(mine), '-p', 'camera_rate_hz:=25.0') is None
    # A section for another node does not apply to this one.
    assert refusal([FeatureNode], '--params-file', str(mine)) is None
    # An integer, then a double: rclpy would keep the integer; refused, naming both.
    whole = tmp_path / 'whole.yaml'
    whole.write_text('/**:\n  ros__parameters: {camera_rate_hz: 30}\n')
    said = refusal(joint, '--params-file', str(whole), '-p', 'camera_rate_hz:=25.0')
    assert 'integer 30' in said and 'double 25.0' in said and 'drop' in said, said
    assert refusal(joint, '-p', 'use_sim_time:=maybe') is not None
    assert refusal(joint, '--params-file', scenario1, '-p', 'camera_rate_hz:=25') is None
    mixed = tmp_path / 'mixed.yaml'
    mixed.write_text('/**:\n  ros__parameters: {disturbance_deg: [0.1, 0, 0, 0, 0, 0]}\n')
    assert 'one type' in refusal(joint, '--params-file', str(mixed))


def test_a_number_read_as_a_string_says_how_to_write_it():
    rate = Param('rate', 1.0, 'a rate', low=0.0, low_open=True)
    for text, why in (('1e-300', 'YAML 1.1'), ('1e400', 'normal range'), ('1_0', "'_'")):
        with pytest.raises(ParameterError, match=f'(?s){why}.*1.0e-300'):
            rate.check(text)
    assert scenario.parse_override('real_time_factor:=1e-300') == ('real_time_factor', 1e-300)
    assert scenario.parse_override('camera_rate_hz:=1:2') == ('camera_rate_hz', '1:2')
    assert scenario.parse_override('disturbance_deg:=[0.1, 0]')[1] == [0.1, 0.0]


def test_ibvs_refuses_a_use_sim_time_that_contradicts_its_mode(capsys, tmp_path):
    code = cli.main(['run', 'scenario1', '--duration', '0.1', '-o', str(tmp_path / 'out'),
                     '-p', 'use_sim_time:=false'])
    err = capsys.readouterr().err
    assert code == 2 and "'use_sim_time' = False" in err and 'simulator owns time' in err
    assert not (tmp_path / 'out').exists()
    # ibvs cell takes use_sim_time true: the rehearsal against a simulator started by hand
    missing = tmp_path / 'missing.yaml'
    code = cli.main(['cell', '--params-file', str(missing)])
    err = capsys.readouterr().err
    assert code == 2 and f'parameter file {missing}' in err and 'scenario' not in err, err
