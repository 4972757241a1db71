"""
builtin_interfaces Time and Duration <-> integer nanoseconds, and the one stamp rule.

Every node reads a header stamp with :func:`read_stamp` (docs/design.md §4) and keeps the
order of each source's stamps with :class:`StampOrder`; both raise
:class:`.input_error.InputError`.
"""

from typing import Optional, Tuple

from builtin_interfaces.msg import Duration, Time

from .input_error import InputError
from .sim_time import clock_problem
from .timing import is_frame_stamp, NS_PER_S


def stamp_ns(stamp: Time) -> int:
    """Return a builtin_interfaces/Time as integer nanoseconds (exact)."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def read_stamp(stamp: Time, now_ns: Optional[int] = None, lead_ns: Optional[int] = None,
               frames: Optional[Tuple[int, int]] = None) -> int:
    """
    Return a header stamp as integer nanoseconds; :class:`InputError` if no node may use it.

    The one stamp rule of every node (docs/design.md §4). Refused:

    - malformed: a negative ``sec`` (before the sim starts at 0) or ``nanosec`` of a second
      or more, which :func:`stamp_ns` would silently carry into the seconds;
    - with ``lead_ns``, 'stamp in the future': more than ``lead_ns`` after ``now_ns``, the
      newest time the node knows (:func:`ibvs_common.sim_time.node_time_ns`; None: 0, the
      start of sim time). A node never stores such a stamp: one input from a bad publisher
      would otherwise make every later good one look stale, or hold a buffer for ever;
    - with ``frames`` = (camera_period_ns, step_ns), 'off the frame grid': not the stamp
      of a camera frame (:func:`ibvs_common.timing.is_frame_stamp`).

    Parameters
    ----------
    stamp : builtin_interfaces.msg.Time
        The stamp read.
    now_ns : int, optional
        The node's newest known time (ns).
    lead_ns : int, optional
        How far (ns) a stamp may lead ``now_ns``; None: no bound.
    frames : tuple of (int, int), optional
        The camera period and the physics step (ns) of a frame stamp.

    Returns
    -------
    int
        The stamp in nanoseconds.

    """
    problem = clock_problem(stamp.sec, stamp.nanosec)
    if problem is not None:
        raise InputError(*problem)
    t_ns = stamp_ns(stamp)
    now_ns = max(int(now_ns or 0), 0)
    if lead_ns is not None and t_ns > now_ns + lead_ns:
        raise InputError('stamp in the future',
                         f'{t_ns} ns, more than {lead_ns} ns after the newest time known, '
                         f'{now_ns} ns')
    if frames is not None and not is_frame_stamp(t_ns, *frames):
        raise InputError('off the frame grid',
                         f'{t_ns} ns is not the stamp of a frame (every {frames[0]} ns, '
                         f'at the physics step of {frames[1]} ns at or after it)')
    return t_ns


class StampOrder:
    """
    The newest stamp taken from each source; a stamp not after it is refused.

    A source (one publisher's stream, e.g. a topic) stamps its messages in order. A stamp
    equal to the newest taken is 'duplicate stamp' (the same message again, or a second
    publisher), one before it 'stamp went back' (a restarted or a foreign clock): both
    raise :class:`InputError`, so that the node counts and skips the message. Only a stamp
    the node :meth:`take` s moves the order on: a message refused for its values leaves its
    stamp free for a good one.
    """

    def __init__(self) -> None:
        """Start with no stamp taken from any source."""
        self._newest = {}

    def check(self, source: str, t_ns: int) -> None:
        """Raise :class:`InputError` unless ``t_ns`` is after the newest taken from ``source``."""
        newest = self._newest.get(source)
        if newest is None or t_ns > newest:
            return
        if t_ns == newest:
            raise InputError('duplicate stamp', f'{t_ns} ns again')
        raise InputError('stamp went back', f'{t_ns} ns after {newest} ns')

    def take(self, source: str, t_ns: int) -> None:
        """Note that the message stamped ``t_ns`` from ``source`` was used."""
        self._newest[source] = int(t_ns)

    def newest(self, source: str) -> Optional[int]:
        """Return the newest stamp taken from ``source`` (ns), or None."""
        return self._newest.get(source)

    def forget(self) -> None:
        """Forget every stamp taken (the clock jumped back: a new time line starts)."""
        self._newest.clear()


def ns_stamp(ns: int) -> Time:
    """Return integer nanoseconds as builtin_interfaces/Time."""
    ns = int(ns)
    return Time(sec=ns // NS_PER_S, nanosec=ns % NS_PER_S)


def duration_ns(duration: Duration) -> int:
    """Return a builtin_interfaces/Duration as integer nanoseconds (exact)."""
    return int(duration.sec) * NS_PER_S + int(duration.nanosec)
