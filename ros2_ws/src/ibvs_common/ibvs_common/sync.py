"""
The stamp-ordered buffers every lockstep rule of docs/design.md §4 is built from.

No rclpy and no messages here: a node turns its messages into stamps (integer ns of sim
time) and payloads, offers them to a buffer (or to its node's lockstep rule built from
these), and reports the :class:`Rejection` it gets back
(``Diagnostics.reject(source, *rejection)``). Each node's own rule stands beside it:
:mod:`ibvs_control.feedback_lockstep` (joint controller, model-only loop),
:mod:`ibvs_control.frame_lockstep` (adaptive feedback) and
:mod:`ibvs_vision.stereo_pairing` (feature node); the timing rules themselves are in
:mod:`.timing`.

- :class:`Rejection`: why an input was refused.
- :class:`StampHistory`: values by stamp, bounded by count and/or a horizon of sim time,
  looked up by the first stamp at or after a time (or the last at or before it).
- :class:`JointTrack`: joint states by stamp, read at any stamp between two of them by
  linear interpolation, within a gap bound set from the rate it measures.
- :class:`PendingQueue`: inputs waiting for their answer, in strictly increasing stamp
  order, bounded; stale and overflowing inputs are rejected with a reason.

Every buffer is bounded, and every input that is refused comes back as a reason, so that a
missing input is named rather than waited on in silence. Each can ``forget()`` all it holds:
after the node's clock jumped back (:class:`ibvs_common.sim_time.ClockWatch`) the stamps of
the old time line would otherwise refuse every fresh input as older.
"""

import bisect
from collections import deque
import math
from typing import Any, Deque, Generic, List, NamedTuple, Optional, Tuple, TypeVar

import numpy as np

V = TypeVar('V')


class Rejection(NamedTuple):
    """Why an input was refused: ``reason`` (counted by name) and ``detail`` (logged)."""

    reason: str
    detail: str


class StampHistory(Generic[V]):
    """
    Values by stamp, sorted, bounded by count and/or by a horizon of sim time.

    Parameters
    ----------
    max_len : int, optional
        Most values kept; the oldest goes when a new one would exceed it.
    horizon_ns : int, optional
        :meth:`prune` forgets the values stamped more than this before its ``now_ns``.
    strict : bool
        True: stamps must increase, an older or equal one is rejected ('stale stamp').
        False: a late stamp is inserted in order, an equal one replaces the value.

    """

    def __init__(self, max_len: Optional[int] = None, horizon_ns: Optional[int] = None,
                 strict: bool = True) -> None:
        """Create an empty history (see the class docstring for the parameters)."""
        if max_len is not None and max_len < 1:
            raise ValueError(f'max_len must be >= 1, got {max_len}')
        self.max_len = max_len
        self.horizon_ns = horizon_ns
        self.strict = strict
        self._stamps: List[int] = []
        self._values: List[V] = []

    def __len__(self) -> int:
        """Return the number of values kept."""
        return len(self._stamps)

    def __contains__(self, t_ns: int) -> bool:
        """Return whether a value is kept for exactly ``t_ns``."""
        i = bisect.bisect_left(self._stamps, t_ns)
        return i < len(self._stamps) and self._stamps[i] == t_ns

    @property
    def newest(self) -> Optional[int]:
        """Return the newest stamp kept, None when empty."""
        return self._stamps[-1] if self._stamps else None

    def add(self, t_ns: int, value: V) -> Optional[Rejection]:
        """
        Keep ``value`` at ``t_ns``; return why not, or None.

        Parameters
        ----------
        t_ns : int
            The stamp (ns).
        value
            What to keep for it.

        Returns
        -------
        Rejection or None
            'stale stamp' when the history is strict and ``t_ns`` is not after the newest.

        """
        stamps = self._stamps
        if stamps and t_ns <= stamps[-1]:
            if self.strict:
                return Rejection('stale stamp', f'{t_ns} ns after {stamps[-1]} ns')
            i = bisect.bisect_left(stamps, t_ns)
            if stamps[i] == t_ns:
                self._values[i] = value
            else:
                stamps.insert(i, t_ns)
                self._values.insert(i, value)
        else:
            stamps.append(t_ns)
            self._values.append(value)
        if self.max_len is not None and len(stamps) > self.max_len:
            del stamps[0], self._values[0]
        return None

    def forget(self) -> None:
        """Forget every value (the clock jumped back: a new time line starts)."""
        self._stamps.clear()
        self._values.clear()

    def prune(self, now_ns: int) -> None:
        """Forget the values stamped before ``now_ns - horizon_ns`` (no horizon: none)."""
        if self.horizon_ns is None:
            return
        cut = bisect.bisect_left(self._stamps, now_ns - self.horizon_ns)
        del self._stamps[:cut], self._values[:cut]

    def at_or_after(self, t_ns: int) -> Optional[Tuple[int, V]]:
        """
        Return the first ``(stamp, value)`` with stamp >= ``t_ns``, or None.

        Parameters
        ----------
        t_ns : int
            The time (ns) looked up, e.g. a frame's stamp.

        Returns
        -------
        tuple of (int, value) or None
            None when every stamp kept is before ``t_ns`` (the value may still come).

        """
        i = bisect.bisect_left(self._stamps, t_ns)
        return (self._stamps[i], self._values[i]) if i < len(self._stamps) else None

    def at_or_before(self, t_ns: int) -> Optional[Tuple[int, V]]:
        """Return the last ``(stamp, value)`` with stamp <= ``t_ns``, or None."""
        i = bisect.bisect_right(self._stamps, t_ns)
        return (self._stamps[i - 1], self._values[i - 1]) if i else None

    def last_stamps(self, n: int) -> List[int]:
        """Return the newest ``n`` stamps kept (fewer when fewer are kept), oldest first."""
        return self._stamps[-n:] if n > 0 else []


