"""
The lockstep of docs/design.md §4 as plain code: stamp histories, frame matching, buffers.

No rclpy and no messages here: a node turns its messages into stamps (integer ns of sim
time) and payloads, offers them to one of these objects, and reports the
:class:`Rejection` it gets back (``Diagnostics.reject(source, *rejection)``). What may be
answered, in which order and with which inputs is decided here, once, for the nodes and
for the model-only loop (``ibvs_control.closed_loop``); the timing rules themselves stay in
:mod:`.timing`.

- :class:`StampHistory`: values by stamp, bounded by count and/or a horizon of sim time,
  looked up by the first stamp at or after a time.
- :class:`PendingQueue`: inputs waiting for their answer, in strictly increasing stamp
  order, bounded; stale and overflowing inputs are rejected with a reason.
- :class:`FeedbackLockstep`: the joint controller's rule, which /joint_states can be
  answered now and with which q_feedback (:func:`.timing.feedback_frame_ns`, lost frames).
- :class:`FrameLockstep`: the adaptive feedback's rule, frames answered in stamp order,
  each with the first joint state at or after its stamp.
- :class:`StereoPairer`: the feature node's rule, left and right images paired by stamp,
  each frame matched with the joint state of its physics step, dropped when it never can be.

Every buffer is bounded, and every input that is refused comes back as a reason, so that a
missing input is named (``waiting_for``) rather than waited on in silence.
"""

import bisect
from collections import deque
from typing import Any, Dict, Generic, Iterator, List, NamedTuple, Optional, Tuple, TypeVar

from .timing import feedback_frame_ns

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
                 strict: bool = True):
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

    def __init__(self, max_len: int, full_note: str = ''):
        """Create an empty queue (see the class docstring for the parameters)."""
        if max_len < 1:
            raise ValueError(f'max_len must be >= 1, got {max_len}')
        self.max_len = max_len
        self.full_note = full_note
        self._items: deque = deque()
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


