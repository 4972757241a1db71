"""
The joint controller's position interface, without ROS (docs/design.md §4, free-running).

With ``command_interface: position`` the arm's own drive closes the joint loop (a real
IRB 4600 through ros2_control and ABB's EGM), and the joint controller sends joint position
references at its ``command_rate_hz``: q_ref = q_feedforward(t) + q_feedback, shaped so that
the arm can follow it (:class:`PositionShaper`), in the joint order of the ros2_control
controller (:func:`joint_permutation`). Which frame's q_feedback each command uses, and
which command is the first to use a frame (the latency measurement), is
:class:`FeedbackHold`.
"""

import math

from ibvs_common.shared_params import joint_permutation  # noqa: F401 (this module's too)
from ibvs_model import IRB4600
from ibvs_model.drive import ACCELERATION_LIMITS, check_limits, SPEED_LIMITS
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .governor import ReferenceGovernor


class PositionShaper:
    """
    Turn q_ref into a position reference within the arm's speed and acceleration limits.

    The 'limited' actuators' reference governor (:class:`.governor.ReferenceGovernor`, a
    bang-bang law on the braking curve) at the command period, with the IRB 4600's speed
    limits times ``speed_margin``, each at most ``max_speed`` (rad/s: a first run's cap,
    e.g. the EGM session's MaxSpeedDeviation), and the acceleration limits of
    :mod:`ibvs_model.drive`:
    a reference the drive can follow without saturating, so that its own loop stays
    linear. A small correction (the feedback's) passes almost unchanged. The target is
    first clipped to the joint ranges less ``range_margin`` (the drive refuses a reference
    beyond a joint's range; the margin covers the encoders' offset d_q).

    Each :meth:`step` advances by the time since the last one (``dt``), not by a nominal
    period: free-running, a command timer on sim time can skip a tick when /clock jumps,
    and the reference must keep the pace of the arm, not of the ticks.
    """

    def __init__(self, command_rate_hz: float, speed_limits: ArrayLike = SPEED_LIMITS,
                 acceleration_limits: ArrayLike = ACCELERATION_LIMITS,
                 speed_margin: float = 1.0,
                 position_limits: tuple[ArrayLike, ArrayLike] = (IRB4600.q_min, IRB4600.q_max),
                 range_margin: float = 0.02, max_speed: float = math.inf) -> None:
        """Nominal rate ``command_rate_hz``; limits (6,) rad/s, rad/s^2 and rad; cap rad/s."""
        if not (np.isfinite(command_rate_hz) and command_rate_hz > 0.0):
            raise ValueError(f'command_rate_hz must be > 0, got {command_rate_hz}')
        if not (0.0 < speed_margin <= 1.0):
            raise ValueError(f'speed_margin must be in (0, 1], got {speed_margin}')
        if not max_speed > 0.0:
            raise ValueError(f'max_speed must be > 0, got {max_speed}')
        v_max, a_max = check_limits(speed_limits, acceleration_limits)
        self.period = 1.0 / command_rate_hz
        #: The speed limit of each joint's reference (rad/s): per joint the smaller of the
        #: arm's (times ``speed_margin``) and the cap ``max_speed``.
        self.speed_limits = np.minimum(speed_margin * v_max, float(max_speed))
        self.governor = ReferenceGovernor(self.period, self.speed_limits, a_max)
        self.low = np.asarray(position_limits[0], dtype=float) + range_margin
        self.high = np.asarray(position_limits[1], dtype=float) - range_margin

    @property
    def started(self) -> bool:
        """Return whether :meth:`start` was called."""
        return self.governor.r is not None

    def start(self, q: ArrayLike) -> None:
        """Start from the measured joints ``q`` (6,), at rest."""
        self.governor.reset(q)

    def step(self, q_ref: ArrayLike, dt: float | None = None) -> NDArray[np.float64]:
        """
        Advance ``dt`` seconds (default one nominal period) toward ``q_ref`` (6,).

        Returns the reference to send. ``dt`` is clipped to [0, 25 periods]: a long pause
        (the command timer starved) does not turn into one jump.
        """
        if not self.started:
            raise RuntimeError('start() the shaper from the measured joints first')
        dt = self.period if dt is None else min(max(float(dt), 0.0), 25.0 * self.period)
        if dt == 0.0:
            return self.governor.r.copy()
        self.governor.dt = dt
        return self.governor.step(np.clip(q_ref, self.low, self.high))

    def preview(self, targets: ArrayLike) -> NDArray[np.float64]:
        """
        Return the references of the next len(``targets``) nominal periods, state untouched.

        Row k is where the reference will be k + 1 periods after the last :meth:`step`,
        heading for ``targets[k]`` (the target of that time: the feedforward moves on): the
        future points of a trajectory window (``trajectory_window_points``,
        :mod:`ibvs_control.joint_controller_node`). The shaper itself does not advance.
        """
        if not self.started:
            raise RuntimeError('start() the shaper from the measured joints first')
        governor = self.governor
        saved = governor.r, governor.rd, governor.dt
        governor.dt = self.period
        try:
            return np.array([governor.step(np.clip(t, self.low, self.high))
                             for t in np.asarray(targets, dtype=float).reshape(-1, 6)]
                            ).reshape(-1, 6)
        finally:
            governor.r, governor.rd, governor.dt = saved

    def stopping_point(self) -> NDArray[np.float64]:
        """
        Return where the reference comes to rest if braked now at the acceleration limits.

        r + rd |rd| / (2 a_max) per joint, within the joint ranges: the target of a
        controlled stop (the reference decelerates to it on its braking curve and stays, it
        does not turn back to where the stop was asked).
        """
        governor = self.governor
        if governor.a_max is None:
            return governor.r.copy()
        stop = governor.r + governor.rd * np.abs(governor.rd) / (2.0 * governor.a_max)
        return np.clip(stop, self.low, self.high)


class FeedbackHold:
    """
    The q_feedback that each command uses: the newest one received, held until the next.

    Free-running, nobody waits: a command uses what has arrived. :meth:`offer` takes a
    q_feedback with its frame stamp; :meth:`use` returns the q_feedback for a command and,
    the first time a frame's q_feedback is used, that frame's stamp (exposure time), so the
    node can report the latency from exposure to the command that first acts on it.
    """

    def __init__(self, initial: ArrayLike) -> None:
        """Hold ``initial`` (6,) until the first q_feedback."""
        self.q = np.asarray(initial, dtype=float).copy()
        self.stamp_ns = None
        self._used = True

    def offer(self, stamp_ns: int, q: ArrayLike) -> tuple[str, str] | None:
        """
        Take the q_feedback of the frame stamped ``stamp_ns``.

        Returns None, or (reason, detail) when it is rejected: a stamp not newer than the
        one held (out of order or a duplicate; the newer one stays).
        """
        if self.stamp_ns is not None and stamp_ns <= self.stamp_ns:
            return ('out of order', f'frame {stamp_ns} ns, not newer than the frame '
                    f'{self.stamp_ns} ns already held')
        self.q = np.asarray(q, dtype=float).copy()
        self.stamp_ns = stamp_ns
        self._used = False
        return None

    def use(self) -> tuple[NDArray[np.float64], int | None]:
        """Return (q_feedback, stamp ns of the frame used for the first time, or None)."""
        first = None if self._used else self.stamp_ns
        self._used = True
        return self.q, first
