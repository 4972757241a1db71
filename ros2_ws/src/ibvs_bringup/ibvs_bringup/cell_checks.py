"""
What ``ibvs cell`` checks before any node starts: its parameters, names and topics.

The checks of ``ibvs cell`` (ibvs_experiments.cell, whose module docstring, steps 1 and 2,
is the contract) before it brings up the cell's nodes: the cell's parameters
(:func:`cell_parameters`), the names of the camera's and the controller's topics and the
nodes' remappings to them (:func:`camera_topics`, :func:`command_topic`, :func:`remaps`),
what each topic must offer (:func:`expectations`) and what is wrong with what the graph
shows (:func:`problems`, :func:`wait_for_topics`, :func:`wait_for_camera_info`,
:func:`foreign_publishers`). ``ibvs cell`` re-exports every name.
"""

import argparse
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
import importlib
import math
from pathlib import Path
import re
import time
from typing import Any

from ibvs_bringup import graph_params, scenario
from ibvs_bringup.graph import GRAPH
from ibvs_common import contract, shared_params
from ibvs_common.params import check_retired, ParameterError

#: The nodes of a cell, in start order (docs/real_cell.md "By hand"): the paper's, no
#: simulator and no viewers' node.
CELL_NODES = tuple(n.name for n in GRAPH.cell_nodes() if n.paper)
#: The parameter file of a cell, in ibvs_bringup's config (installed with the scenarios).
CELL_CONFIG = 'cell.yaml'
#: zed-ros2-wrapper's launch defaults (master 33dfefa zed_wrapper/launch/zed_camera.launch.py
#: L498-500 camera_name 'zed', used as the namespace, L514-516 node_name 'zed_node'): the
#: topics are /<camera_name>/<node_name>/...
DEFAULT_CAMERA = 'zed'
ZED_NODE = 'zed_node'
#: The default wall time (s) the cell's topics have to appear in the graph.
CHECK_TIMEOUT_S = 10.0
#: The wall time (s) the first camera_info pair has once the topics are there (a camera
#: publishes one a frame, 30 or 60 a second, as soon as it is read).
CAMERA_INFO_TIMEOUT_S = 2.0
#: The taught pair's topics (``ibvs cell --teach`` publishes them).
TEACH_TOPICS = (contract.TEACH_LEFT_IMAGE, contract.TEACH_RIGHT_IMAGE)

#: Where the hints of :func:`expectations` send the reader (upstream, file and line).
ZED_LEFT_RIGHT = ('is video.publish_left_right true? (zed-ros2-wrapper common_stereo.yaml L54 '
                  'defaults it to false: master 33dfefa zed_wrapper/config/common_stereo.yaml; '
                  'launch with param_overrides:="video.publish_left_right:=true")')


@dataclass(frozen=True)
class Controller:
    """A position controller of ros2_control the joint controller can command."""

    #: The joint controller's ``position_command_type``.
    command_type: str
    #: The joint controller's topic (the contract's name).
    contract_topic: str
    #: abb_ros2's name of the controller (abb_bringup/config/abb_controllers.yaml).
    default_name: str
    #: The controller's topic under its name (``/<name>/<suffix>``).
    suffix: str
    #: The topic's type, as the graph names it.
    msg_type: str
    #: Where the joint controller publishes instead in a dry run (``dry_run``).
    dry_run_topic: str


#: ``--controller``: abb_ros2 (rolling 0705714) abb_bringup/config/abb_controllers.yaml
#: L11-12 and L36-45 (forward_command_controller/ForwardCommandController
#: ``forward_command_controller_position``, joints joint_1..6, interface position; its topic
#: ``~/commands``) and L8-9, L14-34 (``joint_trajectory_controller``, its topic
#: ``~/joint_trajectory``).
CONTROLLERS = {
    'forward_command': Controller('forward_command', contract.POSITION_COMMANDS,
                                  'forward_command_controller_position', 'commands',
                                  'std_msgs/msg/Float64MultiArray', contract.DRY_RUN_COMMANDS),
    'joint_trajectory': Controller('joint_trajectory', contract.TRAJECTORY_COMMANDS,
                                   'joint_trajectory_controller', 'joint_trajectory',
                                   'trajectory_msgs/msg/JointTrajectory',
                                   contract.DRY_RUN_TRAJECTORY),
}

