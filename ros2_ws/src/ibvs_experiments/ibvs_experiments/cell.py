"""
``ibvs cell``: the controller side of a real cell, without the simulator.

On a cell the arm is abb_ros2's ros2_control driver (EGM) and the camera is Stereolabs'
zed-ros2-wrapper; this command starts the four nodes that turn the camera's frames into
joint references (feature, adaptive feedback, feedforward and joint controller), each in a
process of its own as ``ros2 run`` starts it (:class:`ibvs_bringup.supervision.NodeProcess`),
with ``config/cell.yaml`` (real_cell.yaml less the simulator's keys, on the wall clock) and
the remappings to the driver's and the wrapper's names (:func:`remaps`: no code change in a
node). docs/real_cell.md is the manual; this module docstring is the contract.

1. **Parameters** (:func:`cell_parameters`): the file, the ``-p`` overrides, then the
   controller's ``position_command_type``; every name must be declared by one of the four
   nodes (a simulator's key would be ignored by all of them: refused, named) and in range.
2. **The cell's topics** (:func:`expectations`, :func:`problems`), before any node starts:
   each topic the nodes read has a publisher of the right type whose QoS our subscription
   matches (the rectified images and their camera_info, /joint_states; /stereo/pose while
   ``camera_pose`` is zeros; the taught pair while ``target_features_source`` is
   ``taught``), and the command topic has a subscriber (the position controller; not in a
   dry run, which commands nobody), within
   ``check_timeout_s`` (10 s; discovery takes a second or two). What is missing is named
   with what to look at, e.g. zed-ros2-wrapper's ``video.publish_left_right``, false by
   default (master 33dfefa ``zed_wrapper/config/common_stereo.yaml`` L54; the wrapper
   reads it at ``zed_components/src/zed_camera/src/zed_camera_component_main.cpp`` L904 and
   creates the left and right publishers only when it is true,
   ``zed_camera_component_video_depth.cpp`` L258-261 and L391-395); then the command exits
   with :data:`EXIT_CHECK_FAILED` and nothing has started. Then one left and one right
   camera_info (:func:`wait_for_camera_info`) must be a rectified pair at one of the ZED 2's
   native sizes (:func:`.cell_camera.camera_problems`: a downscaled 640 x 360, the
   wrapper's ``general.pub_resolution: 'CUSTOM'``, is refused naming it; a camera that
   sends none within :data:`CAMERA_INFO_TIMEOUT_S` is named in a warning, not refused).
   With a teach (``--teach DIR``, :mod:`.teach`) this process publishes its pair latched
   before the check (which then finds it), takes its target (the cli sets it), and
   refuses another publisher of the pair (:func:`foreign_publishers`: a simulator that
   teaches for itself).
3. **Run**: the recorder of ``ibvs run`` (:class:`ibvs_bringup.recorder.Recorder`) opens
   ``bag/`` in the session's folder, with the parameters, the teach record and, at the end,
   the session (exit codes, dry run) in its metadata, /joint_states included, on the wall
   clock without sim time; ``ibvs analyse DIR/bag`` reads it (:mod:`.analysis`: a cell's
   tool poses are the kinematics of /joint_states where the simulator's truth is not there).
   Then the four processes start; a status line once a second (:class:`StatusBoard`): DRY
   RUN first in a dry run (the joint controller's ``dry_run``: its references on
   :func:`dry_run_topic`, none on the command topic), the joint controller's
   ``/ibvs/servo_status`` code and name (:class:`ibvs_common.servo_codes.ServoStatus`),
   the second publishers a node names on /diagnostics (``second_publishers``:
   :class:`ibvs_common.kit.PublisherWatch`, which every node runs), the image error
   (:meth:`StatusBoard.image_error`: |s - s*| of the features the loop used, /ibvs/features,
   against the taught target's, /ibvs/target_features; without a taught target the feedback
   node's own ``image_error_norm_px`` on /diagnostics) and the model's pose error
   (:class:`PoseError`: the nominal kinematics of the newest /joint_states against the
   target), the camera's stamp offset once the feature node has estimated one (its
   ``stamp_offset_ms`` and ``stamp_offset_sd_ms`` on /diagnostics, and its state when it
   holds: pass it as ``stamp_offset_initial_s`` next time), the frames used (its
   ``/ibvs/frame_latency``, one per frame a command used) and
   the last error any node reported there (a WARN or ERROR status, or a rejected input). A
   new servo status or second publisher prints a line at once, without waiting for the
   second. A node that exits ends the session (:data:`runner.EXIT_NODE_DIED`), the others
   stopped.
4. **Stop**: one SIGINT (Ctrl-C; taken between two spins, as ``ibvs run`` takes it, so
   that it never lands inside the recorder's message) stops every process together
   (:func:`ibvs_bringup.supervision.stop_all`: SIGINT, then SIGTERM, then SIGKILL of each
   process group; each also dies with this process, PR_SET_PDEATHSIG; the recorder takes
   their last messages meanwhile), then the bag is closed; exit code 0.

The ROS domain is the cell's: ``ROS_DOMAIN_ID``, else ROS's default 0 (never a free one of
the pool: the driver and the camera are on the cell's), and this process holds that
domain's lock (:mod:`ibvs_bringup.domains`) so that no ``ibvs run`` on this machine starts
a simulator there.
"""

