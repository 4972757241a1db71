"""
The node kit: what every node of the graph opens, waits for and assembles, written once.

- :func:`publisher` and :func:`subscription`: the one way a node opens a topic. The QoS
  picks the transport by rclcpp's rule (:func:`direct`): a volatile, keep-last topic is
  handed to this process's readers as an object (:mod:`.intra_process`) and goes through
  DDS as well when another process reads it; a transient-local one goes through DDS only.
  Each topic opened is recorded (:class:`Endpoint`, :func:`opened`), so that what a graph
  reads and writes can be read from the nodes themselves.
- :func:`config`: a node's typed configuration (:class:`.params.ParamConfig`): its
  parameters declared with their ranges, checked, and its rules between parameters run.
- :class:`WaitReporter`: the "waiting for" log, once a second while the node made no
  progress, naming what is missing.
- :class:`Inputs`: a node's stamped inputs: the one stamp rule, the stamp order per topic,
  each message read, a rejection counted on /diagnostics under the topic.
- :func:`forget_on_back`: the stamp orders and buffers a node keeps, forgotten when its
  clock jumps back, so that fresh inputs are taken again.
- :class:`PublisherWatch`: who publishes on the node's inputs and commands, looked at while
  it runs; a second publisher named on /diagnostics (the rule: :mod:`.publishers`).
- :class:`StereoCameraInput`: both CameraInfo and the camera pose (the ``camera_pose``
  parameter or /stereo/pose), checked, rejected with a reason counted on /diagnostics, and
  a :class:`ibvs_model.StereoCamera` once they describe one.
"""

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any, Mapping, Protocol, TYPE_CHECKING, TypeVar
import weakref

from geometry_msgs.msg import PoseStamped
from rclpy.clock import Clock, ClockType
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile
from sensor_msgs.msg import CameraInfo

from . import contract, intra_process, publishers
from .conversions import (camera_from_msgs, check_camera_info, InputError, pose_stamped,
                          read_camera_pose, read_stamp, StampOrder)
from .params import declare, ParamConfig
from .shared_params import camera_pose_from
from .sim_time import clock_watch

if TYPE_CHECKING:
    from ibvs_model import StereoCamera
    from rclpy.node import Node


class Rejections(Protocol):
    """What the input assemblers need of a node's diagnostics (``diagnostics.Diagnostics``)."""

    def reject(self, source: str, reason: str, detail: str = '') -> None:
        """Log and count one rejected message of ``source``."""


#: Steady-clock period of the "waiting for" log (s).
WAIT_LOG_S = 1.0
#: Steady-clock period of a node's look at who publishes on its topics (s)
#: (:class:`PublisherWatch`): a newcomer is named within it, once the graph has it.
PUBLISHERS_CHECK_S = 0.25
PUBLISHES, SUBSCRIBES = 'publishes', 'subscribes'


def qos_profile(qos: QoSProfile | int) -> QoSProfile:
    """Return ``qos`` as a profile (an int is a keep-last depth, as rclpy takes it)."""
    return qos if isinstance(qos, QoSProfile) else QoSProfile(depth=qos)


def direct(qos: QoSProfile | int) -> bool:
    """
    Return whether a topic of ``qos`` is delivered directly within a process.

    rclcpp's rule (rclcpp jazzy 985e320, ``rclcpp/include/rclcpp/publisher.hpp``
    L173-191, ``subscription.hpp`` L157-168): intra-process delivery needs keep-last
    history and a depth above 0. rclcpp (Jazzy) keeps a buffer for transient-local
    publishers to serve late joiners from; :mod:`.intra_process` has none, so a
    transient-local topic goes through DDS only, as before Jazzy, when rclcpp refused it.
    """
    p = qos_profile(qos)
    return (p.history == HistoryPolicy.KEEP_LAST and p.depth > 0
            and p.durability == DurabilityPolicy.VOLATILE)


@dataclass(frozen=True)
class Endpoint:
    """One topic a node opened: the node, the resolved topic, its type, direction and QoS."""

    node: str
    topic: str
    msg_type: str
    direction: str
    qos: QoSProfile = field(compare=False)  # unhashable; ``direct`` says what it decides
    direct: bool = False


