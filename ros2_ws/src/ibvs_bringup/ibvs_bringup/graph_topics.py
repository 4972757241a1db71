"""
What the graph reads and writes, as the nodes record it: one source for the topic tables.

Every node opens its topics through :mod:`ibvs_common.kit`, which records each one
(:func:`ibvs_common.kit.opened`). :func:`record` builds every node of
:data:`~ibvs_bringup.graph.GRAPH` with its default parameters in a private rclpy context,
once per mode that opens different topics (:data:`MODES`), and reads those records; the
result is committed as :mod:`ibvs_bringup.opened_topics` (``python -m
ibvs_bringup.graph_topics --write``; a test regenerates it and compares). From that file,
without rclpy, come the reads and writes of docs/design.md §1's table
(:func:`node_table`), §3's table of who opens what
(:func:`contract_table`) and the topic graph tests/test_process_graph.py expects
(:func:`expected_counts`).

A record is a topic as the node names it (``ros2 run``, no remapping); :func:`endpoints`
applies the remappings a run gives (:meth:`~ibvs_bringup.graph.Graph.remaps`).
"""

import argparse
from collections.abc import Iterable, Mapping
import importlib
from pathlib import Path
import sys
from typing import Any, NamedTuple

from ibvs_common import contract
from ibvs_common.kit import PUBLISHES, SUBSCRIBES

from .graph import FRAME_STATES, GRAPH, Graph, uses_frame_states, uses_zed_names

#: The modes whose nodes open different topics: name -> parameters given to every node
#: that declares them (the rest keep their defaults). 'effort' is scenario 1's.
MODES = {
    'effort': {},
    'position': {'command_interface': 'position'},
    'trajectory': {'command_interface': 'position', 'position_command_type': 'joint_trajectory'},
    'taught': {'target_features_source': 'taught'},
    'zed': {'camera_topics': 'zed_wrapper'},
}
#: The contract's profiles by name, in the order a name is chosen, and the message types
#: each names ('' any): CAMERA_INFO is the images' profile, ZED_IMAGES the wrapper's.
QOS_NAMES = (('RELIABLE', contract.RELIABLE, ''),
             ('CAMERA_INFO', contract.CAMERA_INFO, '/CameraInfo'),
             ('IMAGES', contract.IMAGES, ''),
             ('ZED_IMAGES', contract.ZED_IMAGES, '/Image /CameraInfo'),
             ('LATCHED', contract.LATCHED, ''))
#: The committed records, in the source tree (relative to the repository's root).
GENERATED = Path('ros2_ws/src/ibvs_bringup/ibvs_bringup/opened_topics.py')


class Opened(NamedTuple):
    """One topic a node of the graph opens: in which modes (:data:`MODES`), with which QoS."""

    node: str
    direction: str
    topic: str
    msg_type: str
    qos: str
    modes: tuple


def qos_name(qos: Any, msg_type: str) -> str:
    """Return the contract's name of profile ``qos``, or its policies in words."""
    key = (qos.history, qos.depth, qos.reliability, qos.durability)
    for name, profile, types in QOS_NAMES:
        if types and not any(msg_type.endswith(t) for t in types.split()):
            continue
        if key == (profile.history, profile.depth, profile.reliability, profile.durability):
            return name
    return (f'keep last {qos.depth}, {qos.reliability.name.lower()}, '
            f'{qos.durability.name.lower().replace("_", " ")}')


def record(graph: Graph = GRAPH, modes: Mapping[str, Mapping[str, Any]] = MODES
           ) -> tuple[Opened, ...]:
    """
    Build every node of ``graph`` in each mode in a private context; return what they opened.

    Each node gets the mode's parameters it declares (its module's ``PARAMS``). Rows come
    in the graph's node order, then the order each node opened its topics.
    """
    import rclpy
    from rclpy.parameter import Parameter

    from ibvs_common import kit

    rows: dict[tuple, list] = {}
    for mode, params in modes.items():
        context = rclpy.Context()
        rclpy.init(context=context)
        nodes = []
        try:
            for n in graph.nodes:
                module = importlib.import_module(n.module)
                declared = {p.name for p in module.PARAMS}
                nodes.append(getattr(module, n.cls)(context=context, parameter_overrides=[
                    Parameter(k, value=v) for k, v in params.items() if k in declared]))
            for n, node in zip(graph.nodes, nodes):
                for e in kit.opened(node):
                    key = (n.name, e.direction, e.topic, e.msg_type,
                           qos_name(e.qos, e.msg_type))
                    rows.setdefault(key, []).append(mode)
        finally:
            for node in nodes:
                node.destroy_node()
            rclpy.shutdown(context=context)
    order = {n.name: i for i, n in enumerate(graph.nodes)}
    keys = sorted(rows, key=lambda k: order[k[0]])  # stable: each node's own order kept
    return tuple(Opened(*k, tuple(rows[k])) for k in keys)


