"""
Counting and reporting of rejected inputs and node status on /diagnostics.

Every rejected input (NaN, wrong length, stale stamp, ...) is counted per reason and
logged the first time that reason occurs (then at most every ``log_period_s``), never
raised: a node keeps running whatever it is fed. That includes /clock, which rclpy reads
itself: a :class:`Diagnostics` puts its node's sim time behind
:class:`ibvs_common.sim_time.GuardedTimeSource`, so that a malformed /clock is counted here
instead of ending the process.
"""

from collections import Counter
from collections.abc import Callable, Iterable
from typing import Any, TYPE_CHECKING
import weakref

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType

from . import contract, kit
from .profiling import Stopwatch
from .sim_time import guard_clock

if TYPE_CHECKING:
    from rclpy.node import Node
    from rclpy.publisher import Publisher


#: Wall seconds between two progress lines of a node (:meth:`Diagnostics.log_progress`):
#: a modest rate for someone who starts the nodes by hand and watches their terminals.
PROGRESS_S = 5.0
#: What every progress line starts with (never "waiting": the runner reads those lines as
#: what a node waits for, ibvs_experiments.runner.last_waiting_line).
PROGRESS_PREFIX = 'progress: '

#: Each node's :class:`Diagnostics`, for :func:`publish_last`.
_OF_NODE: 'weakref.WeakKeyDictionary[Node, list[Diagnostics]]' = weakref.WeakKeyDictionary()


def publish_last(node: 'Node') -> None:
    """
    Publish the status of each :class:`Diagnostics` of ``node`` once more (its end).

    :func:`ibvs_common.node_main.run` calls it before it destroys the node, so that the
    totals of a run's last second (the timings of :mod:`.profiling` above all) reach the
    bag even when the run ends between two heartbeats: a run of a simulated second now
    takes about a second of wall time.
    """
    for diagnostics in _OF_NODE.get(node, ()):
        diagnostics.publish()


def publisher_of(node: 'Node') -> 'Publisher | None':
    """
    Return the /diagnostics publisher of ``node``'s first :class:`Diagnostics`, or None.

    For :class:`ibvs_common.node_main.Watchdog`, which publishes on it from its own thread
    (rcl's publish is thread-safe), so that the graph has one /diagnostics publisher a node.
    """
    found = _OF_NODE.get(node)
    return found[0]._pub if found else None


