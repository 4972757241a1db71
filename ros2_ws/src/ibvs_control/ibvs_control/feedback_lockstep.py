"""
The joint controller's lockstep rule (docs/design.md §4), plain code without rclpy.

Which /joint_states the joint controller can answer now, and with which q_feedback: the
feedback of the frame acting at the state's stamp
(:func:`ibvs_common.timing.feedback_frame_ns`) or, for a lost frame, the one held. Used
by :mod:`.joint_controller_node` and by the model-only loop (:mod:`.closed_loop`), so both
answer by the very same rule.
"""

from typing import Any, Dict, List, Optional, Set, Tuple

from ibvs_common.sync import PendingQueue, Rejection
from ibvs_common.timing import feedback_frame_ns


class FeedbackLockstep:
    """
    Which /joint_states the joint controller can answer now, and with which q_feedback.

    The answer to the state at t needs the q_feedback of the frame acting at t
    (:func:`ibvs_common.timing.feedback_frame_ns`: none before the first frame acts), or word that
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
                 lost_name: str = 'frame_lost') -> None:
        """Create the lockstep with nothing received (see the class docstring)."""
        feedback_frame_ns(0, camera_period_ns, latency_ns, step_ns)  # checks the periods
        self.camera_period_ns = camera_period_ns
        self.latency_ns = latency_ns
        self.step_ns = step_ns
        self.max_buffer = max_buffer
        self.feedback_name = feedback_name
        self.lost_name = lost_name
        self.states: PendingQueue[Any] = PendingQueue(max_buffer)
        #: q_feedback by frame stamp, from the one still acting on.
        self.feedback: Dict[int, Any] = {}
        #: Stamps of the lost frames still to come into play.
        self.lost: Set[int] = set()
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