#: Per node, the topics it opened, by (topic, direction); a node is forgotten when it goes.
_REGISTRY: 'weakref.WeakKeyDictionary[Node, dict[tuple[str, str], Endpoint]]' = \
    weakref.WeakKeyDictionary()


def _record(node: 'Node', topic: str, msg_type: type, direction: str,
            qos: QoSProfile | int) -> None:
    package = msg_type.__module__.split('.')[0]
    profile = qos_profile(qos)
    _REGISTRY.setdefault(node, {})[(topic, direction)] = Endpoint(
        node.get_fully_qualified_name(), topic, f'{package}/msg/{msg_type.__name__}',
        direction, profile, direct(profile))


def opened(node: 'Node | str | None' = None) -> list[Endpoint]:
    """
    Return the topics opened by the live nodes of this process.

    ``node``: only those of this node, or of the nodes of this fully qualified name.
    """
    if node is not None and not isinstance(node, str):
        return list(_REGISTRY.get(node, {}).values())
    ends = [e for topics in list(_REGISTRY.values()) for e in topics.values()]
    return [e for e in ends if node is None or e.node == node]


def publisher(node: 'Node', msg_type: type, topic: str, qos: QoSProfile | int) -> Any:
    """
    Return a publisher of ``topic`` on ``node``, direct where :func:`direct` allows.

    Either an :class:`.intra_process.Publisher` or an rclpy publisher: both have
    ``publish``, ``topic_name`` and ``get_subscription_count``.
    """
    if direct(qos):
        pub = intra_process.publisher(node, msg_type, topic, qos)
    else:
        pub = node.create_publisher(msg_type, topic, qos)
    _record(node, pub.topic_name, msg_type, PUBLISHES, qos)
    return pub


def subscription(node: 'Node', msg_type: type, topic: str, callback: Callable[[Any], None],
                 qos: QoSProfile | int, raw: bool = False) -> Any:
    """
    Return an rclpy subscription of ``topic`` on ``node``, direct where allowed.

    ``raw``: the callback gets the serialized bytes (rclpy's ``raw=True``), DDS only (a
    transient-local ``qos``; a direct message is an object): :mod:`.cdr`.
    """
    if raw and direct(qos):
        raise ValueError(f'{topic}: a raw subscription needs a topic that goes through DDS')
    if direct(qos):
        sub = intra_process.subscription(node, msg_type, topic, callback, qos)
    else:
        sub = node.create_subscription(msg_type, topic, callback, qos, raw=raw)
    _record(node, sub.topic_name, msg_type, SUBSCRIBES, qos)
    return sub


Config = TypeVar('Config', bound=ParamConfig)


def config(node: 'Node', cls: type[Config], **others: Any) -> Config:
    """
    Return the typed configuration ``cls`` of ``node``, its parameters declared and checked.

    Each Param field of ``cls`` is declared on ``node`` with its descriptor (units, range)
    and checked (:func:`.params.declare`, ParameterError naming it), the class's ``RULES``
    between parameters run (:func:`.params.check_rules`); ``others`` sets the fields
    without a Param.
    """
    values = declare(node, cls.params(), getattr(cls, 'RULES', ()))
    return cls.from_values(values, **others)


class WaitReporter:
    """
    Log what the node waits for, once every ``period_s`` (steady clock) without progress.

    ``describe()`` returns the line to log, or None (or '') when nothing is missing; the
    node calls :meth:`progress` whenever it moved on (a frame answered, a step taken). The
    first look comes after a full period of silence, as the node has just started.
    """

    def __init__(self, node: 'Node', describe: Callable[[], str | None],
                 period_s: float = WAIT_LOG_S) -> None:
        """Look every ``period_s`` on the steady clock (sim time may stand still)."""
        self._node = node
        self._describe = describe
        self._progress = True
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.timer = node.create_timer(period_s, self.tick, clock=self._steady)

    def progress(self) -> None:
        """Note that the node moved on: the next look says nothing."""
        self._progress = True

    def tick(self) -> None:
        """Look once: log the line when there is one and no progress since the last look."""
        line = self._describe()
        if line and not self._progress:
            self._node.get_logger().info(line)
        self._progress = False


