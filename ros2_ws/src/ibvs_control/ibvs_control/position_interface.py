"""
The joint controller's position interface, without ROS (docs/design.md §4, free-running).

With ``command_interface: position`` the arm's own drive closes the joint loop (a real
IRB 4600 through ros2_control and ABB's EGM), and the joint controller sends joint position
references at its ``command_rate_hz``: the time-optimal, jerk-limited move toward the
feedforward's target plus the q_feedback (:class:`PositionShaper`), in the joint order of
the ros2_control controller (:func:`joint_permutation`). Which frame's q_feedback each
command uses, and which command is the first to use a frame (the latency measurement), is
:class:`FeedbackHold`.
"""

from collections.abc import Mapping
import math
from typing import Any

from ibvs_common import shared_params as shared
from ibvs_common.shared_params import joint_permutation  # noqa: F401 (this module's too)
from ibvs_model import IRB4600
from ibvs_model.drive import (ACCELERATION_LIMITS, check_limits, EGM_DELAY_S, JERK_LIMITS,
                              SPEED_LIMITS)
import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import node_params
from .controllers import synchronised_move
from .governor import ReferenceGovernor


class PositionShaper:
    """
    Turn a joint target into a time-optimal, jerk-limited position reference (Ruckig).

    Every command period the reference is re-planned from its own last state (position,
    velocity, acceleration: no jump at a hand-over, whatever the target did) toward the
    target at rest, with Ruckig (PyPI ``ruckig``: time-optimal, jerk-limited, synchronised
    so that every joint arrives at once on a straight joint-space line when it starts at
    rest), under the IRB 4600's speed limits times ``speed_margin``, each at most
    ``max_speed`` (rad/s: the EGM session's MaxSpeedDeviation), and the acceleration and
    jerk limits of :mod:`ibvs_model.drive`: a reference the drive can follow without
    saturating, its own loop linear. The target is first clipped to the joint ranges less
    ``range_margin`` (the drive refuses a reference beyond a joint's range; the margin
    covers the encoders' offset d_q). Every reference obeys the limits by construction.

    Each :meth:`step` advances by the time since the last one (``dt``), not by a nominal
    period: free-running, a command timer on sim time can skip a tick when /clock jumps,
    and the reference must keep the pace of the arm, not of the ticks.
    """

    def __init__(self, command_rate_hz: float, speed_limits: ArrayLike = SPEED_LIMITS,
                 acceleration_limits: ArrayLike = ACCELERATION_LIMITS,
                 speed_margin: float = 1.0,
                 position_limits: tuple[ArrayLike, ArrayLike] = (IRB4600.q_min, IRB4600.q_max),
                 range_margin: float = 0.02, max_speed: float = math.inf,
                 jerk_limits: ArrayLike = JERK_LIMITS, synchronised: bool = True) -> None:
        """
        Nominal rate ``command_rate_hz``; limits (6,) rad/s, rad/s^2, rad/s^3 and rad.

        ``synchronised``: the joints move together (a planned move), or each on its own
        (a velocity law's corrections: :func:`.controllers.synchronised_move`).
        """
        if not (np.isfinite(command_rate_hz) and command_rate_hz > 0.0):
            raise ValueError(f'command_rate_hz must be > 0, got {command_rate_hz}')
        if not (0.0 < speed_margin <= 1.0):
            raise ValueError(f'speed_margin must be in (0, 1], got {speed_margin}')
        if not max_speed > 0.0:
            raise ValueError(f'max_speed must be > 0, got {max_speed}')
        v_max, a_max = check_limits(speed_limits, acceleration_limits)
        j_max = np.asarray(jerk_limits, dtype=float)
        if j_max.shape != (6,) or not np.all(np.isfinite(j_max)) or np.any(j_max <= 0.0):
            raise ValueError(f'jerk limits must be 6 finite values > 0, got {jerk_limits}')
        self.period = 1.0 / command_rate_hz
        #: The speed limit of each joint's reference (rad/s): per joint the smaller of the
        #: arm's (times ``speed_margin``) and the cap ``max_speed``.
        self.speed_limits = np.minimum(speed_margin * v_max, float(max_speed))
        self.acceleration_limits = a_max
        self.jerk_limits = j_max
        self.low = np.asarray(position_limits[0], dtype=float) + range_margin
        self.high = np.asarray(position_limits[1], dtype=float) - range_margin
        self._governor = ReferenceGovernor(self.period, self.speed_limits, a_max,
                                           jerk_limits=j_max, synchronised=synchronised)

    @property
    def state(self) -> tuple[NDArray[np.float64], NDArray[np.float64],
                             NDArray[np.float64]] | None:
        """Return the reference's position, velocity, acceleration (6,) each; None before."""
        return self._governor.state

    @property
    def started(self) -> bool:
        """Return whether :meth:`start` was called."""
        return self.state is not None

    def start(self, q: ArrayLike) -> None:
        """Start from the measured joints ``q`` (6,), at rest."""
        self._governor.reset(q)

    def target(self, q_ref: ArrayLike) -> NDArray[np.float64]:
        """Return ``q_ref`` (6,) clipped to the joint ranges less ``range_margin``."""
        return np.clip(np.asarray(q_ref, dtype=float), self.low, self.high)

    def step(self, q_ref: ArrayLike, dt: float | None = None) -> NDArray[np.float64]:
        """
        Advance ``dt`` seconds (default one nominal period) toward ``q_ref`` (6,) at rest.

        Returns the reference to send (its velocity and acceleration: :attr:`state`).
        ``dt`` is clipped to [0, 25 periods]: a long pause (the command timer starved) does
        not turn into one jump.
        """
        if not self.started:
            raise RuntimeError('start() the shaper from the measured joints first')
        dt = self.period if dt is None else min(max(float(dt), 0.0), 25.0 * self.period)
        return self._governor.step(self.target(q_ref), dt=dt)

    def preview(self, points: int) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                            NDArray[np.float64]]:
        """
        Return the next ``points`` nominal periods of the current plan, state untouched.

        Positions, velocities and accelerations (``points``, 6) each: row k is the plan k +
        1 periods after the last :meth:`step`, heading for that step's target at rest (the
        future points of a trajectory window, ``trajectory_window_points``, whose velocities
        give the arm's drive its speed reference).
        """
        if not self.started:
            raise RuntimeError('start() the shaper from the measured joints first')
        rows = np.zeros((3, int(points), 6))
        for k in range(int(points)):
            for i, value in enumerate(self._governor.ahead((k + 1) * self.period)):
                rows[i, k] = value
        return rows[0], rows[1], rows[2]

    def duration(self, q_ref: ArrayLike) -> float:
        """Return the time (s) the reference takes from its state to ``q_ref`` at rest."""
        if not self.started:
            raise RuntimeError('start() the shaper from the measured joints first')
        return float(self._governor.plan(self.target(q_ref)).duration)

    def stopping_point(self) -> NDArray[np.float64]:
        """
        Return where the reference comes to rest if braked now at the limits.

        The end of Ruckig's jerk-limited stop from the reference's state, within the joint
        ranges: the target of a controlled stop (the reference decelerates to it and stays;
        it does not turn back to where the stop was asked).
        """
        if not self.started:
            raise RuntimeError('start() the shaper from the measured joints first')
        trajectory = self._governor.plan(None)
        return self.target(self._governor.sample(trajectory, trajectory.duration)[0])