import argparse
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
import importlib
import math
import os
from pathlib import Path
import re
import sys
import time
from typing import Any, TYPE_CHECKING

from ibvs_bringup import domains, graph_params, scenario
from ibvs_bringup.graph import GRAPH
from ibvs_common import contract
from ibvs_common.shared_params import target_from_parameters
import numpy as np

if TYPE_CHECKING:
    from .teach import Recorded

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
#: What the status line says of a holding code until /diagnostics says more (in the
#: sim-time rehearsal a stopped /clock ages nothing: only the code tells it).
HOLD_WORDS = {'HOLD_CLOCK_STOPPED': 'clock stopped',
              'HOLD_CLOCK_JUMPED_BACK': 'clock jumped back',
              'HOLD_SECOND_PUBLISHER': 'second publisher'}
#: Wall time (s) between two status lines.
STATUS_PERIOD_S = 1.0
#: ``ibvs cell``'s exit code when a topic of the cell is missing or does not match.
EXIT_CHECK_FAILED = 5
#: Where ``ibvs cell`` writes its parameters and the nodes' logs without ``-o``.
CELL_DIR = Path('results') / 'cell'
#: What a session replaces of a previous one in its folder, by name, once its check passed
#: (as ``ibvs run`` does): the bag and the metrics ``ibvs analyse`` wrote beside it.
SESSION_RESULTS = ('bag', 'metrics.json')
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
    :class:`CellError` for a name the cell's nodes do not declare (a simulator's: none of
    them would read it), a ``-p position_command_type`` other than the controller's,
    a value out of its range or a rule between parameters broken
    (:func:`graph_params.check`, :func:`graph_params.check_rules`: position interface,
    free-running).
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
    if params.get('target_features_source') == 'taught':
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


class PoseError:
    """
    The model's pose error of the tool: the nominal kinematics of /joint_states vs the target.

    Called with the newest /joint_states as serialized bytes (the recorder's ``latest``),
    returns (position error m, tool-axis error deg) as the analysis defines them
    (:func:`.analysis.axis_angle_deg`), or (None, None) without a readable one. The
    encoders' view: on a cell the only one; at the taught pose it is the target's own
    (:mod:`.teach`), so it goes to zero as the image error does.
    """

    def __init__(self, target: Any) -> None:
        """Keep the target T_E^O (4x4)."""
        self.target = target

    def __call__(self, raw: bytes | None) -> tuple[float | None, float | None]:
        """Return the errors of the joint state ``raw`` (class docstring)."""
        if raw is None:
            return None, None
        from ibvs_common.conversions import InputError, read_joints
        from ibvs_model import forward_kinematics
        from rclpy.serialization import deserialize_message
        from sensor_msgs.msg import JointState

        from .analysis import axis_angle_deg
        try:
            pose = forward_kinematics(read_joints(deserialize_message(raw, JointState)))
        except (InputError, ValueError):
            return None, None
        position = float(math.dist(pose[:3, 3], self.target[:3, 3]))
        return position, float(axis_angle_deg(pose[None, :3, :3], self.target[:3, :3])[0])


