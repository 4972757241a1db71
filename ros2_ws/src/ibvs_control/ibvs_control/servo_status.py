"""
The joint controller's status and its watch on its inputs, without ROS.

On a cell nothing waits: if the camera, the vision or the feedback stops, a position
controller that keeps following the feedforward with the last correction drives the arm on
blind, and forward_command_controller holds its last command forever. MoveIt Servo halts
when its commands are older than ``incoming_command_timeout`` and says why on ``~/status``.
The joint controller does the same with :class:`InputWatch`: every input it needs has an
age (the node's clock less the input's newest stamp) and a timeout; while one is older than
its timeout the controller holds the arm where it is, and the status (:class:`ServoStatus`,
published as one ``std_msgs/Int8`` code) says which input is stale. The ages need a clock
that runs forward: after a jump back every age would be negative and nothing could go
stale until the clock passed the old newest stamp again, so :meth:`InputWatch.forget` drops
them and holds until each input came again (HOLD_CLOCK_JUMPED_BACK); with sim time, a
/clock that stopped (a simulator that died) holds too (:func:`clock_stopped`). So does a
second publisher on an input the arm's motion follows, or a second commander on the
controller's own command topic (:func:`second_publisher`; who is seen there:
:class:`ibvs_common.kit.PublisherWatch`): each of its messages may be well formed, and the
arm would follow whichever came last.

One node publishes the status: the joint controller. What only the feedback node can
tell (the image error against the model's pose: :mod:`.minimum_watch`) it reports on its
own /ibvs/feedback_status, and the joint controller relays it (:class:`FeedbackStatus`)
while nothing of its own is to be said: a hold, or waiting, comes first.

The codes (:class:`ibvs_common.servo_codes.ServoStatus`, re-exported here) 0-6 and -1 are
MoveIt Servo's own, so that a supervisor written for Servo reads ours; 10 and up are this
stack's. The 0.1 s
default of ``joint_state_timeout_s`` is Servo's ``incoming_command_timeout``
(``moveit_ros/moveit_servo/config/servo_parameters.yaml`` L102-104).
"""

from collections.abc import Iterable, Mapping, Sequence
from typing import NamedTuple

from ibvs_common.publishers import describe
# The codes are the meaning of /ibvs/servo_status, so they live in the topic contract (a
# supervisor or the launcher reads them without this package); re-exported here.
from ibvs_common.servo_codes import ServoStatus  # noqa: F401


#: Each stale input's holding code.
HOLD_CODES = {'joint_states': ServoStatus.HOLD_STALE_JOINT_STATES,
              'camera': ServoStatus.HOLD_STALE_CAMERA,
              'feedback': ServoStatus.HOLD_STALE_FEEDBACK}


#: Every holding code: a stale input's, the clock's own, and a second publisher's.
HOLDING = frozenset(HOLD_CODES.values()) | {
    ServoStatus.HOLD_CLOCK_JUMPED_BACK, ServoStatus.HOLD_CLOCK_STOPPED,
    ServoStatus.HOLD_SECOND_PUBLISHER}


class Verdict(NamedTuple):
    """The status and the words that go with it (/diagnostics, the log)."""

    status: ServoStatus
    detail: str

    @property
    def holding(self) -> bool:
        """Return whether the arm is to be held (an input is stale, or the clock failed)."""
        return self.status in HOLDING