class Diagnostics:
    """
    Status values and rejection counters of one node, published on /diagnostics.

    ``values`` are free key/value pairs the node sets (mode, rank, condition number, ...).
    Rejections are counted per ``'<input>: <reason>'``. Publishing runs on a steady-clock
    timer so that it goes on while sim time is paused. A /clock message that rclpy could not
    convert (negative seconds, nanosec >= 1e9) is counted as a rejection of ``/clock``.
    An alert (:meth:`alert`) is reported beside the node's own level and message, whatever
    the node sets them to: :attr:`publishers` (:class:`.kit.PublisherWatch`) names a second
    publisher on the node's inputs and commands so.
    """

    def __init__(self, node: 'Node', name: str, period_s: float = 1.0,
                 log_period_s: float = 5.0) -> None:
        """Create the /diagnostics publisher and the steady-clock timer of ``node``."""
        self._node = node
        self._name = f'{node.get_name()}: {name}'
        self._hardware_id = node.get_fully_qualified_name()
        self._log_period_s = log_period_s
        # Through the kit like every topic, so that it is recorded (kit.opened).
        self._pub = kit.publisher(node, DiagnosticArray, contract.DIAGNOSTICS, 10)
        self.rejections = Counter()
        self.values = {}
        #: Wall time per section of the node's work (ibvs_common.profiling), published too.
        self.timing = Stopwatch()
        self.level = DiagnosticStatus.OK
        self.message = 'ok'
        #: Conditions reported beside the node's own status (:meth:`alert`), by key.
        self.alerts: dict[str, str] = {}
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._last_log = {}
        self._ignored = {}
        self._timer = node.create_timer(period_s, self.publish, clock=self._steady)
        guard_clock(node, self.reject)
        #: Who publishes on the node's inputs and commands, looked at while it runs.
        self.publishers = kit.PublisherWatch(node, self)
        _OF_NODE.setdefault(node, []).append(self)

    def reject(self, source: str, reason: str, detail: str = '') -> None:
        """Count one rejected input from ``source`` for ``reason``; log it once per period."""
        key = f'{source}: {reason}'
        self.rejections[key] += 1
        now = self._steady.now().nanoseconds * 1e-9
        last = self._last_log.get(key)
        if last is None or now - last >= self._log_period_s:
            self._last_log[key] = now
            count = self.rejections[key]
            self._node.get_logger().warn(
                f'rejected {source} ({reason}){": " + detail if detail else ""}'
                f' [{count} so far]')

    def note_ignored(self, source: str, names: Iterable[str], key: str = 'ignored_joints'
                     ) -> None:
        """
        Show ``names`` that ``source`` carries and the node ignores, each once, and log it.

        For the joints of /joint_states that are not the arm's (a track, a gripper:
        :func:`ibvs_common.conversions.ignored_joints`): not rejections, the message is
        used. ``key`` (e.g. ``ignored_joints: track_1, gripper``) lists every name ignored so far;
        a name is logged (INFO) the first time only.
        """
        ignored = self._ignored.setdefault(key, [])
        new = [n for n in names if n not in ignored]
        if new:
            ignored.extend(new)
            self.values[key] = ', '.join(ignored)
            self._node.get_logger().info(f"{source}: ignoring joints {new} (not the arm's)")

    def log_progress(self, describe: Callable[[], str | None],
                     period_s: float = PROGRESS_S) -> None:
        """
        Log what the node does as one INFO line every ``period_s`` of wall time.

        Parameters
        ----------
        describe : callable
            Returns the line, without :data:`PROGRESS_PREFIX` (added here), or None when
            there is nothing to say yet. A line equal to the last one logged is not logged
            again: an idle node falls silent instead of repeating itself.
        period_s : float
            Wall seconds between two looks, on the steady clock (sim time may stand still).

        """
        last = []

        def tick():
            text = describe()
            if text is not None and last != [text]:
                last[:] = [text]
                self._node.get_logger().info(PROGRESS_PREFIX + text)

        self._progress_timer = self._node.create_timer(period_s, tick, clock=self._steady)

    @property
    def rejected_total(self) -> int:
        """Return the number of inputs rejected so far, all reasons together."""
        return sum(self.rejections.values())

    def update(self, **values: Any) -> None:
        """Set status values shown on /diagnostics (numbers are formatted, others str())."""
        self.values.update(values)

    def set_level(self, level: bytes, message: str) -> None:
        """Set the overall level (DiagnosticStatus.OK/WARN/ERROR) and its message."""
        self.level, self.message = level, message

    def alert(self, key: str, text: str | None) -> None:
        """
        Report ``text`` under ``key`` beside the node's own status (None: it is over).

        While an alert is set the status is at least WARN, and its message the node's own
        followed by each alert's text that it does not already say (just the alerts' while
        the node's own level is OK).
        """
        if text is None:
            self.alerts.pop(key, None)
        else:
            self.alerts[key] = text

    def status(self) -> DiagnosticStatus:
        """Return the current DiagnosticStatus."""
        level, message = self.level, self.message
        alerts = [text for text in self.alerts.values() if text not in message]
        if self.alerts and level < DiagnosticStatus.WARN:
            level, message = DiagnosticStatus.WARN, '; '.join(self.alerts.values())
        elif alerts:
            message = '; '.join([message, *alerts])
        kvs = [KeyValue(key=k, value=_fmt(v)) for k, v in self.values.items()]
        kvs.append(KeyValue(key='rejected_total', value=str(self.rejected_total)))
        kvs += [KeyValue(key=f'rejected[{k}]', value=str(n))
                for k, n in sorted(self.rejections.items())]
        kvs += [KeyValue(key=k, value=v) for k, v in self.timing.values().items()]
        return DiagnosticStatus(level=level, name=self._name, message=message,
                                hardware_id=self._hardware_id, values=kvs)

    def publish(self) -> None:
        """Publish the current status now."""
        msg = DiagnosticArray()
        msg.header.stamp = self._node.get_clock().now().to_msg()
        msg.status = [self.status()]
        self._pub.publish(msg)


def _fmt(value):
    if isinstance(value, float):
        return f'{value:.6g}'
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(_fmt(v) for v in value) + ']'
    if hasattr(value, 'tolist'):
        return _fmt(value.tolist())
    return str(value)