@dataclass
class StatusBoard:
    """
    What the status line says (module docstring, step 3), from the messages as they come.

    Fed with plain values (:meth:`servo`, :meth:`frame_used`, :meth:`diagnostics`), so
    that it needs no ROS; ``clock`` is the wall clock of ages.
    """

    clock: Callable[[], float] = time.monotonic
    code: int | None = None
    frames: set = field(default_factory=set)
    last_error: str = ''
    last_error_at: float | None = None
    #: The joint controller's /diagnostics message (why it waits or holds).
    detail: str = ''
    #: Each node's second publishers, in its words (``second_publishers``), while any.
    newcomers: dict = field(default_factory=dict)
    #: Whether something the operator must see at once came since :meth:`take_news`: a
    #: new servo status, a second publisher that came or went.
    news: bool = False
    #: A dry run (the joint controller's ``dry_run``): the line says so first.
    dry_run: bool = False
    #: The newest features the loop used (/ibvs/features) and the taught target's
    #: (/ibvs/target_features), px (6,): the image error |s - s*| of the status line.
    features_px: Any = None
    target_px: Any = None
    #: The feedback node's own error norm (its /diagnostics ``image_error_norm_px``: the
    #: error it integrates, predicted to the rest pose), shown without a taught target.
    feedback_error_px: float | None = None
    #: The model's pose error (:class:`PoseError`): position (m), tool axis (deg).
    position_error_m: float | None = None
    axis_error_deg: float | None = None
    #: The camera's stamp offset the feature node estimated (its /diagnostics
    #: ``stamp_offset_ms`` and ``stamp_offset_sd_ms``, ibvs_vision.stamp_offset), and the
    #: estimate's state when it holds or waits: shown once there is an estimate.
    stamp_offset_ms: float | None = None
    stamp_offset_sd_ms: float | None = None
    stamp_offset_state: str = ''
    _rejected: dict = field(default_factory=dict)

    def __post_init__(self):
        """Start the session's clock."""
        self.started = self.clock()

    def servo(self, code: int) -> None:
        """Take a /ibvs/servo_status code."""
        self.news = self.news or int(code) != self.code
        self.code = int(code)

    def take(self, attr: str, msg: Any) -> None:
        """Take a features message as ``attr`` (:attr:`features_px`, :attr:`target_px`)."""
        from ibvs_common.conversions import InputError, read_features
        try:
            setattr(self, attr, read_features(msg))
        except InputError:
            pass  # the nodes reject and count it: the last error says so

    def take_news(self) -> bool:
        """Return whether there is news (:attr:`news`), and clear it."""
        news, self.news = self.news, False
        return news

    def image_error(self) -> tuple[float | None, str]:
        """
        Return the image error (px) and its words: |s - s*| of the features the loop used.

        s* is the taught target's (/ibvs/target_features); without one (a model target) the
        feedback node's own error norm, said so; (None, '') before either.
        """
        if self.features_px is not None and self.target_px is not None:
            from ibvs_control.controllers import feature_error
            return float(np.linalg.norm(feature_error(self.features_px, self.target_px))), ''
        if self.feedback_error_px is not None:
            return self.feedback_error_px, " (the feedback's)"
        return None, ''

    def pose_error(self, position_m: float | None, axis_deg: float | None) -> None:
        """Take the model's pose error (:class:`PoseError`; None: none known yet)."""
        if position_m is not None:
            self.position_error_m, self.axis_error_deg = position_m, axis_deg

    def frame_used(self, frame_stamp_ns: int) -> None:
        """Take a /ibvs/frame_latency: the frame of that stamp was used by a command."""
        self.frames.add(int(frame_stamp_ns))

    def diagnostics(self, name: str, level: int, message: str,
                    values: Mapping[str, str]) -> None:
        """
        Take one DiagnosticStatus (``name`` '<node>: <what>', level 0 OK, 1 WARN, 2 ERROR).

        A WARN or ERROR is the last error; so is a rejected input (a ``rejected[...]``
        count that grew, ibvs_common.diagnostics).
        """
        node = name.partition(': ')[0]
        if node == 'joint_controller_node' and 'servo_status' in values:
            self.detail = message
        if node == 'adaptive_feedback_node' and 'image_error_norm_px' in values:
            try:
                self.feedback_error_px = float(values['image_error_norm_px'])
            except ValueError:
                pass
        if node == 'feature_node' and 'stamp_offset_state' in values:
            self.stamp_offset_state = values['stamp_offset_state']
            try:
                self.stamp_offset_ms = float(values.get('stamp_offset_ms', ''))
                self.stamp_offset_sd_ms = float(values.get('stamp_offset_sd_ms', ''))
            except ValueError:
                pass  # 'none': no estimate yet
        if 'second_publishers' in values:
            words = values['second_publishers']
            words = '' if words == 'none' else words
            if words != self.newcomers.get(node, ''):
                self.news = True
            if words:
                self.newcomers[node] = words
            else:
                self.newcomers.pop(node, None)
        for key, count in values.items():
            if not key.startswith('rejected['):
                continue
            try:
                count = int(count)
            except ValueError:
                continue
            if count > self._rejected.get((node, key), 0):
                self._error(f'{node} {key[len("rejected["):-1]} ({count} so far)')
            self._rejected[(node, key)] = count
        if level >= 1 and message:
            self._error(f'{node}: {message}')

    def _error(self, text):
        self.last_error, self.last_error_at = text, self.clock()

    def line(self) -> str:
        """Return the status line now."""
        from ibvs_common.servo_codes import ServoStatus
        now = self.clock()
        if self.code is None:
            servo = 'servo: no status yet'
        else:
            try:
                name = ServoStatus(self.code).name
                servo = f'servo {self.code} {name}'
            except ValueError:
                name, servo = None, f'servo {self.code} (unknown code)'
            words = HOLD_WORDS.get(name)
            if name == 'HOLD_SECOND_PUBLISHER' and self.newcomers:
                servo += f' ({words})'  # who: named next
            elif words is not None and not self.detail.startswith(words):
                servo += f' ({words})'  # the code comes at once, /diagnostics once a second
            elif self.detail and self.detail != 'ok':
                servo += f' ({self.detail})'
        error = (f'{self.last_error} ({now - self.last_error_at:.0f} s ago)'
                 if self.last_error_at is not None else 'none')
        seen = {}  # each topic's words once, naming who saw them
        for node, words in sorted(self.newcomers.items()):
            for item in words.split('; '):
                seen.setdefault(item, []).append(node)
        second = ''.join(f' | {words} (seen by {", ".join(nodes)})'
                         for words, nodes in seen.items())
        errors = ''
        image, whose = self.image_error()
        if image is not None:
            errors += f' | image error {image:.3f} px{whose}'
        if self.position_error_m is not None:
            errors += (f' | pose error {self.position_error_m * 1e3:.3f} mm, '
                       f'{self.axis_error_deg:.3f} deg')
        if self.stamp_offset_ms is not None:
            held = '' if self.stamp_offset_state == 'estimating' else \
                f' ({self.stamp_offset_state})'
            errors += (f' | stamp offset {self.stamp_offset_ms:.1f} +- '
                       f'{self.stamp_offset_sd_ms:.1f} ms{held}')
        dry = 'DRY RUN | ' if self.dry_run else ''
        return (f'[{now - self.started:6.0f} s] {dry}{servo}{second}{errors} | frames used '
                f'{len(self.frames)} | last error: {error}')