#: A ROS name token (camera and controller names): letters, digits, underscores.
_TOKEN = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')


class CellError(ValueError):
    """A cell's configuration that cannot be started (named, with the reason)."""


def camera_topics(camera_name: str = DEFAULT_CAMERA,
                  node_name: str = ZED_NODE) -> dict[str, str]:
    """
    Return {the contract's camera topic: the ZED wrapper's topic} for a camera so named.

    The wrapper's names are the contract's ``ZED_*`` (those of camera ``zed``, node
    ``zed_node``) under ``/<camera_name>/<node_name>/``.
    """
    for what, name in (('camera name', camera_name), ('node name', node_name)):
        if not _TOKEN.fullmatch(name):
            raise CellError(f'{what} {name!r}: expected a ROS name (letters, digits, _)')
    root = f'/{DEFAULT_CAMERA}/{ZED_NODE}/'
    graph = {contract.LEFT_IMAGE: contract.ZED_LEFT_IMAGE,
             contract.RIGHT_IMAGE: contract.ZED_RIGHT_IMAGE,
             contract.LEFT_INFO: contract.ZED_LEFT_INFO,
             contract.RIGHT_INFO: contract.ZED_RIGHT_INFO}
    return {ours: f'/{camera_name}/{node_name}/' + theirs[len(root):]
            for ours, theirs in graph.items()}


def command_topic(controller: str, controller_name: str | None = None) -> str:
    """Return the topic of ``controller`` (a key of :data:`CONTROLLERS`) named so."""
    spec = _controller(controller)
    name = controller_name or spec.default_name
    if not _TOKEN.fullmatch(name):
        raise CellError(f'controller name {name!r}: expected a ROS name (letters, digits, _)')
    return f'/{name}/{spec.suffix}'


def dry_run_topic(controller: str) -> str:
    """Return where the joint controller's references go in a dry run of ``controller``."""
    return _controller(controller).dry_run_topic


def _controller(controller):
    try:
        return CONTROLLERS[controller]
    except KeyError:
        raise CellError(f'controller {controller!r}: expected one of '
                        f'{", ".join(CONTROLLERS)}') from None


def remaps(controller: str = 'forward_command', camera_name: str = DEFAULT_CAMERA,
           controller_name: str | None = None) -> dict[str, dict[str, str]]:
    """
    Return {node: {topic: remapped}} of the cell's nodes.

    The camera's readers take the wrapper's names as the graph gives them in its
    ``camera_topics: zed_wrapper`` mode (:attr:`ibvs_bringup.graph.Node.zed_remaps`: images
    and camera_info for the feature node, camera_info for the feedback node and the joint
    controller), for the camera ``camera_name``; the joint controller's command topic goes
    to the controller's. /joint_states stays: the driver's joint_state_broadcaster
    publishes it (without the simulator's /stereo/joint_states the feature and feedback
    nodes interpolate it at each frame's stamp).
    """
    zed = camera_topics(camera_name)
    out = {}
    for name in CELL_NODES:
        node = {topic: zed[topic] for topic in GRAPH.node(name).zed_remaps}
        if node:
            out[name] = node
    spec = _controller(controller)
    topic = command_topic(controller, controller_name)
    if topic != spec.contract_topic:
        out.setdefault('joint_controller_node', {})[spec.contract_topic] = topic
    return out


def remap_args(node_remaps: Mapping[str, str]) -> tuple[str, ...]:
    """Return ``('-r', 'topic:=remapped', ...)`` for one node's process (``--ros-args``)."""
    return tuple(arg for topic, remapped in node_remaps.items()
                 for arg in ('-r', f'{topic}:={remapped}'))


def declared_by(nodes: Iterable[str]) -> dict[str, set[str]]:
    """Return {parameter: the nodes of ``nodes`` that declare it} (each module's PARAMS)."""
    out = {}
    for name in nodes:
        for spec in importlib.import_module(GRAPH.node(name).module).PARAMS:
            out.setdefault(spec.name, set()).add(name)
    return out