def render(rows: Iterable[Opened]) -> str:
    """Return the source of :mod:`ibvs_bringup.opened_topics` holding ``rows``."""
    lines = ['"""',
             'What each node of the graph opens, per mode: generated, do not edit.',
             '',
             'Written by ``python -m ibvs_bringup.graph_topics --write`` from what the nodes',
             'record (:func:`ibvs_bringup.graph_topics.record`); a test regenerates it.',
             '"""',
             '',
             '#: Every mode of :data:`ibvs_bringup.graph_topics.MODES`.',
             f'ALL = {tuple(MODES)!r}',
             '#: (node, direction, topic, type, QoS, modes)',
             'OPENED = (']
    for r in rows:
        modes = 'ALL' if r.modes == tuple(MODES) else repr(r.modes)
        lines.append(f'    ({r.node!r}, {r.direction!r}, {r.topic!r},')
        lines.append(f'     {r.msg_type!r}, {r.qos!r}, {modes}),')
    lines.append(')')
    return '\n'.join(lines) + '\n'


def opened() -> tuple[Opened, ...]:
    """Return the committed records (:mod:`ibvs_bringup.opened_topics`)."""
    from .opened_topics import OPENED
    return tuple(Opened(*r) for r in OPENED)


def mode_params(mode: str) -> dict[str, Any]:
    """Return the run parameters of ``mode`` (what picks the run's remappings)."""
    return dict(MODES[mode])


def endpoints(mode: str = 'effort', remapped: bool = True, graph: Graph = GRAPH,
              rows: Iterable[Opened] | None = None) -> list[Opened]:
    """
    Return the topics opened in ``mode``, with the remappings of ``ibvs run`` if ``remapped``.

    ``rows``: the records (default :func:`opened`).
    """
    params = mode_params(mode)
    remaps = (graph.remaps(zed=uses_zed_names(params), frame_states=uses_frame_states(params))
              if remapped else {})
    out = []
    for r in opened() if rows is None else rows:
        if mode in r.modes:
            out.append(r._replace(topic=remaps.get(r.node, {}).get(r.topic, r.topic)))
    return out


def compact(topics: Iterable[str]) -> list[str]:
    """Return ``topics`` in order, a left/right pair merged into ``.../{left,right}/...``."""
    topics = list(dict.fromkeys(topics))
    out = []
    for t in topics:
        twin = t.replace('left', 'right', 1) if 'left' in t else None
        if twin is not None and twin in topics:
            out.append(t.replace('left', '{left,right}', 1))
        elif 'right' in t and t.replace('right', 'left', 1) in topics:
            continue
        else:
            out.append(t)
    return out


def node_topics(name: str, direction: str, rows: Iterable[Opened] | None = None) -> str:
    """
    Return the topics node ``name`` opens in ``direction``, for docs/design.md §1.

    As the node names them; a topic opened in some modes only names them.
    """
    rows = [r for r in (opened() if rows is None else rows)
            if r.node == name and r.direction == direction]
    every = set(MODES)
    by_modes: dict[tuple, list[str]] = {}
    for r in rows:
        by_modes.setdefault(() if set(r.modes) >= every else r.modes, []).append(r.topic)
    parts = []
    for modes, topics in by_modes.items():
        text = ', '.join(compact(topics))
        parts.append(text if not modes else f'{text} ({", ".join(modes)})')
    return '; '.join(parts)


def node_table(graph: Graph = GRAPH, rows: Iterable[Opened] | None = None) -> str:
    """
    Return the node table of docs/design.md §1 (markdown).

    Reads and writes: what each node opens (``rows``, default :func:`opened`), with the
    remappings of a run; the rest is the graph's description (:class:`.graph.Node`).
    """
    rows = list(opened() if rows is None else rows)
    out = ['| node | package, module | process | reads | writes | rate |',
           '|---|---|---|---|---|---|']
    for n in graph.nodes:
        remapped = ''.join(f'; {t} read as {r} (`ibvs run`'
                           f'{", lockstep" if FRAME_STATES.get(t) == r else ""})'
                           for t, r in n.remaps.items())
        where = (f'`{n.process}` ({", ".join(graph.shared(n.process))})' if n.process
                 else 'its own')
        out.append(f'| `{n.name}` | `{n.module}`'
                   f'{" (" + n.doc_module + ")" if n.doc_module else ""} | {where} | '
                   f'{node_topics(n.name, SUBSCRIBES, rows)}{remapped} | '
                   f'{node_topics(n.name, PUBLISHES, rows)} | {n.doc_rate} |')
    out.append('| recorder (in the runner) | `ibvs_bringup.recorder.Recorder` | the '
               "runner's | every topic (images, /joint_states and /joint_effort_commands "
               'on request: /ibvs/joint_path has their values) | the MCAP bag | as '
               'messages arrive |')
    return '\n'.join(out) + '\n'