class PublisherWatch:
    """
    Who publishes on a node's inputs and commands, looked at while it runs.

    Every node has one, made by its :class:`.diagnostics.Diagnostics`. Every ``period_s``
    of the steady clock (it goes on while sim time stands still) the node reads the graph
    (``get_publishers_info_by_topic``): each topic it subscribes through this kit
    (:func:`opened`, looked up at each look, so that a topic opened later is watched too)
    is to have one publisher, the first one seen
    (:class:`.publishers.ExpectedPublishers` with a count: a cell's driver's or camera's
    node name is not the graph's to know), and each topic it commands something on
    (:meth:`command`) none but the node's own. It only reads: a lockstep's numbers
    are the same with it. A newcomer is logged as it comes (WARN) and when it went (INFO),
    counted (``second_publishers_seen`` on /diagnostics, one for each publisher that
    came), named while it is there (``second_publishers``, and the node's status at least
    WARN: :meth:`.diagnostics.Diagnostics.alert`); on each change each callback given to
    :meth:`command` is called with {topic: newcomers} of the topics that have one, then
    /diagnostics is published at once.

    Parameters
    ----------
    node : rclpy.node.Node
        The node whose topics are watched.
    diagnostics : ibvs_common.diagnostics.Diagnostics
        Its diagnostics.
    period_s : float
        Steady-clock seconds between two looks.

    """

    #: The key of the alert and of the value that names the newcomers.
    KEY = 'second_publishers'

    def __init__(self, node: 'Node', diagnostics: Any,
                 period_s: float = PUBLISHERS_CHECK_S) -> None:
        """Start the timer; nothing seen yet."""
        self._node = node
        self._diag = diagnostics
        self._on_change: list[Callable[[dict], None]] = []
        #: {topic: its expected publishers}: the commands, and the inputs seen so far.
        self.expected: dict[str, publishers.ExpectedPublishers] = {}
        #: {topic: newcomers} as of the last look.
        self.found: dict[str, list[publishers.Publisher]] = {}
        self.seen = 0
        self.timer = node.create_timer(period_s, self.look,
                                       clock=Clock(clock_type=ClockType.STEADY_TIME))

    def command(self, topic: str, on_change: Callable[[dict], None] | None = None) -> None:
        """
        Expect the node's own publisher alone on ``topic`` (resolved: a ``topic_name``).

        ``on_change(found)``: called on each change of the newcomers, of any topic.
        """
        self.expected[topic] = publishers.ExpectedPublishers(
            0, own=self._node.get_fully_qualified_name())
        if on_change is not None:
            self._on_change.append(on_change)

    def look(self) -> dict[str, list[publishers.Publisher]]:
        """Look at the graph once; report a change; return {topic: newcomers}."""
        for e in opened(self._node):
            if e.direction == SUBSCRIBES and e.topic not in self.expected:
                self.expected[e.topic] = publishers.ExpectedPublishers(1)
        found = {}
        for topic, expected in self.expected.items():
            new = expected.look(publishers.from_infos(
                self._node.get_publishers_info_by_topic(topic)))
            if new:
                found[topic] = new
        if found != self.found:
            self._report(found)
        return found

    def _report(self, found):
        log = self._node.get_logger()
        for topic, new in found.items():
            came = [p for p in new if p not in self.found.get(topic, ())]
            self.seen += len(came)
            if came:
                log.warn(f'{publishers.describe(topic, came)} (the graph expects '
                         f"{self.expected[topic].count} besides this node's own; "
                         f'known: {", ".join(self.expected[topic].known) or "none"})')
        for topic in self.found:
            if topic not in found:
                log.info(f'{topic}: the second publisher is gone')
        self.found = found
        words = '; '.join(publishers.describe(t, new) for t, new in found.items())
        self._diag.alert(self.KEY, words or None)
        self._diag.update(second_publishers=words or 'none', second_publishers_seen=self.seen)
        for callback in self._on_change:
            callback(found)
        self._diag.publish()