def simulator_only(names: Iterable[str]) -> list[str]:
    """Return those of ``names`` that no node of a cell declares (the simulator's only)."""
    cell = declared_by(CELL_NODES)
    return [n for n in names if n not in cell and n not in graph_params.NOT_NODES]


def config_path() -> Path:
    """Return the installed ``config/cell.yaml`` (the source tree's if not built)."""
    return scenario.share_directory() / 'config' / CELL_CONFIG


def cell_parameters(params_file: str | Path | None = None,
                    overrides: Mapping[str, Any] | None = None,
                    controller: str = 'forward_command') -> dict[str, Any]:
    """
    Return the checked parameters of a cell: the file's, the overrides, the controller's.

    The controller sets ``position_command_type`` (the file's is replaced). Raises
    :class:`CellError` for a retired name (:data:`ibvs_common.params.RETIRED`), a name the
    cell's nodes do not declare (a simulator's: none of them would read it), a ``-p
    position_command_type`` other than the controller's, a value out of its range or a rule
    between parameters broken (:func:`graph_params.check`, :func:`graph_params.check_rules`).
    """
    path = Path(params_file) if params_file else config_path()
    try:
        params = scenario.load_parameters(path)
    except scenario.ScenarioError as exc:
        raise CellError(str(exc)) from None
    overrides = dict(overrides or {})
    params.update(overrides)
    spec = _controller(controller)
    given = overrides.get('position_command_type', spec.command_type)
    if given != spec.command_type:  # the file's is the default controller's: replaced
        raise CellError(f'position_command_type {given!r} with --controller {controller}: '
                        f'the controller takes {spec.command_type!r} (leave it out, '
                        '--controller sets it)')
    params['position_command_type'] = spec.command_type
    try:
        check_retired(params, str(path))  # nobody's, rather than the simulator's only
    except ParameterError as exc:
        raise CellError(str(exc)) from None
    foreign = simulator_only(params)
    if foreign:
        raise CellError(f'{", ".join(foreign)}: not read by any node of a cell (feature, '
                        "feedback, feedforward, joint controller); the simulator's only "
                        'or unknown: leave it out')
    try:
        graph_params.check(params, str(path))
        graph_params.check_rules(params, str(path))
    except scenario.ScenarioError as exc:
        raise CellError(str(exc)) from None
    return params


@dataclass(frozen=True)
class Expectation:
    """
    One topic of the cell and what must be on it.

    ``role``: 'publisher' (the cell publishes it, our nodes read it) or 'subscriber' (our
    joint controller publishes it, the cell's controller reads it). ``reliability`` and
    ``durability``: those of our side (its subscription, or its publisher), which the
    cell's endpoints must match. ``hint``: what to look at when nobody is there.
    """

    topic: str
    msg_type: str
    role: str
    hint: str
    reliability: str = 'reliable'
    durability: str = 'volatile'


@dataclass(frozen=True)
class Endpoint:
    """A publisher or subscription seen in the graph (rclpy's TopicEndpointInfo, plain)."""

    node: str
    msg_type: str
    reliability: str
    durability: str


