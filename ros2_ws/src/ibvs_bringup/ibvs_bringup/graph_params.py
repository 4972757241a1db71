"""
The parameters of the node graph, by name: the one check of a run's parameters.

Every node declares its parameters as :class:`ibvs_common.params.Param` (name, default,
range) and checks them at start with :meth:`~ibvs_common.params.Param.check`. The runner
checks a run's parameters (scenario file, ``-p`` overrides, a study's grid and draws) with
the very same :class:`Param` objects and the same conversion before any node starts
(:func:`check`), so that a value a node would refuse is refused in a second, not after the
graph has started, and a name that no node declares, which every node would silently
ignore, is refused with the nearest declared names. Then the rules between parameters, and
every node's typed configuration built from the run's values (:func:`check_rules`,
:func:`configs`): what a node would refuse at start is refused before any node starts.
"""

from collections.abc import Mapping
from typing import Any, TYPE_CHECKING

from ibvs_common.params import check_declared, Param, ParamConfig, ParameterError, plain_value
from ibvs_common.params import check_rules as check_rules_of

from .scenario import RUNNER_KEYS, ScenarioError

if TYPE_CHECKING:
    from .graph import Graph

#: Parameters that are not a node's: ROS's own (every node declares use_sim_time) and the
#: runner's (:data:`.scenario.RUNNER_KEYS`).
NOT_NODES = ('use_sim_time',) + RUNNER_KEYS


def declared(graph: 'Graph | None' = None) -> dict[str, Param]:
    """
    Return ``{name: Param}`` of every parameter a node of ``graph`` declares.

    ``graph``: a :class:`.graph.Graph` (default :data:`.graph.GRAPH`); each node's module
    declares its parameters as ``PARAMS``. A parameter several nodes declare is one
    :class:`Param` (:mod:`ibvs_common.shared_params`); the simulator's declaration is taken
    first, as the one that owns the physical meaning.
    """
    import importlib
    from .graph import GRAPH
    graph = graph or GRAPH
    nodes = sorted(graph.nodes, key=lambda n: n.name != graph.simulator)
    specs = {}
    for node in nodes:
        for spec in importlib.import_module(node.module).PARAMS:
            specs.setdefault(spec.name, spec)
    return specs


def check(params: Mapping[str, Any], where: str = 'parameter') -> None:
    """
    Raise :class:`ScenarioError` unless every one of ``params`` is declared and in range.

    ``where`` starts each message (e.g. the scenario file or the study's run).
    """
    specs = declared()
    for name, value in params.items():
        if name in NOT_NODES:
            continue
        spec = specs.get(name)
        if spec is None:
            try:
                check_declared([name], list(specs) + list(NOT_NODES), where)
            except ParameterError as exc:
                raise ScenarioError(str(exc)) from None
            continue  # rclpy's own (ibvs_common.params.ROS_PARAMS)
        try:
            spec.check(plain_value(value, spec.default))
        except ParameterError as exc:
            raise ScenarioError(f'{where}: {exc}') from None


def rules(graph: 'Graph | None' = None) -> tuple:
    """
    Return the rules between parameters of every node of ``graph``, each once, in node order.

    Each node's module lists them as ``RULES`` (:func:`ibvs_common.params.check_rules`): the
    functions the node runs on its values at start (``declare(node, PARAMS, RULES)``).
    """
    import importlib
    from .graph import GRAPH
    out = []
    for node in (graph or GRAPH).nodes:
        for rule in getattr(importlib.import_module(node.module), 'RULES', ()):
            if rule not in out:
                out.append(rule)
    return tuple(out)


def values(params: Mapping[str, Any], graph: 'Graph | None' = None) -> dict[str, Any]:
    """
    Return every declared parameter's value in a run of ``params``: its default, else given.

    The values as a node takes them (:func:`ibvs_common.params.plain_value`); a name no node
    declares is kept as given (:func:`check` refuses it).
    """
    out = {name: spec.default for name, spec in declared(graph).items()}
    out.update({name: plain_value(value, out.get(name)) for name, value in params.items()})
    return out


def configs(params: Mapping[str, Any], where: str = 'parameters',
            graph: 'Graph | None' = None) -> dict[str, ParamConfig]:
    """
    Return each node's typed configuration in a run of ``params``, by node name.

    Each node's module names its :class:`ibvs_common.params.ParamConfig` as ``CONFIG``
    (the one the node builds at start, :func:`ibvs_common.kit.config`); it is built here from
    :func:`values`, so that what its construction checks (each value's range, its rules
    across values: e.g. the simulator's camera outage in lockstep, the detector's Hough
    radii) raises :class:`ScenarioError` with the node's own message, before any node
    starts. A module without ``CONFIG`` is left out.
    """
    import importlib
    from .graph import GRAPH
    run_values = values(params, graph)
    out = {}
    for node in (graph or GRAPH).nodes:
        cls = getattr(importlib.import_module(node.module), 'CONFIG', None)
        if cls is None:
            continue
        try:
            out[node.name] = cls.from_values(run_values)
        except ParameterError as exc:
            raise ScenarioError(f'{where}: {exc}') from None
    return out


def check_rules(params: Mapping[str, Any], where: str = 'parameters',
                graph: 'Graph | None' = None) -> None:
    """
    Raise :class:`ScenarioError` if ``params`` break a rule between parameters.

    The rules are the nodes' own functions (:func:`rules`: the command interface against
    the time mode, the servo law against the feedforward and its gains, omega_n against
    tau_in, the camera rate against the physics rate, a reachable target, a unit quaternion
    in ``camera_pose``, ...), run on ``params`` over every declared default (a parameter not
    given is the node's default, :func:`values`); then every node's configuration is built
    (:func:`configs`). A run that breaks one is refused before any node starts, with the
    message the node would log, not by a node seconds into its start.
    """
    try:
        check_rules_of(rules(graph), values(params, graph))
    except ParameterError as exc:
        raise ScenarioError(f'{where}: {exc}') from None
    configs(params, where, graph)
