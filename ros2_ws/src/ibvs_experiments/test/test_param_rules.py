"""
Rules between parameters: refused before any node starts, by the nodes' own functions.

Each node module lists its rules as ``RULES`` and runs them at start
(``ibvs_common.params.declare(node, PARAMS, RULES)``); ``ibvs run`` (runner.resolve),
``ibvs study`` and ``ibvs cell`` run the same functions (graph_params.check_rules) before
anything starts: ``runner.resolve('scenario1', {'servo_law': 'ibvs'})`` is refused there,
not by the feedback node after start.
"""

import importlib
import itertools

from ibvs_bringup import graph_params
from ibvs_bringup.graph import GRAPH
from ibvs_bringup.scenario import ScenarioError
from ibvs_common.params import check_rules, ParameterError, RETIRED
from ibvs_experiments import runner
import pytest
from rclpy.parameter import Parameter

#: A broken rule per example, the parameters its message must name, and a node that runs it.
BROKEN = [
    ({'servo_law': 'ibvs'}, ('feedforward_method', 'servo_law'), 'adaptive_feedback_node'),
    ({'lambda_inf': 1e3, 'lambda_slope': 1.0}, ('lambda_inf',), 'adaptive_feedback_node'),
    ({'omega_n': 1000.0}, ('omega_n', 'tau_in'), 'adaptive_feedback_node'),
    ({'target_position': [2.9, 2.9, 2.9]}, ('target_position', 'unreachable'),
     'feedforward_node'),
    ({'camera_pose': [0.5, 0.0, 1.0, 0.0, 0.0, 0.0, 2.0]}, ('camera_pose', 'quaternion'),
     'feature_node'),
]


def _node_class(name):
    spec = GRAPH.node(name)
    return getattr(importlib.import_module(spec.module), spec.cls)


@pytest.mark.parametrize('overrides, names, node', BROKEN)
def test_resolve_refuses_a_broken_rule_naming_the_parameters(overrides, names, node):
    with pytest.raises(ScenarioError) as caught:
        runner.resolve('scenario1', overrides)
    for name in names:
        assert name in str(caught.value), caught.value


@pytest.mark.parametrize('overrides, names, node', BROKEN)
def test_the_node_refuses_with_the_same_message(context, overrides, names, node):
    # One function per rule: the node's refusal at start is the pre-check's, word for word.
    with pytest.raises(ScenarioError) as pre:
        graph_params.check_rules(overrides, 'x')
    declared = {p.name for p in importlib.import_module(GRAPH.node(node).module).PARAMS}
    with pytest.raises(ParameterError) as started:
        _node_class(node)(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in overrides.items() if k in declared])
    assert str(pre.value) == f'x: {started.value}'


def test_the_camera_rate_rule_names_both_rates():
    from ibvs_common.shared_params import check_camera_rate_param
    with pytest.raises(ParameterError, match='camera_rate_hz.*physics_rate_hz'):
        check_camera_rate_param({'camera_rate_hz': 30.0, 'physics_rate_hz': 20.0})
    check_camera_rate_param({'camera_rate_hz': 30.0, 'physics_rate_hz': 30.0})


def test_every_node_rule_is_checked_before_start_and_scenario1_keeps_them():
    rules = graph_params.rules()
    for n in GRAPH.nodes:
        for rule in getattr(importlib.import_module(n.module), 'RULES', ()):
            assert rule in rules, (n.name, rule)
    params, _ = runner.resolve('scenario1')
    graph_params.check_rules(params)


def test_a_servo_law_with_its_feedforward_passes():
    from ibvs_control.servo_laws import SERVO_LAWS
    for law in SERVO_LAWS:
        runner.resolve('scenario1', runner.with_servo_law({'servo_law': law}))


@pytest.mark.parametrize('interface, camera, physics', list(itertools.product(
    ['effort', 'position'], [10.0, 30.0, 100.0], [100.0, 1000.0])))
