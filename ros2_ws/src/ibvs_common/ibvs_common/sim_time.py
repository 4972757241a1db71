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
"""

from collections.abc import Callable
from typing import Optional, Tuple, TYPE_CHECKING

from rclpy.time_source import TimeSource

from . import contract
from .timing import NS_PER_S

if TYPE_CHECKING:
    from rclpy.node import Node
    from rosgraph_msgs.msg import Clock


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
        super().__init__(node=node)

    def clock_callback(self, msg: 'Clock') -> None:
        """Set the attached clocks from ``msg``, unless its time is malformed."""
        problem = clock_problem(msg.clock.sec, msg.clock.nanosec)
        if problem is not None:
            self._reject(contract.CLOCK, *problem)
            return
        super().clock_callback(msg)


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
    clock = node.get_clock()
    now = clock.now().nanoseconds
    if clock.ros_time_is_active and now == 0:
        return None
    return now


def node_time_ns(node: 'Node', *stamps: int | None) -> int:
    """
    Return the newest time ``node`` knows (ns): its clock and the ``stamps`` it accepted.

    The clock counts while sim time is unknown (:func:`known_now_ns` None) as 0, the start
    of sim time, so that a stamp far in the future is recognised from the first message on;
    ``stamps`` that are None (nothing accepted yet) are skipped.
    """
    return max([known_now_ns(node) or 0] + [t for t in stamps if t is not None])