def expectations(params: Mapping[str, Any], controller: str = 'forward_command',
                 camera_name: str = DEFAULT_CAMERA,
                 controller_name: str | None = None) -> list[Expectation]:
    """
    Return what the cell must offer before the nodes start (module docstring, step 2).

    The QoS of our side is the contract's: images reliable (``contract.IMAGES``),
    camera_info and /joint_states reliable, /stereo/pose and the teach pair transient
    local (``contract.LATCHED``), the command reliable and volatile (``contract.RELIABLE``).
    """
    zed = camera_topics(camera_name)
    wrapper = (f'{ZED_LEFT_RIGHT}; is the wrapper running, with camera_name:={camera_name}?')
    out = [Expectation(zed[contract.LEFT_IMAGE], 'sensor_msgs/msg/Image', 'publisher', wrapper),
           Expectation(zed[contract.RIGHT_IMAGE], 'sensor_msgs/msg/Image', 'publisher',
                       wrapper),
           Expectation(zed[contract.LEFT_INFO], 'sensor_msgs/msg/CameraInfo', 'publisher',
                       wrapper),
           Expectation(zed[contract.RIGHT_INFO], 'sensor_msgs/msg/CameraInfo', 'publisher',
                       wrapper),
           Expectation(contract.JOINT_STATES, 'sensor_msgs/msg/JointState', 'publisher',
                       'is the driver running and joint_state_broadcaster spawned? (abb_ros2 '
                       'abb_bringup/launch/abb_control.launch.py spawns it)')]
    spec = _controller(controller)
    name = controller_name or spec.default_name
    other = ('joint_trajectory' if controller == 'forward_command' else 'forward_command')
    if not params.get('dry_run', False):  # a dry run commands nobody
        out.append(Expectation(
            command_topic(controller, controller_name), spec.msg_type, 'subscriber',
            f'is the controller spawned? abb_ros2 starts joint_trajectory_controller unless '
            f'launched with initial_joint_controller:={name} (abb_control.launch.py '
            f'initial_joint_controller); or ibvs cell --controller {other}'))
    if all(float(v) == 0.0 for v in params.get('camera_pose', [0.0] * 7)):
        out.append(Expectation(
            contract.STEREO_POSE, 'geometry_msgs/msg/PoseStamped', 'publisher',
            'camera_pose is all zeros, so the feature and feedback nodes wait for the '
            'camera pose here, latched (transient local): set camera_pose to the hand-eye '
            'calibration (docs/real_cell.md step 4)', durability='transient_local'))
    if shared_params.taught(params):
        for topic in (contract.TEACH_LEFT_IMAGE, contract.TEACH_RIGHT_IMAGE):
            out.append(Expectation(
                topic, 'sensor_msgs/msg/Image', 'publisher',
                'target_features_source is taught: ibvs cell --teach DIR publishes the '
                'pair ibvs teach recorded in DIR (or publish the stereo pair of the tool at '
                'the target latched, transient local: docs/real_cell.md step 4), or set '
                'target_features_source:=model', durability='transient_local'))
    return out


def mismatch(expect: Expectation, endpoint: Endpoint) -> str:
    """
    Return why ``endpoint`` cannot serve ``expect`` ('' if it can): its type, or its QoS.

    DDS's request-offered rule: a reliable subscription matches only a reliable
    publisher, a transient-local subscription only a transient-local publisher.
    """
    if endpoint.msg_type != expect.msg_type:
        return f'type {endpoint.msg_type}, expected {expect.msg_type}'
    pub, sub = ((endpoint, expect) if expect.role == 'publisher' else (expect, endpoint))
    if sub.reliability == 'reliable' and pub.reliability != 'reliable':
        return (f'QoS reliability: the publisher is {pub.reliability}, the subscription '
                f'{sub.reliability}: they do not match')
    if sub.durability == 'transient_local' and pub.durability != 'transient_local':
        return (f'QoS durability: the publisher is {pub.durability}, the subscription '
                f'{sub.durability}: they do not match')
    return ''


def problems(expected: Sequence[Expectation],
             found: Mapping[str, Sequence[Endpoint]]) -> list[str]:
    """
    Return what is wrong with the cell's topics, one sentence each ([] when all is there).

    ``found``: {topic: the endpoints of the expectation's role on it}. A topic is served
    when at least one endpoint matches (:func:`mismatch`); otherwise it is missing, or each
    endpoint is named with why it does not match.
    """
    out = []
    for expect in expected:
        endpoints = found.get(expect.topic, ())
        if not endpoints:
            out.append(f'no {expect.topic}: {expect.hint}' if expect.role == 'publisher'
                       else f'no subscriber on {expect.topic}: {expect.hint}')
            continue
        why = [(e, mismatch(expect, e)) for e in endpoints]
        if all(reason for _, reason in why):
            out.append(f'{expect.topic}: ' + '; '.join(
                f'{expect.role} {e.node or "?"}: {reason}' for e, reason in why))
    return out