def test_pre_check_passes_either_interface_with_its_own_time_mode(interface, camera, physics):
    # Within their ranges (camera_rate_hz <= 100, physics_rate_hz >= 100) the rates agree;
    # the time mode is the interface's: no second parameter that could disagree with it.
    graph_params.check_rules({'command_interface': interface, 'camera_rate_hz': camera,
                              'physics_rate_hz': physics})


@pytest.mark.parametrize('name, value, node', [
    ('lockstep', False, 'joint_controller_node'), ('lockstep', True, 'feature_node'),
    ('renderer', 'opengl', 'sim_node')])
def test_a_retired_parameter_is_refused_before_start_and_by_the_node_alike(context, name,
                                                                           value, node):
    with pytest.raises(ScenarioError) as pre:
        runner.resolve('scenario1', {name: value})
    with pytest.raises(ParameterError) as started:
        _node_class(node)(context=context, parameter_overrides=[Parameter(name, value=value)])
    assert str(pre.value) == str(started.value) == \
        f"parameter '{name}' is retired: {RETIRED[name]}"


#: Refused by a node's typed configuration as it is built (its __post_init__), not by a RULE:
#: the overrides, the parameters its message must name, the node that builds it.
BUILT = [
    ({'hough_min_radius_px': 40}, ('hough_max_radius_px', 'hough_min_radius_px'),
     'feature_node'),
    ({'camera_outage_s': [0.1, 0.2]}, ('camera_outage_s', 'lockstep'), 'sim_node'),
    ({'extra_joints': ['joint_1']}, ('extra_joints',), 'sim_node'),
    ({'target_features_source': 'taught', 'publish_images': False},
     ('target_features_source', 'publish_images'), 'sim_node'),
]


@pytest.mark.parametrize('overrides, names, node', BUILT)
def test_resolve_refuses_what_only_a_node_config_checks(overrides, names, node):
    # No rule of RULES breaks: the refusal is the config's, built before any node starts.
    graph_params.check(overrides)
    check_rules(graph_params.rules(), graph_params.values(overrides))
    with pytest.raises(ScenarioError) as caught:
        runner.resolve('scenario1', overrides)
    for name in names:
        assert name in str(caught.value), caught.value


@pytest.mark.parametrize('overrides, names, node', BUILT)
def test_the_node_refuses_its_config_with_the_same_message(context, overrides, names, node):
    with pytest.raises(ScenarioError) as pre:
        graph_params.configs(overrides, 'x')
    with pytest.raises(ParameterError) as started:
        _node_class(node)(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in overrides.items()])
    assert str(pre.value) == f'x: {started.value}'


def test_every_node_config_is_its_parameters_and_scenario1_builds_them_all():
    params, _ = runner.resolve('scenario1')
    built = graph_params.configs(params)
    assert list(built) == [n.name for n in GRAPH.nodes]
    for n in GRAPH.nodes:
        module = importlib.import_module(n.module)
        assert module.PARAMS == module.CONFIG.params(), n.name
        assert isinstance(built[n.name], module.CONFIG)
        # Each field holds the run's value, as the node would declare it.
        for name, value in built[n.name].values().items():
            expected = graph_params.values(params)[name]
            assert value == (tuple(expected) if isinstance(expected, list) else expected), name


def test_a_start_outside_a_joints_range_is_refused_before_any_node_starts():
    # Started, the graph would stall with the feedforward unable to plan from it.
    with pytest.raises(ScenarioError, match=r"'start_joints'.*joint 1 at 229\.2 deg is "
                                            r'outside its range \[-180\.0, 180\.0\] deg'):
        runner.resolve('scenario1', {'start_joints': [4.0, 0.0, 0.0, 0.0, 0.0, 0.0]})
    runner.resolve('scenario1', {'start_joints': [3.0, 0.0, 0.0, 0.0, 0.0, 0.0]})