class FeedbackLockstep:
    """
    Which /joint_states the joint controller can answer now, and with which q_feedback.

    The answer to the state at t needs the q_feedback of the frame acting at t
    (:func:`.timing.feedback_frame_ns`: none before the first frame acts), or word that
    this frame was lost; it then holds the q_feedback of the latest frame not lost. States
    are answered in stamp order, each once; a state whose input is missing waits, and
    :meth:`waiting_for` names that input. The node's own preconditions (the feedforward
    trajectory) are its business: it pops only once they are met.

    Parameters
    ----------
    camera_period_ns, latency_ns, step_ns : int
        T_cam, the feedback latency and the physics step (ns), as for feedback_frame_ns.
    max_buffer : int
        Most states, q_feedbacks and lost frames kept, each (a flood is rejected). Stamps
        ahead of the node's time are the node's to refuse before they get here
        (:func:`ibvs_common.conversions.read_stamp`, the one stamp rule).
    initial
        The q_feedback held before the first frame acts (the node's zeros).
    feedback_name, lost_name : str
        How :meth:`waiting_for` names the q_feedback and the lost-frame inputs.

    """

    def __init__(self, camera_period_ns: int, latency_ns: int, step_ns: int, *,
                 max_buffer: int = 1000, initial: Any = None, feedback_name: str = 'q_feedback',
                 lost_name: str = 'frame_lost'):
        """Create the lockstep with nothing received (see the class docstring)."""
        feedback_frame_ns(0, camera_period_ns, latency_ns, step_ns)  # checks the periods
        self.camera_period_ns = camera_period_ns
        self.latency_ns = latency_ns
        self.step_ns = step_ns
        self.max_buffer = max_buffer
        self.feedback_name = feedback_name
        self.lost_name = lost_name
        self.states: PendingQueue = PendingQueue(max_buffer)
        #: q_feedback by frame stamp, from the one still acting on.
        self.feedback: Dict[int, Any] = {}
        #: Stamps of the lost frames still to come into play.
        self.lost: set = set()
        #: The q_feedback the last answer used.
        self.held = initial

    @property
    def last_answered_ns(self) -> Optional[int]:
        """Return the stamp of the last state answered, None before the first."""
        return self.states.last_popped_ns

    def frame_at(self, t_ns: int) -> Optional[int]:
        """Return the stamp of the frame whose q_feedback acts at ``t_ns`` (None: none yet)."""
        return feedback_frame_ns(t_ns, self.camera_period_ns, self.latency_ns, self.step_ns)

    def _stale(self, t_ns: int) -> Optional[Rejection]:
        # The oldest frame still needed: the one acting at the last answered step.
        last = self.last_answered_ns
        needed = None if last is None else self.frame_at(last)
        if needed is not None and t_ns < needed:
            return Rejection('stale stamp', f'{t_ns} ns is no longer needed')
        return None

    def offer_state(self, t_ns: int, item: Any) -> Optional[Rejection]:
        """
        Buffer the state at ``t_ns`` until it can be answered; return why not, or None.

        Parameters
        ----------
        t_ns : int
            Its stamp (ns).
        item
            What the answer needs of it (the node's q, qdot), handed back by :meth:`pop_ready`.

        Returns
        -------
        Rejection or None
            'stale stamp' (not after the newest state), 'buffer full'.

        """
        return self.states.offer(t_ns, item)

    def offer_feedback(self, t_ns: int, q_feedback: Any) -> Optional[Rejection]:
        """
        Keep the q_feedback of the frame stamped ``t_ns``; return why not, or None.

        Returns
        -------
        Rejection or None
            'stale stamp' (older than the frame still needed), 'frame was lost',
            'duplicate stamp', 'buffer full'.

        """
        rejection = self._stale(t_ns)
        if rejection is not None:
            return rejection
        if t_ns in self.lost:
            return Rejection('frame was lost', f'{t_ns} ns')
        if t_ns in self.feedback or len(self.feedback) >= self.max_buffer:
            return Rejection('duplicate stamp' if t_ns in self.feedback else 'buffer full',
                             f'{t_ns} ns')
        self.feedback[t_ns] = q_feedback
        return None

    def offer_lost(self, t_ns: int) -> Optional[Rejection]:
        """
        Note that the frame stamped ``t_ns`` was lost (no q_feedback will come for it).

        Returns
        -------
        Rejection or None
            'stale stamp', 'duplicate stamp', 'frame has a q_feedback', 'buffer full'.

        """
        rejection = self._stale(t_ns)
        if rejection is not None:
            return rejection
        if t_ns in self.lost or t_ns in self.feedback or len(self.lost) >= self.max_buffer:
            reason = ('duplicate stamp' if t_ns in self.lost else 'frame has a q_feedback'
                      if t_ns in self.feedback else 'buffer full')
            return Rejection(reason, f'{t_ns} ns')
        self.lost.add(t_ns)
        return None

    def waiting_for(self, t_ns: Optional[int] = None) -> List[str]:
        """
        Return what the answer to ``t_ns`` still waits for (empty when it has it all).

        ``t_ns`` defaults to the oldest state pending (nothing pending: empty).
        """
        t_ns = self.states.first_ns if t_ns is None else t_ns
        frame = None if t_ns is None else self.frame_at(t_ns)
        if frame is not None and frame not in self.feedback and frame not in self.lost:
            return [f'{self.feedback_name} of frame {frame} ns (or its {self.lost_name})']
        return []

    def pop_ready(self) -> Optional[Tuple[int, Any, Any]]:
        """
        Take the oldest pending state if it can be answered now.

        Returns
        -------
        tuple of (int, item, q_feedback) or None
            The state's stamp and item, and the q_feedback to answer it with (its frame's,
            the one held for a lost frame, ``initial`` before the first frame acts); None
            while nothing is pending or the oldest state still waits.

        """
        if not self.states or self.waiting_for():
            return None
        t_ns, item = self.states.pop()
        frame = self.frame_at(t_ns)
        if frame is not None:
            if frame in self.feedback:
                self.held = self.feedback[frame]
            for stamp in [s for s in self.feedback if s < frame]:
                del self.feedback[stamp]
            self.lost = {s for s in self.lost if s >= frame}
        return t_ns, item, self.held