def shaper_for(values: Mapping[str, Any], margins: bool = True) -> PositionShaper:
    """
    Return the joint controller's shaper for its parameters ``values`` (by name).

    ``command_rate_hz``, ``speed_margin``, ``drive_acceleration_margin``,
    ``max_joint_speed_deg_s`` and ``feedforward_method``
    (:func:`.controllers.synchronised_move`), each its parameter's default where ``values``
    does not set it: the one place the position interface's limits are put together, for
    the controller and for the bound (:func:`time_optimal_s`). ``margins`` False leaves
    the two margins out: the arm's own limits, the speed cap and the drive's.
    """
    def value(param):
        return values.get(param.name, param.default) if margins else 1.0
    margin = value(node_params.DRIVE_ACCELERATION_MARGIN)
    return PositionShaper(
        values.get(shared.COMMAND_RATE_HZ.name, shared.COMMAND_RATE_HZ.default),
        speed_margin=value(node_params.SPEED_MARGIN),
        acceleration_limits=margin * np.asarray(ACCELERATION_LIMITS),
        max_speed=math.radians(values.get(shared.MAX_JOINT_SPEED_DEG_S.name,
                                          shared.MAX_JOINT_SPEED_DEG_S.default)),
        jerk_limits=margin * np.asarray(JERK_LIMITS),
        synchronised=synchronised_move(values.get(node_params.FEEDFORWARD_METHOD.name,
                                                  node_params.FEEDFORWARD_METHOD.default)))


def time_optimal_s(q_start: ArrayLike, goal: ArrayLike, values: Mapping[str, Any]) -> float:
    """
    Return the time-optimal bound (s) of a move through the position interface.

    The duration of Ruckig's move from ``q_start`` at rest to ``goal`` at rest (6,) under
    the arm's own limits with ``values`` (:func:`shaper_for` without the margins: the speed
    cap, the drive's speed, acceleration and jerk limits), plus the drive's dead time
    (:data:`ibvs_model.drive.EGM_DELAY_S`): no move of the arm from there, with these
    limits, reaches the goal sooner. The joint controller plans inside them (its margins),
    and what that costs is in the bound's excess.
    """
    shaper = shaper_for(values, margins=False)
    shaper.start(q_start)
    return shaper.duration(goal) + EGM_DELAY_S


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
