"""
The parameters of the node graph, by name: the one check of a run's parameters.

Every node declares its parameters as :class:`ibvs_common.params.Param` (name, default,
range) and checks them at start with :meth:`~ibvs_common.params.Param.check`. The runner
checks a run's parameters (scenario file, ``-p`` overrides, a study's grid and draws) with
the very same :class:`Param` objects and the same conversion before any node starts
(:func:`check`), so that a value a node would refuse is refused in a second, not after the
graph has started, and a name that no node declares, which every node would silently
ignore, is refused with the nearest declared names.
"""

from collections.abc import Mapping
import difflib
from typing import Any, TYPE_CHECKING

from ibvs_common.params import Param, ParameterError, plain_value

from .scenario import ScenarioError

if TYPE_CHECKING:
    from .graph import Graph

#: Parameters that are not a node's: ROS's own (every node declares use_sim_time) and the
#: runner's (a scenario's name and its sim time limit).
NOT_NODES = ('use_sim_time', 'scenario_name', 'run_duration_s')


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
            near = difflib.get_close_matches(name, list(specs) + list(NOT_NODES), n=3)
            raise ScenarioError(
                f"{where} '{name}': no node of the graph declares it"
                + (f"; did you mean {', '.join(repr(n) for n in near)}?" if near else
                   '; `ros2 param list` on a running graph lists the declared names'))
        try:
            spec.check(plain_value(value, spec.default))
        except ParameterError as exc:
            raise ScenarioError(f'{where}: {exc}') from None