class FrameLockstep:
    """
    Frames answered in stamp order, each with the first joint state at or after its stamp.

    The simulator renders frame n from the first physics step at or after n * T_cam and
    publishes that step's joint state with it, so the joints of a frame are those of the
    first state stamped at or after it. Optionally a frame also waits for its status (was it
    measured?). The node's own preconditions (the camera model) are its business: it pops
    only once they are met.

    Parameters
    ----------
    history : int
        Joint states kept, most frames pending and most statuses kept.
    needs_status : bool
        Whether a frame waits for its status (:meth:`offer_status`).
    joints_name, status_name : str
        How :meth:`waiting_for` names the joint-state and the status inputs.
    full_note : str
        Said when a frame is rejected for a full buffer (why frames pile up).

    """

    def __init__(self, history: int = 2000, needs_status: bool = False, *,
                 joints_name: str = 'joint_states', status_name: str = 'feature_status',
                 full_note: str = ''):
        """Create the lockstep with nothing received (see the class docstring)."""
        self.history = history
        self.needs_status = needs_status
        self.joints_name = joints_name
        self.status_name = status_name
        self.joints: StampHistory = StampHistory(max_len=history)
        self.frames: PendingQueue = PendingQueue(history, full_note)
        self._measured: Dict[int, bool] = {}

    @property
    def last_answered_ns(self) -> Optional[int]:
        """Return the stamp of the last frame answered, None before the first."""
        return self.frames.last_popped_ns

    def offer_joints(self, t_ns: int, joints: Any) -> Optional[Rejection]:
        """Keep the joint state at ``t_ns``; 'stale stamp' unless after the newest one."""
        return self.joints.add(t_ns, joints)

    def offer_frame(self, t_ns: int, item: Any) -> Optional[Rejection]:
        """Queue the frame at ``t_ns``; 'stale stamp' unless after the newest, 'buffer full'."""
        return self.frames.offer(t_ns, item)

    def offer_status(self, t_ns: int, measured: bool) -> Optional[Rejection]:
        """
        Keep whether the frame at ``t_ns`` was measured; return why not, or None.

        A status of a frame already answered is dropped without a word (None).
        """
        last = self.last_answered_ns
        if last is not None and t_ns <= last:
            return None
        if len(self._measured) >= self.history:
            return Rejection('buffer full', f'{t_ns} ns')
        self._measured[t_ns] = measured
        return None

    def waiting_for(self, t_ns: Optional[int] = None) -> List[str]:
        """
        Return what the frame at ``t_ns`` still waits for (empty when it has it all).

        ``t_ns`` defaults to the oldest frame pending (nothing pending: empty).
        """
        t_ns = self.frames.first_ns if t_ns is None else t_ns
        if t_ns is None:
            return []
        missing = []
        if self.joints.at_or_after(t_ns) is None:
            missing.append(f'{self.joints_name} at or after {t_ns} ns')
        if self.needs_status and t_ns not in self._measured:
            missing.append(f'{self.status_name} of frame {t_ns} ns')
        return missing

    def pop_ready(self) -> Optional[Tuple[int, Any, Any, bool]]:
        """
        Take the oldest pending frame if its inputs are here.

        Returns
        -------
        tuple of (int, item, joints, bool) or None
            The frame's stamp and item, the joint state matched to it and whether it was
            measured (True without statuses); None while nothing is pending or the oldest
            frame still waits.

        """
        if not self.frames or self.waiting_for():
            return None
        t_ns, item = self.frames.pop()
        joints = self.joints.at_or_after(t_ns)[1]
        measured = self._measured.pop(t_ns, True)
        for old in [s for s in self._measured if s < t_ns]:
            del self._measured[old]
        return t_ns, item, joints, measured


class Drop(NamedTuple):
    """A stereo frame that will never be complete: counted with ``reason``."""

    t_ns: int
    reason: str
    detail: str