def lerp(a: Any, b: Any, w: float) -> Any:
    """
    Return ``a + (b - a) * w`` for arrays, numbers or tuples of them, element by element.

    ``w`` = 0 returns ``a`` itself and ``w`` = 1 ``b`` itself (no arithmetic), so that a
    value read at one of the stamps it was kept at is that value, to the bit.
    """
    if w == 0.0:
        return a
    if w == 1.0:
        return b
    if isinstance(a, tuple):
        return tuple(lerp(x, y, w) for x, y in zip(a, b))
    return np.asarray(a) + (np.asarray(b) - np.asarray(a)) * w


class JointTrack(Generic[V]):
    """
    Joint states by stamp, read at any stamp between two of them by linear interpolation.

    A real cell's joint_state_broadcaster publishes /joint_states on the controller
    manager's own cycle (250 Hz on abb_ros2), stamped when it reads the hardware, never at a
    camera's exposure: the state of an image stamped ``t`` is interpolated between the two
    states that bracket it (positions, velocities, any array or tuple of arrays:
    :func:`lerp`). A state stamped exactly ``t`` is returned itself, so that the simulator's
    lockstep, which publishes a frame's state at the frame's stamp, reads exactly what it
    published. The two bracketing states may be at most :attr:`max_gap_ns` apart:
    ``gap_periods`` times the median interval of the last ``rate_samples`` states, i.e. the
    rate the track measures, not a rate it is told (one lost message at 250 Hz is still
    interpolated over 8 ms; a gap of three periods is not). A rejected state
    (:meth:`add_bad`) counts as a lost one, except at the very stamp looked up: there the
    image's own state was refused, and so is the image.

    Parameters
    ----------
    max_len, horizon_ns : int, optional
        The bounds of the histories kept (:class:`StampHistory`).
    strict : bool
        Whether a state older than the newest one is rejected (:class:`StampHistory`).
    gap_periods : float
        The widest gap interpolated over, in measured periods (> 1).
    rate_samples : int
        How many of the newest intervals the period is the median of.

    """

    def __init__(self, *, max_len: Optional[int] = None, horizon_ns: Optional[int] = None,
                 strict: bool = False, gap_periods: float = 2.5,
                 rate_samples: int = 32) -> None:
        """Create an empty track (see the class docstring for the parameters)."""
        if not gap_periods > 1.0:
            raise ValueError(f'gap_periods must be > 1, got {gap_periods}')
        self.gap_periods = gap_periods
        self.rate_samples = rate_samples
        self.good: StampHistory[V] = StampHistory(max_len, horizon_ns, strict)
        self.bad: StampHistory[str] = StampHistory(max_len, horizon_ns, strict=False)
        self._period: Optional[Tuple[Tuple[int, ...], float]] = None

    def __len__(self) -> int:
        """Return the number of good states kept."""
        return len(self.good)

    @property
    def newest(self) -> Optional[int]:
        """Return the newest good stamp kept, None when empty."""
        return self.good.newest

    def add(self, t_ns: int, value: V) -> Optional[Rejection]:
        """Keep the state ``value`` at ``t_ns``; return why not (:meth:`StampHistory.add`)."""
        return self.good.add(t_ns, value)

    def add_bad(self, t_ns: int, reason: str) -> None:
        """Note that the state stamped ``t_ns`` was rejected for ``reason``."""
        self.bad.add(t_ns, reason)

    def forget(self) -> None:
        """Forget every state, good and bad (the clock jumped back)."""
        self.good.forget()
        self.bad.forget()

    def prune(self, now_ns: int) -> None:
        """Forget the states older than the horizon before ``now_ns``."""
        self.good.prune(now_ns)
        self.bad.prune(now_ns)

    def period_ns(self) -> Optional[float]:
        """Return the median interval (ns) of the newest states, None before two."""
        stamps = tuple(self.good.last_stamps(self.rate_samples + 1))
        if len(stamps) < 2:
            return None
        # Kept until the newest stamps change: every lookup reads it (:meth:`at`), and
        # the median costs far more than the lookup.
        if self._period is None or self._period[0] != stamps:
            self._period = (stamps, float(np.median(np.diff(stamps))))
        return self._period[1]

    def max_gap_ns(self) -> Optional[int]:
        """Return the widest gap (ns) interpolated over, None before two states."""
        period = self.period_ns()
        return None if period is None else math.ceil(self.gap_periods * period)

    def at(self, t_ns: int) -> Tuple[Optional[V], Optional[str]]:
        """
        Return the state at ``t_ns``: ``(value, None)``, ``(None, None)`` to wait, ``(None, why)``.

        Parameters
        ----------
        t_ns : int
            The stamp (ns) looked up, e.g. an image's.

        Returns
        -------
        tuple
            ``(value, None)``: the state kept at ``t_ns``, or interpolated between the two
            that bracket it; ``(None, None)``: no state after ``t_ns`` yet (it may come);
            ``(None, why)``: never (no state before it, its own state rejected, or a gap
            wider than :meth:`max_gap_ns`).

        """
        after = self.good.at_or_after(t_ns)
        if after is not None and after[0] == t_ns:
            return after[1], None
        bad = self.bad.at_or_after(t_ns)
        if bad is not None and bad[0] == t_ns:
            return None, f'joint state of the image rejected ({bad[1]})'
        before = self.good.at_or_before(t_ns)
        if before is None:
            if after is None:
                return None, None
            return None, (f'no joint state at or before the image stamp {t_ns} ns (the '
                          f'first kept is {after[0]} ns): nothing to interpolate from')
        if after is None:
            return None, None
        gap = after[0] - before[0]
        max_gap = self.max_gap_ns()
        if gap > max_gap:
            return None, (f'the joint states around the image stamp are {gap * 1e-6:.3f} ms '
                          f'apart, more than {max_gap * 1e-6:.3f} ms ({self.gap_periods:g} '
                          f'periods of the {1e9 / self.period_ns():.1f} Hz measured)')
        return lerp(before[1], after[1], (t_ns - before[0]) / gap), None