class InputWatch:
    """
    The ages of a controller's inputs against their timeouts.

    Parameters
    ----------
    timeouts_ns : mapping of str to int
        Each input's name (a key of :data:`HOLD_CODES`) and its timeout (ns), in the order
        of precedence: the first stale one names the status (the joint states first: with
        them stale, the others do not matter).
    required : iterable of str
        Inputs without an age (latched once, e.g. the feedforward trajectory) that must
        have come before anything is commanded.
    after_start : iterable of str
        Inputs with a timeout that the first command does not wait for: until one first
        comes, its age counts from the start (the first verdict at which every other
        input had come). The position controller starts the arm's planned move on the
        feedforward and the joint states and takes the camera and the q_feedback as they
        come: a ZED 2's first frame arrives 67-100 ms after its exposure, which the arm
        would otherwise spend at rest; with none within the timeout it holds as for a
        camera that stopped.

    """

    def __init__(self, timeouts_ns: Mapping[str, int], required: Iterable[str] = (),
                 after_start: Iterable[str] = ()) -> None:
        """Create the watch with nothing heard (see the class docstring)."""
        for name, timeout in timeouts_ns.items():
            if name not in HOLD_CODES:
                raise ValueError(f'unknown input {name!r}: expected one of {list(HOLD_CODES)}')
            if not timeout > 0:
                raise ValueError(f'timeout of {name!r} must be > 0, got {timeout}')
        self.timeouts_ns = dict(timeouts_ns)
        self.required = list(required)
        self.after_start = list(after_start)
        for name in self.after_start:
            if name not in self.timeouts_ns:
                raise ValueError(f'after_start input {name!r} has no timeout: expected one '
                                 f'of {list(self.timeouts_ns)}')
        self.newest_ns: dict[str, int] = {}
        self._present: set[str] = set()
        #: The time of the start (every input but ``after_start`` had come), else None.
        self.start_ns: int | None = None
        #: The last jump back (from ns, to ns) until every input came again, else None.
        self.jump: tuple[int, int] | None = None

    def heard(self, name: str, t_ns: int) -> None:
        """Note an input ``name`` stamped ``t_ns`` (an older stamp than the newest is kept out)."""
        self._present.add(name)
        if name in self.timeouts_ns:
            self.newest_ns[name] = max(t_ns, self.newest_ns.get(name, t_ns))

    def forget(self, from_ns: int, to_ns: int) -> None:
        """
        Take a jump back of the clock from ``from_ns`` to ``to_ns``: every age is unknown.

        The newest stamps are of the old time line (their ages would be negative: nothing
        would go stale for as long as the jump); they are dropped, and :meth:`verdict` holds
        with HOLD_CLOCK_JUMPED_BACK until each input with a timeout came again. Inputs
        without one (the latched feedforward) stay heard.
        """
        self.newest_ns.clear()
        self.jump = (int(from_ns), int(to_ns))
        self.start_ns = None

    def missing(self) -> list[str]:
        """Return the inputs that never came, required ones first."""
        return ([n for n in self.required if n not in self._present]
                + [n for n in self.timeouts_ns if n not in self._present])

    def awaited(self) -> list[str]:
        """Return the inputs the first command waits for: :meth:`missing`, not ``after_start``."""
        return [n for n in self.missing() if n not in self.after_start]

    def _age_ns(self, name: str, now_ns: int) -> tuple[int, str]:
        """Return the age (ns) of ``name`` at ``now_ns`` and its words."""
        if name in self.newest_ns:
            age = now_ns - self.newest_ns[name]
            return age, f'newest is {age * 1e-9:.3f} s old'
        age = now_ns - self.start_ns
        return age, f'none in the {age * 1e-9:.3f} s since the start'

    def verdict(self, now_ns: int) -> Verdict:
        """
        Return the status at ``now_ns`` and why.

        WAITING until every input but ``after_start`` came once (the start); after a jump
        back (:meth:`forget`) HOLD_CLOCK_JUMPED_BACK until each came again; then the hold
        code of the first input (in the order of ``timeouts_ns``) older than its timeout,
        an ``after_start`` input not heard yet aged from the start; else NO_WARNING.
        """
        awaited = self.awaited()
        if awaited:
            return Verdict(ServoStatus.WAITING, 'waiting for ' + ', '.join(awaited))
        if self.start_ns is None:
            self.start_ns = int(now_ns)
        if self.jump is not None:
            again = [n for n in self.timeouts_ns if n not in self.newest_ns]
            if again:
                from_ns, to_ns = self.jump
                return Verdict(ServoStatus.HOLD_CLOCK_JUMPED_BACK,
                               f'clock jumped back from {from_ns * 1e-9:.3f} s to '
                               f'{to_ns * 1e-9:.3f} s: holding the arm until fresh '
                               + ', '.join(again))
            self.jump = None
        for name, timeout in self.timeouts_ns.items():
            age, words = self._age_ns(name, now_ns)
            if age > timeout:
                return Verdict(HOLD_CODES[name], f'{name} stale: {words} (timeout '
                               f'{timeout * 1e-9:g} s): holding the arm')
        return Verdict(ServoStatus.NO_WARNING, 'ok')


def clock_stopped(stalled_s: float | None, bound_s: float) -> Verdict | None:
    """
    Return HOLD_CLOCK_STOPPED when sim time stood still ``stalled_s`` > ``bound_s``, else None.

    ``stalled_s``: the wall time since /clock last moved
    (:meth:`ibvs_common.sim_time.ClockWatch.stalled_s`), None before it first did.
    """
    if stalled_s is None or not stalled_s > bound_s:
        return None
    return Verdict(ServoStatus.HOLD_CLOCK_STOPPED,
                   f'clock stopped: /clock has not moved for {stalled_s:.1f} s of wall time '
                   f'(bound {bound_s:.1f} s): the simulator is not running; holding the arm')


def second_publisher(found: Mapping[str, Sequence[object]]) -> Verdict | None:
    """
    Return HOLD_SECOND_PUBLISHER naming each topic's newcomers in ``found``, else None.

    ``found``: {topic: the newcomers on it} (:func:`ibvs_common.publishers.newcomers`), of
    the topics the controller holds on; a topic without any may be left out.
    """
    words = '; '.join(describe(topic, new) for topic, new in found.items() if new)
    if not words:
        return None
    return Verdict(ServoStatus.HOLD_SECOND_PUBLISHER,
                   f'{words}: holding the arm until it is gone')


#: The codes the feedback node reports on /ibvs/feedback_status.
FEEDBACK_CODES = frozenset({ServoStatus.NO_WARNING, ServoStatus.LOCAL_MINIMUM})


class FeedbackStatus:
    """
    The feedback node's newest status (/ibvs/feedback_status), as the joint controller relays it.

    :meth:`take` checks a code (one of :data:`FEEDBACK_CODES`) and returns whether it
    changed; :meth:`over` lays it over the controller's own verdict.
    """

    def __init__(self) -> None:
        """Start with nothing reported: NO_WARNING."""
        self.status = ServoStatus.NO_WARNING

    def take(self, code: int) -> bool:
        """Take a reported code; ValueError names one the feedback node does not report."""
        if code not in {int(c) for c in FEEDBACK_CODES}:
            raise ValueError(f'code {code} is not one the feedback node reports (expected one '
                             f'of {sorted((int(c), c.name) for c in FEEDBACK_CODES)})')
        changed = ServoStatus(code) != self.status
        self.status = ServoStatus(code)
        return changed

    def over(self, verdict: Verdict) -> Verdict:
        """Return ``verdict``, or the feedback's warning where ``verdict`` is NO_WARNING."""
        if verdict.status != ServoStatus.NO_WARNING or self.status == ServoStatus.NO_WARNING:
            return verdict
        return Verdict(self.status, 'the feedback node reports a local minimum of the image '
                       'error: the image error is small while the model puts the tool far '
                       'from the target (its /diagnostics: image_error_norm_px, '
                       'model_position_error_m, model_tool_axis_error_deg)')