def contract_table(rows: Iterable[Opened] | None = None, graph: Graph = GRAPH) -> str:
    """
    Return docs/design.md §3's table of the topics the nodes open (markdown).

    One row a topic, as a run of ``ibvs run`` names it (remapped) in any mode: its type, its
    QoS (one per topic: tests/test_topic_qos.py), who publishes and who reads it, and in
    which modes where not in all.
    """
    rows = list(opened() if rows is None else rows)
    topics: dict[str, dict] = {}
    for mode in MODES:
        for r in endpoints(mode, rows=rows, graph=graph):
            t = topics.setdefault(r.topic, {'type': r.msg_type, 'qos': [],
                                            PUBLISHES: [], SUBSCRIBES: [], 'modes': []})
            for key, value in (('qos', r.qos), (r.direction, r.node), ('modes', mode)):
                if value not in t[key]:
                    t[key].append(value)
    out = ['| topic | type | QoS | published by | read by | modes |',
           '|---|---|---|---|---|---|']
    for topic in sorted(topics):
        t = topics[topic]
        modes = 'all' if len(t['modes']) == len(MODES) else ', '.join(t['modes'])
        out.append(f'| `{topic}` | {t["type"]} | {", ".join(t["qos"])} | '
                   f'{", ".join(t[PUBLISHES]) or "-"} | {", ".join(t[SUBSCRIBES]) or "-"} | '
                   f'{modes} |')
    return '\n'.join(out) + '\n'


def expected_counts(nodes: Iterable[str], mode: str = 'effort',
                    rows: Iterable[Opened] | None = None) -> dict[str, tuple[str, int, int]]:
    """
    Return {topic: (type, publishers, subscribers)} of ``nodes`` started by ``ros2 run``.

    No remapping: each node under the names it opens. What tests/test_process_graph.py
    expects ``ros2 topic list -t`` and the counts of ``ros2 topic info`` to show.
    """
    nodes = set(nodes)
    out: dict[str, list] = {}
    for r in endpoints(mode, remapped=False, rows=rows):
        if r.node in nodes:
            entry = out.setdefault(r.topic, [r.msg_type, 0, 0])
            entry[1 if r.direction == PUBLISHES else 2] += 1
    return {t: tuple(v) for t, v in out.items()}


def _param_row(spec) -> str:
    default = spec.default if not isinstance(spec.default, str) else repr(spec.default)
    return (f'| `{spec.name}` | {default} | {spec.units or "-"} | '
            f'{spec.allowed().replace("|", "/")} |')


def node_tables(graph: Graph = GRAPH, rows: Iterable[Opened] | None = None) -> str:
    """
    Return docs/nodes.md's generated part: each node's topics and parameters (markdown).

    Topics: what the node records opening (:func:`opened`), as it names them (``ros2
    run``; :meth:`~ibvs_bringup.graph.Graph.remaps` says what ``ibvs run`` remaps), with
    the modes that open it where not all. Parameters: its module's ``PARAMS``, with their
    defaults, units and allowed values (``ros2 param describe`` shows the same); a parameter
    that several nodes declare alike is in one table first, and each node names it.
    """
    rows = list(opened() if rows is None else rows)
    params = {n.name: importlib.import_module(n.module).PARAMS for n in graph.nodes}
    declared = {}
    for specs in params.values():
        for spec in specs:
            declared.setdefault(spec.name, set()).add(_param_row(spec))
    counts = {name: sum(name in {s.name for s in specs} for specs in params.values())
              for name in declared}
    shared = [name for name in declared if counts[name] > 1 and len(declared[name]) == 1]
    out = ['### Parameters of several nodes', '', '| parameter | default | units | allowed |',
           '|---|---|---|---|']
    out += [next(iter(declared[name])) for name in shared] + ['']
    for n in graph.nodes:
        out += [f'### {n.name}', '', '| opens | topic | type | QoS | modes |',
                '|---|---|---|---|---|']
        for r in rows:
            if r.node == n.name:
                modes = 'all' if set(r.modes) >= set(MODES) else ', '.join(r.modes)
                out.append(f'| {r.direction} | `{r.topic}` | {r.msg_type} | {r.qos} | '
                           f'{modes} |')
        own = [spec for spec in params[n.name] if spec.name not in shared]
        common = [f'`{spec.name}`' for spec in params[n.name] if spec.name in shared]
        out += ['']
        if common:
            out += [f'Of several nodes: {", ".join(common)}.', '']
        if own:
            out += ['| parameter | default | units | allowed |', '|---|---|---|---|']
            out += [_param_row(spec) for spec in own] + ['']
    return '\n'.join(out)


def main(argv: list[str] | None = None) -> int:
    """Write (``--write``) or check (default) :mod:`ibvs_bringup.opened_topics`."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0].strip())
    parser.add_argument('--write', action='store_true', help='write the file')
    parser.add_argument('--file', type=Path, default=GENERATED,
                        help=f'the file (default: {GENERATED}, from the repository root)')
    args = parser.parse_args(argv)
    text = render(record())
    if args.write:
        args.file.write_text(text)
        print(f'wrote {args.file}')
        return 0
    same = args.file.read_text() == text
    print('up to date' if same else f'{args.file} differs: run with --write')
    return 0 if same else 1


if __name__ == '__main__':
    sys.exit(main())