class PendingQueue(Generic[V]):
    """
    Inputs waiting for their answer, in strictly increasing stamp order, at most ``max_len``.

    An input is accepted only if it is newer than the newest one pending, or, with none
    pending, than the last one answered (popped): nothing is answered twice or out of order.

    Parameters
    ----------
    max_len : int
        Most inputs pending; one more is rejected ('buffer full').
    full_note : str
        Said after '<t> ns dropped' when one is rejected for a full buffer.

    """

    def __init__(self, max_len: int, full_note: str = '') -> None:
        """Create an empty queue (see the class docstring for the parameters)."""
        if max_len < 1:
            raise ValueError(f'max_len must be >= 1, got {max_len}')
        self.max_len = max_len
        self.full_note = full_note
        self._items: Deque[Tuple[int, V]] = deque()
        #: Stamp of the last input popped (answered), None before the first.
        self.last_popped_ns: Optional[int] = None

    def __len__(self) -> int:
        """Return the number of inputs pending."""
        return len(self._items)

    @property
    def first_ns(self) -> Optional[int]:
        """Return the stamp of the oldest input pending, None when empty."""
        return self._items[0][0] if self._items else None

    @property
    def newest_ns(self) -> Optional[int]:
        """Return the newest stamp pending, else the last one popped, else None."""
        return self._items[-1][0] if self._items else self.last_popped_ns

    def forget(self) -> None:
        """Drop every input pending and the last answered (the clock jumped back)."""
        self._items.clear()
        self.last_popped_ns = None

    def check_order(self, t_ns: int) -> Optional[Rejection]:
        """Return 'stale stamp' unless ``t_ns`` is after :attr:`newest_ns`, else None."""
        newest = self.newest_ns
        if newest is not None and t_ns <= newest:
            return Rejection('stale stamp', f'{t_ns} ns, not after {newest} ns')
        return None

    def push(self, t_ns: int, item: V) -> Optional[Rejection]:
        """Append ``item`` (order already checked); return 'buffer full' when it is."""
        if len(self._items) >= self.max_len:
            note = f': {self.full_note}' if self.full_note else ''
            return Rejection('buffer full', f'{t_ns} ns dropped{note}')
        self._items.append((t_ns, item))
        return None

    def offer(self, t_ns: int, item: V) -> Optional[Rejection]:
        """Append ``item`` at ``t_ns`` if it is in order and there is room; return why not."""
        return self.check_order(t_ns) or self.push(t_ns, item)

    def first(self) -> Tuple[int, V]:
        """Return the oldest ``(stamp, item)`` pending (IndexError when empty)."""
        return self._items[0]

    def pop(self) -> Tuple[int, V]:
        """Remove and return the oldest ``(stamp, item)``; it counts as answered."""
        t_ns, item = self._items.popleft()
        self.last_popped_ns = t_ns
        return t_ns, item