class Inputs:
    """
    A node's stamped inputs: the stamp rule, the order per topic, rejections counted.

    :meth:`read` takes a message's stamp by the one stamp rule
    (:func:`.conversions.read_stamp`, against ``now_ns()`` and ``lead_ns``), checks it
    against the topic's order (:class:`.conversions.StampOrder`: a duplicate or a stamp that
    went back) where ``ordered``, then reads the message with ``reader``; an
    :class:`.conversions.InputError` from any of them is counted on ``diagnostics`` under
    the topic (docs/design.md §3). A message read whole takes its stamp (``take``), so that
    a message refused for its values leaves the stamp to a good one.
    """

    def __init__(self, diagnostics: Rejections, now_ns: Callable[[], int],
                 lead_ns: int) -> None:
        """Count on ``diagnostics``; ``now_ns()`` is the newest time the node knows."""
        self._diag = diagnostics
        self._now_ns = now_ns
        self.lead_ns = lead_ns
        self.order = StampOrder()

    def read(self, topic: str, msg: Any, reader: Callable[[Any], Any] | None = None,
             ordered: bool = True, take: bool = True) -> tuple[int, Any] | None:
        """Return (stamp ns, ``reader(msg)`` or None), or None: rejected and counted."""
        try:
            t_ns = read_stamp(msg.header.stamp, self._now_ns(), self.lead_ns)
            if ordered:
                self.order.check(topic, t_ns)
            value = None if reader is None else reader(msg)
        except InputError as exc:
            self.reject(topic, exc)
            return None
        if ordered and take:
            self.order.take(topic, t_ns)
        return t_ns, value

    def reject(self, topic: str, exc: InputError, note: str = '') -> None:
        """Count ``exc`` under ``topic`` (``note`` appended to its detail)."""
        self._diag.reject(topic, exc.reason, exc.detail + note)

    def forget(self) -> None:
        """Forget every topic's stamp order (the clock jumped back: :func:`forget_on_back`)."""
        self.order.forget()


class Forgets(Protocol):
    """What keeps stamps of the node's time line (an order, a buffer) and can drop them."""

    def forget(self) -> None:
        """Forget every stamp kept."""


def forget_on_back(node: 'Node', *holders: Forgets) -> None:
    """
    Make each of ``holders`` forget its stamps whenever ``node``'s clock jumps back.

    The one way a node keeps its stamp orders through a time jump: a restarted simulator
    (its /clock at 0 again) or an NTP step would otherwise leave every fresh input refused
    as older than the old time line's newest ('stamp went back', 'stale stamp') for as long
    as the jump (:class:`.sim_time.ClockWatch`, which also logs the jump).
    """
    clock_watch(node).on_back(*(lambda _from, _to, h=h: h.forget() for h in holders))


