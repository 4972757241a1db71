"""
The adaptive feedback's lockstep rule (docs/design.md §4), plain code without rclpy.

Frames are answered in stamp order, each with the joint state at its stamp (kept, or
interpolated between the two that bracket it: :class:`ibvs_common.sync.JointTrack`) and, for
a law that needs it, the frame's feature status (was it measured?). Used by
:mod:`.adaptive_feedback_node`.
"""

from typing import Any, Callable, Dict, List, Optional, Tuple

from ibvs_common.sync import JointTrack, PendingQueue, Rejection


class FrameLockstep:
    """
    Frames answered in stamp order, each with the joint state at its stamp.

    The simulator renders frame n from the first physics step at or after n * T_cam,
    stamps it with that step and publishes that step's joint state with it: the joints of a
    frame are the state stamped as it is. A real cell's joint_state_broadcaster publishes on
    its own cycle: there the state is interpolated between the two that bracket the frame
    (:class:`ibvs_common.sync.JointTrack`). A frame whose state can never be had (none
    before it, a gap wider than the measured rate allows) is answered all the same, with a
    :class:`~ibvs_common.sync.Rejection` in place of its joints: the node holds its output
    and counts it, since the joint controller waits for an answer to every frame.
    Optionally a frame also waits for its status (was it
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
    action_ns : callable, optional
        The time (ns) from which a frame's answer acts, from its stamp
        (:func:`ibvs_common.timing.feedback_action_ns`): a frame then also waits for a joint
        state stamped at or after it, the state its features are predicted to
        (:mod:`.prediction`, :meth:`action_joints`). None: the frame's own stamp.

    """

    def __init__(self, history: int = 2000, needs_status: bool = False, *,
                 joints_name: str = 'joint_states', status_name: str = 'feature_status',
                 full_note: str = '', action_ns: Optional[Callable[[int], int]] = None
                 ) -> None:
        """Create the lockstep with nothing received (see the class docstring)."""
        self.history = history
        self.needs_status = needs_status
        self.joints_name = joints_name
        self.status_name = status_name
        self.joints: JointTrack[Any] = JointTrack(max_len=history, strict=True)
        self.frames: PendingQueue[Any] = PendingQueue(history, full_note)
        self._measured: Dict[int, bool] = {}
        self._action_ns = action_ns

    @property
    def last_answered_ns(self) -> Optional[int]:
        """Return the stamp of the last frame answered, None before the first."""
        return self.frames.last_popped_ns

    def forget(self) -> None:
        """Forget every joint state, frame and status (the clock jumped back)."""
        self.joints.forget()
        self.frames.forget()
        self._measured.clear()

    def offer_joints(self, t_ns: int, joints: Any) -> Optional[Rejection]:
        """Keep the joint state at ``t_ns``; 'stale stamp' unless after the newest one."""
        return self.joints.add(t_ns, joints)

    def offer_frame(self, t_ns: int, item: Any) -> Optional[Rejection]:
        """Queue the frame at ``t_ns``; 'stale stamp' unless after the newest, 'buffer full'."""
        return self.frames.offer(t_ns, item)

    def offer_status(self, t_ns: int, measured: Any) -> Optional[Rejection]:
        """
        Keep whether the frame at ``t_ns`` was measured; return why not, or None.

        ``measured`` is returned with the frame by :meth:`pop_ready` as it was given: a
        bool, or the frame's whole status where the caller needs more of it.

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
        joints, why = self.joints.at(t_ns)
        return self._missing(t_ns, joints is None and why is None)

    def _missing(self, t_ns: int, no_joints_yet: bool) -> List[str]:
        missing = []
        if no_joints_yet:
            missing.append(f'{self.joints_name} at or after {t_ns} ns')
        elif self._action_ns is not None:
            action = self._action_ns(t_ns)
            newest = self.joints.newest
            if newest is None or newest < action:
                missing.append(f'{self.joints_name} at or after {action} ns (when its '
                               'q_feedback acts)')
        if self.needs_status and t_ns not in self._measured:
            missing.append(f'{self.status_name} of frame {t_ns} ns')
        return missing

    def pop_ready(self) -> Optional[Tuple[int, Any, Any, bool]]:
        """
        Take the oldest pending frame if its inputs are here.

        Returns
        -------
        tuple of (int, item, joints, bool) or None
            The frame's stamp and item, the joint state at its stamp (or the
            :class:`~ibvs_common.sync.Rejection` that says why it has none) and whether it
            was measured (True without statuses); None while nothing is pending or the
            oldest frame still waits.

        """
        if not self.frames:
            return None
        t_ns = self.frames.first_ns
        joints, why = self.joints.at(t_ns)  # once a frame: it may interpolate
        if self._missing(t_ns, joints is None and why is None):
            return None
        t_ns, item = self.frames.pop()
        if joints is None:
            joints = Rejection('no joint state', why)
        measured = self._measured.pop(t_ns, True)
        for old in [s for s in self._measured if s < t_ns]:
            del self._measured[old]
        return t_ns, item, joints, measured

    def action_joints(self) -> Tuple[Optional[int], Any]:
        """
        Return (stamp, state) of the newest joint state: the one a frame is predicted to.

        When :meth:`pop_ready` answers a frame this is the state at the frame's action time
        in lockstep (the simulator cannot pass it before the answer), and the newest the
        encoders gave on a free-running cell: the delay each frame really carries.
        (None, None) before any state.
        """
        newest = self.joints.newest
        if newest is None:
            return None, None
        return newest, self.joints.at(newest)[0]