class Wait(NamedTuple):
    """A stereo frame still waiting for the inputs named in ``waiting``."""

    t_ns: int
    waiting: List[str]


class Ready(NamedTuple):
    """A complete stereo frame: the images by side and the joint state of its stamp."""

    t_ns: int
    images: Dict[str, Any]
    joints: Any


class _Frame:
    """Both images of one stamp as they arrive; ``rejected`` once one image was refused."""

    __slots__ = ('images', 'rejected')

    def __init__(self):
        self.images: Dict[str, Any] = {}
        self.rejected = False


class StereoPairer:
    """
    Left and right images paired by stamp, each pair matched with its joint state.

    A frame is complete when both images of its stamp and its joint state are here: the
    first joint state stamped in [t, t + ``window_ns``) (one physics step: the simulator
    publishes the state of the step it renders from with the frame). It is dropped when it
    never can be: the other side's images moved past it (left/right stamp mismatch), its
    joint state was rejected or skipped, or it fell ``stale_ns`` behind the newest input.
    Newer frames supersede older ones still waiting. Images older than the last frame
    published or ``stale_ns`` behind the newest input are refused.

    Parameters
    ----------
    stale_ns : int
        How far (ns) an input may lag the newest one (the node's ``stale_timeout_s``).
    window_ns : int
        The physics step (ns): how far after a frame its joint state may be stamped.
    history_ns : int
        How long (ns) joint states are kept behind the newest input (``joint_history_s``).
    sides : tuple of str
        The two image sources, in the order the texts name them.

    """

    def __init__(self, stale_ns: int, window_ns: int, history_ns: int,
                 sides: Tuple[str, str] = ('left', 'right')):
        """Create the pairer with nothing received (see the class docstring)."""
        self.stale_ns = stale_ns
        self.window_ns = window_ns
        self.sides = sides
        self._frames: Dict[int, _Frame] = {}
        self._joints: StampHistory = StampHistory(horizon_ns=history_ns, strict=False)
        self._bad_joints: StampHistory = StampHistory(horizon_ns=history_ns, strict=False)
        self._newest_image = {side: -1 for side in sides}
        #: The newest stamp of any input (images and joint states).
        self.newest_ns = -1
        #: The stamp of the last frame published (:meth:`published`).
        self.last_published_ns = -1

    def __len__(self) -> int:
        """Return the number of frames pending (incomplete or refused, not yet forgotten)."""
        return len(self._frames)

    def _seen(self, t_ns: int) -> None:
        self.newest_ns = max(self.newest_ns, t_ns)

    def offer_image(self, side: str, t_ns: int, image: Any,
                    error: Optional[Rejection] = None) -> Optional[Rejection]:
        """
        Take the ``side`` image stamped ``t_ns``; return why it is refused, or None.

        Parameters
        ----------
        side : str
            One of :attr:`sides`.
        t_ns : int
            Its stamp (ns).
        image
            The decoded image, handed back by :class:`Ready`.
        error : Rejection, optional
            Why the node could not decode it: the frame is then refused as well.

        Returns
        -------
        Rejection or None
            ``error``, 'out of order' (not after the last frame published) or 'stale';
            the frame of a refused image is skipped, its other image dropped silently.

        """
        self._seen(t_ns)
        self._newest_image[side] = max(self._newest_image[side], t_ns)
        rejection = error
        if rejection is None and t_ns <= self.last_published_ns:
            rejection = Rejection('out of order', f'stamp {t_ns} ns is not after the last '
                                  f'published frame {self.last_published_ns} ns')
        if rejection is None and self.newest_ns - t_ns > self.stale_ns:
            rejection = Rejection('stale', f'{(self.newest_ns - t_ns) * 1e-9:.3f} s behind '
                                  'the newest input')
        frame = self._frames.setdefault(t_ns, _Frame())
        if rejection is not None:
            frame.rejected = True
            frame.images.clear()
        elif not frame.rejected:
            frame.images[side] = image
        return rejection

    def offer_joints(self, t_ns: int, joints: Any) -> None:
        """Keep the joint state stamped ``t_ns`` (a late one is inserted in order)."""
        self._seen(t_ns)
        self._joints.add(t_ns, joints)
        self._prune_joints()

    def offer_bad_joints(self, t_ns: int, reason: str) -> None:
        """Note that the joint state stamped ``t_ns`` was rejected for ``reason``."""
        self._seen(t_ns)
        self._bad_joints.add(t_ns, reason)
        self._prune_joints()

    def _prune_joints(self) -> None:
        self._joints.prune(self.newest_ns)
        self._bad_joints.prune(self.newest_ns)

    def published(self, t_ns: int) -> None:
        """Note that the frame at ``t_ns`` was published: older images are out of order."""
        self.last_published_ns = t_ns

    def joints_at(self, t_ns: int) -> Tuple[Any, Optional[str]]:
        """
        Return ``(joints, None)`` for the frame at ``t_ns``, (None, None) to wait, (None, why).

        The joint state is the first stamped in [t_ns, t_ns + window_ns); a rejected one
        there, or a first one past the window, means the frame will never have one (why).
        """
        good = self._joints.at_or_after(t_ns)
        bad = self._bad_joints.at_or_after(t_ns)
        if bad is not None and (good is None or bad[0] < good[0]):
            if bad[0] - t_ns < self.window_ns:
                return None, f'joint state of the image rejected ({bad[1]})'
            return None, 'no joint state within one physics step at or after the image stamp'
        if good is None:
            return None, None
        if good[0] - t_ns < self.window_ns:
            return good[1], None
        return None, 'no joint state within one physics step at or after the image stamp'

    def poll(self, blocker: Optional[str] = None) -> Iterator[Any]:
        """
        Decide every pending frame, oldest first; yield what became of each.

        Parameters
        ----------
        blocker : str, optional
            What else the node still waits for (e.g. its camera model): a complete frame
            then waits too, and a frame that times out names it.

        Yields
        ------
        Drop, Wait or Ready
            :class:`Drop` for a frame that never can be complete and for each older frame
            a :class:`Ready` one supersedes (before it); :class:`Wait` for a frame still
            waiting; :class:`Ready` for a complete frame, which leaves the pairer.
            A refused frame is forgotten without a word once both sides moved past it.

        """
        for t_ns in sorted(self._frames):
            frame = self._frames.get(t_ns)
            if frame is None:
                continue
            if frame.rejected:
                # Already counted when its image was refused; forget it once both came.
                if all(self._newest_image[s] >= t_ns for s in self.sides) \
                        or self.newest_ns - t_ns > self.stale_ns:
                    del self._frames[t_ns]
                continue
            drop = None
            missing = [s for s in self.sides if s not in frame.images]
            for side in missing:
                if self._newest_image[side] > t_ns:
                    other = self.sides[1] if side == self.sides[0] else self.sides[0]
                    drop = ('left/right stamp mismatch',
                            f'{other} image at {t_ns * 1e-9:.9f} s has no {side} image')
            joints, why = self.joints_at(t_ns)
            if drop is None and why is not None:
                drop = ('no joint state', why)
            waiting = [f'{s} image' for s in missing] + (['joint state'] if joints is None
                                                         else [])
            waiting += [blocker] if blocker else []
            if drop is None and self.newest_ns - t_ns > self.stale_ns:
                drop = ('timed out', f'frame at {t_ns * 1e-9:.9f} s waited for '
                        + ', '.join(waiting))
            if drop is not None:
                del self._frames[t_ns]
                yield Drop(t_ns, *drop)
                continue
            if missing or joints is None or blocker:
                yield Wait(t_ns, waiting)
                continue
            del self._frames[t_ns]
            for older in [t for t in self._frames if t < t_ns]:
                del self._frames[older]
                yield Drop(older, 'superseded',
                           f'frame at {older * 1e-9:.9f} s overtaken by a newer one')
            yield Ready(t_ns, frame.images, joints)