def session_dir(root: Path = CELL_DIR) -> Path:
    """Return a new folder for a session's parameters and logs: ``root/<date-time>``."""
    return root / time.strftime('%Y%m%d-%H%M%S')


@contextmanager
def _session_folder(out_dir: Path, procs: Sequence[Any]) -> Iterator[tuple[Path, Any]]:
    """
    Hold a session's folder (:func:`.output_dir.claim`); yield its params.yaml and the claim.

    Claimed once the cell's domain is held, so that a refused start (its domain busy, the
    folder refused) makes no folder; one this start made is removed again, with the
    ``params.yaml``, the empty ``logs/`` and the marker it wrote there, when no node
    started (``procs``, the list the nodes' processes are appended to, still empty: the
    check failed, or SIGINT came during it).
    """
    from . import output_dir
    claimed = output_dir.claim(out_dir)
    try:
        (out_dir / 'logs').mkdir(exist_ok=True)
        yield out_dir / 'params.yaml', claimed
    finally:
        claimed.release(None if procs else ('params.yaml', 'logs'))


def run_cell(params: Mapping[str, Any], out_dir: str | Path, controller: str = 'forward_command',
             camera_name: str = DEFAULT_CAMERA, controller_name: str | None = None,
             check_timeout_s: float = CHECK_TIMEOUT_S,
             print_line: Callable[[str], None] = print, live: bool = False,
             teach: 'Recorded | None' = None) -> int:
    """
    Check the cell's topics, start the four nodes, show their status until SIGINT; stop.

    ``params``: :func:`cell_parameters`'s (``dry_run`` true: :func:`expectations` wants no
    command subscriber, the status line says DRY RUN). ``teach``: a recorded teach
    (:class:`.teach.Recorded`) whose pair this process publishes latched (module docstring,
    step 2).
    Returns the exit code: 0 after SIGINT with every process stopped,
    :data:`EXIT_CHECK_FAILED` when the check fails (nothing started),
    :data:`runner.EXIT_NODE_DIED` when a node exits, 130 after a SIGINT during the check
    (nothing started). ``live``: rewrite one status line in place (a terminal) instead of a
    line each second. Raises :class:`domains.DomainBusy` when another run holds the cell's
    domain.
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PolygonStamped
    from ibvs_bringup.recorder import Recorder
    from ibvs_bringup.supervision import NodeDied, NodeProcess, stop_all
    from ibvs_common import dds
    from ibvs_common.conversions import stamp_ns
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import TimeReference
    from std_msgs.msg import Int8
    import yaml

    from . import analysis, runner

    out_dir = Path(out_dir)
    log_dir = out_dir / 'logs'
    node_remaps = remaps(controller, camera_name, controller_name)
    expected = expectations(params, controller, camera_name, controller_name)
    if domains.domain_id() is None:
        os.environ[domains.DOMAIN_ENV] = '0'  # ROS's default: the cell's, not a free one
    procs = []
    recorder = None
    info = {'session': 'ibvs cell', 'interrupted': False, 'dry_run': bool(params.get(
        'dry_run', False)), 'controller': controller, 'camera_name': camera_name}
    with runner.interruptible(deferred=True) as stop, domains.held() as (domain, _), \
            _session_folder(out_dir, procs) as (params_file, claimed):
        stopped = stop.is_set if stop is not None else (lambda: False)
        params_file = scenario.write_parameters(dict(params), params_file)
        dds.configure()
        context = rclpy.context.Context()
        rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node('ibvs_cell', context=context, parameter_overrides=[])
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        started = time.monotonic()
        try:
            if teach is not None:  # ours before the check: the check then finds it
                teach_pubs = teach.publish(node)
                print_line(f'publishing the taught pair of {teach.folder} latched on '
                           f'{teach_pubs[0].topic_name} and {teach_pubs[1].topic_name}')
            print_line(f"ibvs cell: ROS_DOMAIN_ID {domain}; checking the cell's topics (up to "
                       f'{check_timeout_s:g} s): ' + ', '.join(e.topic for e in expected))
            found = wait_for_topics(node, expected, check_timeout_s, stopped=stopped)
            if teach is not None:
                found += foreign_publishers(node, TEACH_TOPICS, (
                    'ibvs cell --teach publishes the taught pair itself: stop the other '
                    'publisher (a simulator standing in for the cell: -p '
                    'target_features_source:=model), or leave out --teach'))
            if not found:
                found, camera_line = wait_for_camera_info(
                    node, camera_name, CAMERA_INFO_TIMEOUT_S,
                    lambda s: executor.spin_once(timeout_sec=s), stopped=stopped)
                print_line(camera_line)
            if found:
                for text in found:
                    print(f'error: {text}', file=sys.stderr)
                print(f'error: the cell is not ready ({len(found)} problem(s)); no node '
                      'started', file=sys.stderr)
                return EXIT_CHECK_FAILED
            command = command_topic(controller, controller_name)
            others = node.get_publishers_info_by_topic(command)
            if others:
                print_line(f'warning: {command} already has publisher(s) '
                           f'{", ".join(i.node_name for i in others)}: they command the '
                           'same controller')
            board = StatusBoard(dry_run=info['dry_run'])
            node.create_subscription(Int8, contract.SERVO_STATUS,
                                     lambda m: board.servo(m.data), contract.LATCHED)
            node.create_subscription(TimeReference, contract.FRAME_LATENCY,
                                     lambda m: board.frame_used(stamp_ns(m.time_ref)),
                                     contract.RELIABLE)

            def on_diagnostics(msg):
                for s in msg.status:
                    level = s.level[0] if isinstance(s.level, bytes) else int(s.level)
                    board.diagnostics(s.name, level, s.message,
                                      {kv.key: kv.value for kv in s.values})

            node.create_subscription(DiagnosticArray, contract.DIAGNOSTICS, on_diagnostics, 10)
            for topic, qos, attr in ((contract.FEATURES, contract.RELIABLE, 'features_px'),
                                     (contract.TARGET_FEATURES, contract.LATCHED, 'target_px')):
                node.create_subscription(PolygonStamped, topic,
                                         lambda m, a=attr: board.take(a, m), qos)
            custom = {analysis.PARAMS_KEY: yaml.safe_dump(dict(params))}
            if teach is not None:
                custom[analysis.TEACH_KEY] = yaml.safe_dump(dict(teach.record))
            # The bag (module docstring, step 3): the nodes' topics from before they start;
            # /joint_states too (a cell's tool poses), on the wall clock without sim time.
            claimed.remove(SESSION_RESULTS)  # a previous session's, by name
            recorder = Recorder(out_dir / 'bag', include_per_step=True, custom_data=custom,
                                wall_clock=not params.get('use_sim_time', False),
                                context=context)
            executor.add_node(recorder)
            pose_of = PoseError(target_from_parameters(params))
            for name in CELL_NODES:
                spec = GRAPH.node(name)
                procs.append(NodeProcess(spec.package, name, params_file, log_dir,
                                         remap_args(node_remaps.get(name, {}))))
            print_line(f'started {", ".join(f"{p.name} (pid {p.proc.pid})" for p in procs)}; '
                       + (f'DRY RUN: references on {dry_run_topic(controller)}, nothing to the '
                          'arm; ' if info['dry_run'] else f'commands on {command}; ')
                       + f'logs in {log_dir}, the bag in {out_dir / "bag"}; Ctrl-C stops them '
                       'all')
            next_line = time.monotonic()
            while True:
                executor.spin_once(timeout_sec=0.05)
                if stopped():
                    raise KeyboardInterrupt
                dead = next((p for p in procs if p.poll() is not None), None)
                if dead is not None:
                    if live:
                        print_line('')
                    print(f'error: {NodeDied(dead.name, dead.poll(), dead.log_path)}; '
                          'stopping the others', file=sys.stderr)
                    return runner.EXIT_NODE_DIED
                news = board.take_news()
                if news or time.monotonic() >= next_line:
                    if time.monotonic() >= next_line:
                        next_line += STATUS_PERIOD_S
                    board.pose_error(*pose_of(recorder.latest.get(contract.JOINT_STATES)))
                    if live:
                        sys.stdout.write('\r\033[K' + board.line())
                        sys.stdout.flush()
                    else:
                        print_line(board.line())
                        sys.stdout.flush()  # to a file or a pipe (tee) as soon as to a tty
        except KeyboardInterrupt:
            if live:
                print_line('')
            if not procs:  # during the check: nothing to stop, and the session never ran
                print_line('SIGINT during the check: no node started')
                return 130
            print_line(f'SIGINT: stopping {", ".join(p.name for p in procs)}')
            codes = stop_all(procs, executor=executor)
            info['exit_codes'] = codes
            procs = []
            print_line('stopped: ' + ', '.join(f'{n} exit {c}' for n, c in codes.items()))
            return 0
        finally:
            if procs:
                info['exit_codes'] = stop_all(procs, executor=executor)
            if recorder is not None:
                info['wall_duration_s'] = time.monotonic() - started
                recorder.set_custom_data(analysis.RUN_KEY, yaml.safe_dump(info))
                recorder.close()
                print_line(f'wrote the bag {out_dir / "bag"} (ibvs analyse {out_dir / "bag"}: '
                           'its metrics and figures)')
            executor.shutdown()
            if recorder is not None:
                recorder.destroy_node()
            node.destroy_node()
            context.try_shutdown()


def check_seconds(text: str) -> float:
    """Return ``text`` as seconds >= 0 (argparse type of ``--check-timeout``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number of seconds') from None
    if not (value >= 0.0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f'{text}: expected a finite number of seconds >= 0')
    return value
