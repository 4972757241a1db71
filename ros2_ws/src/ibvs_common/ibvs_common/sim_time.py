"""
Sim time from /clock that one bad publisher cannot stop, and the node's idea of "now".

rclpy's own :class:`rclpy.time_source.TimeSource` turns each /clock message into a
:class:`rclpy.time.Time` inside the executor; a message with a negative ``sec`` raises
``ValueError: Seconds value must not be negative`` there, the executor lets it out of
``spin_once`` and the process ends. Every node of the graph runs on sim time, so one bad
publisher on the domain would take the whole graph down. :class:`GuardedTimeSource` rejects
such a message (negative seconds, or ``nanosec`` of a second or more) before rclpy sees it,
reports it to a callback (:class:`ibvs_common.diagnostics.Diagnostics` counts it on
/diagnostics and logs it, throttled) and keeps the last good time.

A node's clock may also jump back: a simulator restarted under a running graph starts its
/clock at 0 again, and on a real cell (``use_sim_time`` false) an NTP step moves the system
clock. Every stamp order a node keeps (:class:`ibvs_common.conversions.StampOrder`, the
buffers of :mod:`.sync`, an input watch) would then refuse each fresh input as older than
the newest one of the old time line, for as long as the jump. :class:`ClockWatch`, one a
node (:func:`clock_watch`), sees the jump, from rclpy's time-jump callback (a /clock set
back) or from a reading of the clock earlier than the newest one read (the system clock,
which rcl does not watch), and calls what each of the node's orders registered
(:meth:`ClockWatch.on_back`) to forget the old time line. It also keeps the wall time at
which /clock last moved, so that a node can tell a stopped simulator from a quiet graph
(:meth:`ClockWatch.stalled_s`).
"""

from collections import deque
from collections.abc import Callable
import statistics
import time
from typing import Optional, Tuple, TYPE_CHECKING
import weakref

from rclpy.clock import JumpThreshold, TimeJump
from rclpy.duration import Duration
from rclpy.time_source import TimeSource

from . import contract
from .timing import NS_PER_S

if TYPE_CHECKING:
    from rclpy.node import Node
    from rosgraph_msgs.msg import Clock

#: The least wall time (s) without a /clock that moved time, for :meth:`ClockWatch.stalled`
#: (a simulator process that a loaded machine stalls for a second or two is not stopped).
CLOCK_STALL_MIN_S = 5.0
#: ... and the bound in wall intervals between two /clock messages (their median, measured).
CLOCK_STALL_INTERVALS = 20
#: How many of the newest wall intervals between /clock messages the median is taken of.
CLOCK_INTERVAL_SAMPLES = 32


class ClockWatch:
    """
    A node's clock as its readers see it: its jumps back, and when /clock last moved.

    Parameters
    ----------
    warn : callable, optional
        Called with one line for each jump back (the node's logger's ``warn``).
    steady : callable
        The wall clock (s) that measures how long /clock stood still.

    """

    def __init__(self, warn: Callable[[str], None] | None = None,
                 steady: Callable[[], float] = time.monotonic) -> None:
        """Start with no reading, no jump and no /clock seen."""
        self._warn = warn
        self._steady = steady
        self._forget: list[Callable[[int, int], None]] = []
        #: The newest clock reading (ns), None before the first.
        self.newest_ns: int | None = None
        #: Jumps back seen, and the last one as (from ns, to ns).
        self.jumps_back = 0
        self.last_jump: tuple[int, int] | None = None
        self._clock_ns: int | None = None
        self._moved_at: float | None = None
        self._intervals: deque[float] = deque(maxlen=CLOCK_INTERVAL_SAMPLES)
        self._handle = None

    def on_back(self, *forget: Callable[[int, int], None]) -> None:
        """Call each of ``forget(from_ns, to_ns)`` on every jump back, in this order."""
        self._forget.extend(forget)

    def read(self, now_ns: int) -> int:
        """Note a reading ``now_ns`` of the clock (a jump back if before the newest); return it."""
        if self.newest_ns is not None and now_ns < self.newest_ns:
            self.jumped(self.newest_ns, now_ns)
        else:
            self.newest_ns = now_ns
        return now_ns

    def jumped(self, from_ns: int, to_ns: int) -> None:
        """Take a jump back from ``from_ns`` to ``to_ns``: every registered order forgets."""
        self.jumps_back += 1
        self.last_jump = (int(from_ns), int(to_ns))
        self.newest_ns = int(to_ns)
        if self._warn is not None:
            self._warn(f'the clock jumped back from {from_ns * 1e-9:.3f} s to '
                       f'{to_ns * 1e-9:.3f} s: every stamp order starts again')
        for forget in list(self._forget):
            try:
                forget(int(from_ns), int(to_ns))
            except Exception as exc:  # one bad forget must not keep the others' orders
                if self._warn is not None:
                    self._warn(f'forgetting the old time line failed: {exc!r}')

    def on_jump(self, now_ns: int, jump: TimeJump) -> None:
        """Take rclpy's time jump (the clock now reads ``now_ns``): a jump back if negative."""
        delta = jump.delta.nanoseconds
        if delta < 0:
            self.jumped(max(now_ns - delta, self.newest_ns or 0), now_ns)

    def clock_message(self, t_ns: int) -> None:
        """Note a /clock message of time ``t_ns``: one that moves time says sim time runs."""
        if t_ns == self._clock_ns:
            return
        now = self._steady()
        if self._moved_at is not None:
            self._intervals.append(now - self._moved_at)
        self._clock_ns, self._moved_at = t_ns, now

    def stalled_s(self) -> float | None:
        """Return the wall time (s) since /clock last moved time, None before it first did."""
        return None if self._moved_at is None else self._steady() - self._moved_at

    def stall_bound_s(self) -> float:
        """
        Return the wall time (s) without /clock after which sim time is taken as stopped.

        :data:`CLOCK_STALL_MIN_S`, or :data:`CLOCK_STALL_INTERVALS` times the median wall
        interval between the newest /clock messages when that is longer (a simulator run
        at a small real-time factor publishes /clock seldom in wall time).
        """
        if not self._intervals:
            return CLOCK_STALL_MIN_S
        return max(CLOCK_STALL_MIN_S,
                   CLOCK_STALL_INTERVALS * statistics.median(self._intervals))

    def stalled(self) -> bool:
        """Return whether /clock moved once and then not for :meth:`stall_bound_s`."""
        stalled = self.stalled_s()
        return stalled is not None and stalled > self.stall_bound_s()


