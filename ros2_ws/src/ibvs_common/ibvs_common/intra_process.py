"""
Intra-process delivery: a message between two nodes of one process handed over as an object.

What rclcpp's intra-process communication does for composed C++ nodes, for rclpy nodes,
which have none. The lockstep passes two messages per physics step between the simulator
and the joint controller (and a stereo pair per frame to the feature node); when they share
a process (:mod:`ibvs_bringup.compose`), DDS still serialises each message, queues it,
wakes the executor and deserialises it: most of what a step costs. Here a
publisher made with :func:`publisher` hands its message to the callbacks of the
subscriptions made with :func:`subscription` on the same topic in the same process, without
DDS.

The rule, one place (:meth:`Publisher.publish`): a message goes to the process's own readers
directly, and through DDS too when the publisher's DDS match count says another reader is
there (a reader in another process: ``ros2 topic echo``, Foxglove, the recorder). A local
reader's DDS subscription is a real one, so it then also receives the DDS copy; it drops
it (:class:`Reader`): each reader gets each message exactly once, the direct copy. Topic
names are the resolved ones, so remapping works as with DDS. A reader matched by DDS only
after a message was published (the first moments of a start) may miss it, as with DDS.

When. A message handed over is queued, not delivered inside ``publish``: the executor of
the process's spin loop (:func:`ibvs_common.node_main.spin_until_stopped`) delivers the
queue as a task (:meth:`LocalBus.drain`), in turns with its timers and DDS messages, so
callbacks run one at a time and never inside another, as an executor runs them. Delivery
happens only while such a loop is spinning the context (:attr:`LocalBus.active`);
otherwise (a test that spins its own executor) every message goes through DDS, as before.
Readers get the publisher's object itself: they must not modify it (no node of this
project does), and it must hold what DDS would carry (a float32 field a value that a
float32 holds: Python keeps a float64 there until the message is serialised;
:func:`ibvs_common.conversions.features_msg` rounds). The queue keeps every message (a
lockstep never has more than a few pending), in publication order. A DDS copy is known by
equality with a message of the same publisher handed over directly and not yet seen from
DDS; as DDS delivers one publisher's messages in order, a copy also settles the older ones
whose copies it lost. A message with a NaN, which equals nothing, would be delivered twice
(no node of this project publishes one).
"""

from collections import deque
from collections.abc import Callable
import time
from typing import Any, TYPE_CHECKING
import weakref

if TYPE_CHECKING:
    from rclpy.context import Context
    from rclpy.node import Node
    from rclpy.qos import QoSProfile
    from rclpy.subscription import Subscription

#: The longest one :meth:`LocalBus.drain` delivers before it gives the executor its turn
#: (s), so that timers (heartbeats, waiting logs), messages from DDS and stop requests are
#: served while a chain of direct messages (the lockstep between two frames) runs.
DRAIN_SLICE_S = 0.02
#: The most directly delivered messages of one publisher a reader remembers to drop their
#: DDS copies (a bound on memory if copies never came: they come in order, and each one
#: settles the older ones). A 20 ms slice of the lockstep publishes up to about 100
#: /joint_states when nothing renders.
EXPECTED_COPIES = 1024


class Reader:
    """A subscription's callback, fed directly and by DDS; it drops the DDS copies."""

    def __init__(self, callback: Callable[[Any], None]) -> None:
        """Wrap ``callback``, which takes the message only."""
        self.callback = callback
        #: Per publisher (its id), the messages delivered directly whose DDS copy has not
        #: come yet, oldest first.
        self.expected: dict[int, deque] = {}

    def expect(self, source: int, msg: Any) -> None:
        """Remember ``msg`` of publisher ``source``: its DDS copy is to be dropped."""
        pending = self.expected.get(source)
        if pending is None:
            pending = self.expected[source] = deque(maxlen=EXPECTED_COPIES)
        pending.append(msg)

    def from_dds(self, msg: Any) -> None:
        """Pass on ``msg`` from DDS unless it is the copy of one delivered directly."""
        for pending in self.expected.values():
            for i, sent in enumerate(pending):
                if sent == msg:
                    for _ in range(i + 1):  # the older ones' copies will not come now
                        pending.popleft()
                    return
        self.callback(msg)