class StereoCameraInput:
    """
    Both CameraInfo and the camera pose, assembled into a StereoCamera.

    Subscribes to /stereo/{left,right}/camera_info (:data:`.contract.CAMERA_INFO`) and,
    unless the ``camera_pose`` parameter gives the hand-eye result, to /stereo/pose
    (latched). A CameraInfo that cannot be a lens (:func:`.conversions.check_camera_info`)
    and a pose looking away from the robot (:func:`.conversions.read_camera_pose`) are
    rejected, counted under the topic's resolved name. Once all three are there, and each
    time one changes, the camera is built (:func:`.conversions.camera_from_msgs`): lenses
    that disagree are rejected under the CameraInfo that came last (docs/design.md §3)
    and the camera is not built until they change. ``on_camera(camera, source)`` is
    called with each camera built (None when the build failed, :attr:`error` says why),
    ``on_input(source)`` after each accepted message. After :meth:`hold` (a model built
    once, for good), a CameraInfo that differs from the one it was built from is rejected
    ('camera_info changed') and later poses are ignored.
    """

    SIDES = ('left', 'right')

    def __init__(self, node: 'Node', diagnostics: Rejections, values: Mapping[str, Any],
                 on_camera: Callable[['StereoCamera | None', str], None],
                 on_input: Callable[[str], None] | None = None) -> None:
        """Open the inputs on ``node``; ``values`` holds the ``camera_pose`` parameter."""
        self._diag = diagnostics
        self._on_camera = on_camera
        self._on_input = on_input
        self.infos: dict[str, CameraInfo] = {}
        self.pose: PoseStamped | None = None
        self.camera: 'StereoCamera | None' = None
        self.error: InputError | ValueError | None = None
        self.held = False
        self.last_side = 'left'  # the lens whose CameraInfo came last
        self._key = None
        #: The resolved topic of each input (the ZED wrapper's under a remap).
        self.topics = {side: subscription(node, CameraInfo, topic, partial(self.on_info, side),
                                          contract.CAMERA_INFO).topic_name
                       for side, topic in zip(self.SIDES, (contract.LEFT_INFO,
                                                           contract.RIGHT_INFO))}
        self.topics['pose'] = contract.STEREO_POSE
        calibrated = camera_pose_from(values)
        if calibrated is None:
            subscription(node, PoseStamped, contract.STEREO_POSE, self.on_pose,
                         contract.LATCHED)
        else:  # a hand-eye calibration's result, as a parameter
            self.pose = pose_stamped(calibrated, 0)

    def missing(self) -> list[str]:
        """Return the topics of the inputs not here yet, left, right, pose."""
        return [self.topics[side] for side in self.SIDES if side not in self.infos] \
            + ([contract.STEREO_POSE] if self.pose is None else [])

    def hold(self) -> None:
        """Keep the inputs as they are: differing CameraInfo is refused from now on."""
        self.held = True

    def forget_infos(self) -> None:
        """Drop both CameraInfo (a model built from them failed): await a new pair."""
        self.infos.clear()
        self._key = None

    def on_info(self, side: str, msg: CameraInfo) -> None:
        """Take one lens's CameraInfo (``side``: 'left' or 'right')."""
        topic = self.topics[side]
        try:
            check_camera_info(msg)
        except InputError as exc:
            self._diag.reject(topic, exc.reason, exc.detail)
            return
        if self.held:
            built = self.infos[side]
            if (msg.width, msg.height, tuple(msg.p)) != (built.width, built.height,
                                                         tuple(built.p)):
                self._diag.reject(topic, 'camera_info changed',
                                  'the camera model is built once, from the first usable '
                                  'pair; this one differs from it')
            return
        self.infos[side] = msg
        self.last_side = side
        self._update(topic)

    def on_pose(self, msg: PoseStamped) -> None:
        """Take the camera pose from /stereo/pose."""
        try:
            read_camera_pose(msg)
        except InputError as exc:
            self._diag.reject(contract.STEREO_POSE, exc.reason, exc.detail)
            return
        if self.held:
            return
        self.pose = msg
        self._update(contract.STEREO_POSE)

    def _update(self, source: str) -> None:
        """Build the camera if the inputs are complete and changed; ``source`` came last."""
        if len(self.infos) == 2 and self.pose is not None:
            left, right = self.infos['left'], self.infos['right']
            pos, rot = self.pose.pose.position, self.pose.pose.orientation
            key = (tuple(left.p), tuple(right.p), left.header.frame_id,
                   right.header.frame_id, left.width, left.height, right.width,
                   right.height, pos.x, pos.y, pos.z, rot.x, rot.y, rot.z, rot.w)
            if key != self._key:
                self._key = key
                try:
                    self.camera, self.error = camera_from_msgs(left, right, self.pose), None
                except ValueError as exc:  # the lenses disagree
                    self.camera, self.error = None, exc
                    self._diag.reject(self.topics[self.last_side],
                                      getattr(exc, 'reason', 'bad camera'),
                                      getattr(exc, 'detail', str(exc)))
                self._on_camera(self.camera, source)
        if self._on_input is not None:
            self._on_input(source)