#: Each node's :class:`ClockWatch`.
_WATCHES: 'weakref.WeakKeyDictionary[Node, ClockWatch]' = weakref.WeakKeyDictionary()


def clock_watch(node: 'Node') -> ClockWatch:
    """
    Return ``node``'s :class:`ClockWatch`, made and hooked to its clock on the first call.

    rclpy calls it back when the node's clock is set back (/clock, or ROS time switched on
    or off); readings through :func:`read_clock_ns`, :func:`known_now_ns` and
    :func:`node_time_ns` catch a system clock stepped back.
    """
    watch = _WATCHES.get(node)
    if watch is None:
        watch = _WATCHES[node] = ClockWatch(node.get_logger().warn)
        clock = node.get_clock()
        watch._handle = clock.create_jump_callback(  # kept: the callback lives with it
            JumpThreshold(min_forward=None, min_backward=Duration(nanoseconds=-1),
                          on_clock_change=True),
            post_callback=lambda jump: watch.on_jump(clock.now().nanoseconds, jump))
    return watch


def read_clock_ns(node: 'Node') -> int:
    """Return ``node``'s clock (ns), noted by its :class:`ClockWatch` (a jump back seen)."""
    return clock_watch(node).read(node.get_clock().now().nanoseconds)


def clock_problem(sec: int, nanosec: int) -> Optional[Tuple[str, str]]:
    """Return why (sec, nanosec) is not a valid builtin_interfaces/Time, or None."""
    if sec < 0:
        return 'negative time', f'sec = {sec}'
    if nanosec >= NS_PER_S:
        return 'malformed stamp', f'nanosec = {nanosec} >= 1e9'
    return None


class GuardedTimeSource(TimeSource):
    """
    rclpy's TimeSource, but a /clock message that rclpy cannot convert is rejected.

    ``reject(source, reason, detail)`` is called for each rejected message (the signature
    of :meth:`ibvs_common.diagnostics.Diagnostics.reject`); the clock keeps its last time.
    """

    def __init__(self, reject: Callable[[str, str, str], None], *,
                 node: 'Node | None' = None) -> None:
        """Keep ``reject``, then attach to ``node`` as rclpy's TimeSource does."""
        self._reject = reject
        self._watch = None if node is None else clock_watch(node)
        super().__init__(node=node)

    def clock_callback(self, msg: 'Clock') -> None:
        """Set the attached clocks from ``msg``, unless its time is malformed."""
        problem = clock_problem(msg.clock.sec, msg.clock.nanosec)
        if problem is not None:
            self._reject(contract.CLOCK, *problem)
            return
        super().clock_callback(msg)
        if self._watch is not None:
            self._watch.clock_message(msg.clock.sec * NS_PER_S + msg.clock.nanosec)


def guard_clock(node: 'Node', reject: Callable[[str, str, str], None]) -> GuardedTimeSource:
    """
    Replace ``node``'s TimeSource by a :class:`GuardedTimeSource` reporting to ``reject``.

    The node's clock, its ``use_sim_time`` parameter and its reaction to a change of that
    parameter stay as they were; only the /clock subscription changes hands. Returns the
    new time source.
    """
    old = node._time_source  # rclpy offers no public way to choose a node's TimeSource
    node.remove_on_set_parameters_callback(old._on_parameter_event)
    old.detach_node()
    new = GuardedTimeSource(reject, node=node)
    new.attach_clock(node.get_clock())
    node._time_source = new
    return new


def known_now_ns(node: 'Node') -> int | None:
    """
    Return ``node``'s clock in integer nanoseconds, or None while sim time has not started.

    With ``use_sim_time`` a node's clock reads 0 until the first /clock arrives; 0 then
    means "unknown", not "t = 0", and a caller cannot bound a stamp by it.
    """
    now = read_clock_ns(node)
    if node.get_clock().ros_time_is_active and now == 0:
        return None
    return now


def node_time_ns(node: 'Node', *stamps: int | None) -> int:
    """
    Return the newest time ``node`` knows (ns): its clock and the ``stamps`` it accepted.

    The clock counts while sim time is unknown (:func:`known_now_ns` None) as 0, the start
    of sim time, so that a stamp far in the future is recognised from the first message on;
    ``stamps`` that are None (nothing accepted yet) are skipped, and so are all of them when
    this very reading found the clock jumped back (they are of the old time line; the
    node's :meth:`ClockWatch.on_back` callbacks forget them for the next reading).
    """
    watch = clock_watch(node)
    jumps = watch.jumps_back
    now = known_now_ns(node) or 0
    if watch.jumps_back != jumps:
        return now
    return max([now] + [t for t in stamps if t is not None])