class LocalBus:
    """The readers and the queue of direct messages of one rclpy context (module docstring)."""

    def __init__(self) -> None:
        """Start inactive, with no readers and an empty queue."""
        self._wake: Callable[[], None] | None = None
        self._draining = False
        self._failure: BaseException | None = None
        self._readers: dict[tuple[str, type], list[tuple['Node', 'Subscription', Reader]]] = {}
        self._queue: deque = deque()
        #: Messages delivered directly so far (for tests and benchmarks).
        self.delivered = 0

    @property
    def active(self) -> bool:
        """Whether an executor delivers the queue; publishers use DDS only while it is not."""
        return self._wake is not None

    def attach(self, wake: Callable[[], None]) -> None:
        """
        Start direct delivery: ``wake()`` makes the executor call :meth:`drain` soon.

        ``wake`` queues :meth:`drain_task` as an executor task
        (:func:`ibvs_common.node_main.spin_until_stopped`; rclpy's EventsExecutor has no
        guard conditions): the drain then takes its turn in the executor's queue with the
        timers and the messages from DDS.
        """
        self._wake = wake

    def detach(self) -> None:
        """Stop direct delivery; what is still queued is dropped."""
        self._wake = None
        self._queue.clear()
        self._failure = None

    def add(self, node: 'Node', sub: 'Subscription', msg_type: type, reader: Reader) -> None:
        """Register ``sub`` of ``node`` (its callback ``reader``) for direct delivery."""
        self._readers.setdefault((sub.topic_name, msg_type), []).append((node, sub, reader))

    def readers(self, topic: str, msg_type: type) -> list:
        """Return the live readers of ``topic`` (a destroyed subscription is forgotten)."""
        readers = self._readers.get((topic, msg_type))
        if not readers:
            return []
        live = [r for r in readers if r[1] in r[0].subscriptions]
        if len(live) != len(readers):
            self._readers[(topic, msg_type)] = live
        return live

    @property
    def pending(self) -> int:
        """Return the number of messages waiting for :meth:`drain`."""
        return len(self._queue)

    def post(self, readers: list, msg: Any, copied_from: int | None = None) -> None:
        """
        Queue ``msg`` for each of ``readers``.

        ``copied_from``: the id of its publisher when DDS brings them a copy too.
        """
        idle = not self._queue and not self._draining
        for _, _, reader in readers:
            self._queue.append((reader.callback, msg))
            if copied_from is not None:
                reader.expect(copied_from, msg)
        if idle:
            self._wake()

    def drain(self, slice_s: float = DRAIN_SLICE_S) -> None:
        """
        Run the queued deliveries, and those they queue, for at most ``slice_s``.

        What is left then waits for the executor's next turn (a wake goes to the back of
        its queue), so that a chain of direct messages (the lockstep between two frames)
        does not hold up timers and DDS messages for longer than ``slice_s``.
        """
        deadline = time.perf_counter() + slice_s
        queue = self._queue
        self._draining = True
        try:
            while queue and time.perf_counter() <= deadline:
                callback, msg = queue.popleft()
                callback(msg)
                self.delivered += 1
        finally:
            self._draining = False
        if queue and self._wake is not None:
            self._wake()

    def drain_task(self) -> None:
        """
        :meth:`drain` as the executor's task: an exception is kept for :meth:`raise_failure`.

        An exception out of an rclpy task ends the process with a segmentation fault
        (EventsExecutor, Jazzy); out of the spin loop it is the traceback and exit code of
        any callback's exception, and a KeyboardInterrupt (a second stop signal,
        :class:`ibvs_common.node_main.StopRequest`) stops the node as it would elsewhere.
        """
        try:
            self.drain()
        except BaseException as exc:  # handed on unchanged by raise_failure
            self._failure = exc

    def raise_failure(self) -> None:
        """Raise what the last :meth:`drain_task` raised, if anything (in the spin loop)."""
        failure, self._failure = self._failure, None
        if failure is not None:
            raise failure


_BUSES: 'weakref.WeakKeyDictionary[Context, LocalBus]' = weakref.WeakKeyDictionary()


def bus_of(context: 'Context') -> LocalBus:
    """Return the :class:`LocalBus` of ``context`` (made on first use)."""
    bus = _BUSES.get(context)
    if bus is None:
        bus = _BUSES[context] = LocalBus()
    return bus


class Publisher:
    """
    An rclpy publisher that hands its messages to this process's readers directly.

    They go through DDS too when other processes read them (module docstring).
    """

    def __init__(self, node: 'Node', msg_type: type, topic: str,
                 qos: 'QoSProfile | int') -> None:
        """Create the rclpy publisher of ``topic`` on ``node``."""
        #: The rclpy publisher (its DDS match count, its name, destruction).
        self.rclpy = node.create_publisher(msg_type, topic, qos)
        self.topic_name = self.rclpy.topic_name
        #: The message type, as an rclpy publisher's ``msg_type``.
        self.msg_type = self._type = msg_type
        self._bus = bus_of(node.context)

    def publish(self, msg: Any) -> None:
        """Hand ``msg`` to the local readers, and to DDS if it has other readers."""
        bus = self._bus
        readers = bus.readers(self.topic_name, self._type) if bus.active else ()
        if not readers:
            self.rclpy.publish(msg)
            return
        others = self.rclpy.get_subscription_count() > len(readers)
        bus.post(readers, msg, id(self) if others else None)
        if others:
            self.rclpy.publish(msg)

    def get_subscription_count(self) -> int:
        """Return the DDS match count, the local readers included."""
        return self.rclpy.get_subscription_count()


def publisher(node: 'Node', msg_type: type, topic: str, qos: 'QoSProfile | int') -> Publisher:
    """Return a :class:`Publisher` of ``topic`` on ``node`` (``node.create_publisher``'s)."""
    return Publisher(node, msg_type, topic, qos)


def subscription(node: 'Node', msg_type: type, topic: str, callback: Callable[[Any], None],
                 qos: 'QoSProfile | int') -> 'Subscription':
    """
    Return an rclpy subscription of ``node``, registered for direct delivery as well.

    ``callback`` takes the message only. Destroy it with ``node.destroy_subscription``, as
    any: the bus forgets it then.
    """
    reader = Reader(callback)
    sub = node.create_subscription(msg_type, topic, reader.from_dds, qos)
    bus_of(node.context).add(node, sub, msg_type, reader)
    return sub