def endpoints_of(node: Any, expected: Sequence[Expectation]) -> dict[str, list[Endpoint]]:
    """Return {topic: [Endpoint]} of each expectation's role, from ``node``'s graph view."""
    out = {}
    for expect in expected:
        query = (node.get_publishers_info_by_topic if expect.role == 'publisher'
                 else node.get_subscriptions_info_by_topic)
        out[expect.topic] = [
            Endpoint(f'{info.node_namespace.rstrip("/")}/{info.node_name}', info.topic_type,
                     info.qos_profile.reliability.name.lower(),
                     info.qos_profile.durability.name.lower())
            for info in query(expect.topic)]
    return out


def wait_for_topics(node: Any, expected: Sequence[Expectation],
                    timeout_s: float = CHECK_TIMEOUT_S, poll_s: float = 0.2,
                    clock: Callable[[], float] = time.monotonic,
                    stopped: Callable[[], bool] = lambda: False) -> list[str]:
    """
    Look at the graph until every expectation is met or ``timeout_s``; return problems.

    Raises KeyboardInterrupt once ``stopped()`` says so (a SIGINT the caller deferred).
    """
    deadline = clock() + timeout_s
    while True:
        if stopped():
            raise KeyboardInterrupt
        found = problems(expected, endpoints_of(node, expected))
        if not found or clock() >= deadline:
            return found
        time.sleep(poll_s)


def wait_for_camera_info(node: Any, camera_name: str, timeout_s: float,
                         spin: Callable[[float], None],
                         clock: Callable[[], float] = time.monotonic,
                         stopped: Callable[[], bool] = lambda: False
                         ) -> tuple[list[str], str]:
    """
    Read one left and one right camera_info of the camera; return (problems, a line).

    :func:`.cell_camera.camera_problems` on the first of each. A camera that gives none
    within ``timeout_s`` is not refused (a ZED wrapper that is up publishes one a frame to
    any reader; the simulator standing in for the cell waits for all the nodes' readers
    first): the line is then a warning that names it. The images are subscribed to as
    well (their bytes dropped unread), as the feature node will: a camera that publishes
    to its image readers only is read as the nodes will read it.
    ``spin(seconds)`` lets ``node``'s executor deliver; raises KeyboardInterrupt once
    ``stopped()`` says so.
    """
    from sensor_msgs.msg import CameraInfo, Image

    from .cell_camera import camera_problems

    topics = camera_topics(camera_name)
    sides = {'left': topics[contract.LEFT_INFO], 'right': topics[contract.RIGHT_INFO]}
    got: dict[str, Any] = {}
    subs = [node.create_subscription(
        CameraInfo, topic, lambda m, side=side: got.setdefault(side, m), contract.CAMERA_INFO)
        for side, topic in sides.items()]
    subs += [node.create_subscription(Image, topics[image], lambda raw: None, contract.IMAGES,
                                      raw=True)
             for image in (contract.LEFT_IMAGE, contract.RIGHT_IMAGE)]
    try:
        deadline = clock() + timeout_s
        while len(got) < 2 and clock() < deadline:
            if stopped():
                raise KeyboardInterrupt
            spin(0.1)
    finally:
        for sub in subs:
            node.destroy_subscription(sub)
    missing = [topic for side, topic in sides.items() if side not in got]
    if missing:
        return [], (f'warning: no camera_info on {" or ".join(missing)} within '
                    f'{timeout_s:g} s (a camera that waits for all its readers, as the '
                    'simulator standing in for the cell does): its size is not checked '
                    'before the start')
    return camera_problems(got['left'], got['right'], sides['left'], sides['right'])


def foreign_publishers(node: Any, topics: Iterable[str], hint: str) -> list[str]:
    """Return a problem for each of ``topics`` that another node than ``node`` publishes."""
    out = []
    for topic in topics:
        others = [f'{i.node_namespace.rstrip("/")}/{i.node_name}'
                  for i in node.get_publishers_info_by_topic(topic)
                  if i.node_name != node.get_name()]
        if others:
            out.append(f'{topic}: published by {", ".join(others)} too: {hint}')
    return out


def check_seconds(text: str) -> float:
    """Return ``text`` as seconds >= 0 (argparse type of ``--check-timeout``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number of seconds') from None
    if not (value >= 0.0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f'{text}: expected a finite number of seconds >= 0')
    return value
