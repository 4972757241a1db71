"""
Reference governor: the time-optimal, jerk-limited, synchronised reference (no ROS).

The inner loop of eq. (28)-(29) is a high-gain linear loop (bandwidth 1/tau_in = 100 rad/s).
Behind speed and torque limits its gain collapses when it saturates, the crossover falls
below the lead zero of G_c, where a double integrator has no phase margin, and the arm
limit-cycles (seen in the model-only loop: +-0.15 rad on joint 1 with 30 rad/s^2). So with
'limited' actuators the reference q_ref = q_ff + q_fb first passes through this governor,
which turns it into a trajectory r the real arm can follow (|r'| <= speed limit,
|r''| <= acceleration limit, |r'''| <= jerk limit) and the linear loop then tracks r with a
small error, out of saturation. The position interface shapes its reference with the same
governor (:class:`.position_interface.PositionShaper`): there the arm's own drive tracks r.

Each time the target changes, r is re-planned from its own state (position,
velocity, acceleration: no jump, whatever the target did) toward the target at rest with
Ruckig (PyPI ``ruckig``: time-optimal, jerk-limited, any initial state), time-synchronised:
every joint arrives at once, so that a move from rest follows the straight line in joint
space and the tool does not pass the target because one joint arrived before the others
(a per-joint shaping does, by millimetres). In the rare states where Ruckig's
synchronisation finds no profile, each joint on its own time-optimal profile (still within
every limit). Small references (the feedback's corrections) pass almost unchanged.
"""

import numpy as np
from numpy.typing import ArrayLike, NDArray
import ruckig


#: 'limited' actuators: the time (s) the reference takes to reach full acceleration, which
#: sets its jerk limits (acceleration limit / rise): two tau_in of the paper's inner loop,
#: so that r'' is smooth at the loop's own time scale.
JERK_RISE_S = 0.02
#: Ruckig's synchronisations, tried in turn: phase (every joint on the same profile, scaled:
#: the straight line in joint space, where the state allows it: from rest, or moving along
#: the line to the target), time (every joint arrives at once), none (each on its own).
SYNCHRONIZATIONS = (ruckig.Synchronization.Phase, ruckig.Synchronization.Time,
                    ruckig.Synchronization.No)
#: The jerk limits' scales Ruckig is tried with, in turn (:meth:`ReferenceGovernor.plan`).
JERK_RETRY_SCALES = (1.0, 0.999, 0.99)


class ReferenceGovernor:
    """Shape a reference into a time-optimal trajectory with bounded speed, acceleration, jerk."""

    def __init__(self, dt: float, speed_limits: ArrayLike,
                 acceleration_limits: ArrayLike | None = None,
                 jerk_limits: ArrayLike | None = None, jerk_rise_s: float | None = None,
                 synchronised: bool = True) -> None:
        """
        Sample time ``dt`` (s); limits (6,) in rad/s, rad/s^2 and rad/s^3, all > 0.

        The acceleration limits may instead be given at each :meth:`step` (they depend on
        the configuration through M(q) and h(q, qdot)); so may the jerk limits, or they
        follow the acceleration limits as a / ``jerk_rise_s`` (the time the reference takes
        to reach full acceleration). ``synchronised``: the joints move together
        (:data:`SYNCHRONIZATIONS`, a planned move), or each on its own time-optimal profile
        (a velocity law's stream of corrections: :func:`.controllers.synchronised_move`).
        """
        self.synchronizations = SYNCHRONIZATIONS if synchronised \
            else (ruckig.Synchronization.No,)
        self.dt = float(dt)
        self.v_max = np.asarray(speed_limits, dtype=float)
        self.a_max = None if acceleration_limits is None \
            else np.asarray(acceleration_limits, dtype=float)
        self.j_max = None if jerk_limits is None else np.asarray(jerk_limits, dtype=float)
        self.jerk_rise_s = jerk_rise_s
        if not self.dt > 0.0 or self.v_max.shape != (6,) or not np.all(self.v_max > 0.0) or (
                self.a_max is not None and not np.all(self.a_max > 0.0)) or (
                self.j_max is not None and not np.all(self.j_max > 0.0)):
            raise ValueError('dt, speed, acceleration and jerk limits must be > 0')
        if (self.j_max is None) == (jerk_rise_s is None) or (
                jerk_rise_s is not None and not jerk_rise_s > 0.0):
            raise ValueError('give either jerk_limits or jerk_rise_s > 0')
        self._otg = ruckig.Ruckig(6)
        self._input = ruckig.InputParameter(6)
        self._input.max_velocity = self.v_max.tolist()
        self._trajectory = ruckig.Trajectory(6)
        #: The reference's state: position, velocity, acceleration (6,) each; None before
        #: :meth:`reset`.
        self.state = None
        self._key = None
        self._planned = None
        self._elapsed = 0.0

    @property
    def r(self) -> NDArray[np.float64] | None:
        """Return the reference's position (None before :meth:`reset`)."""
        return None if self.state is None else self.state[0]

    def reset(self, position: ArrayLike, velocity: ArrayLike | None = None) -> None:
        """Start at ``position`` with ``velocity`` (default at rest), no acceleration."""
        position = np.asarray(position, dtype=float).copy()
        velocity = np.zeros(6) if velocity is None else np.asarray(velocity, dtype=float)
        self.state = (position, np.clip(velocity, -self.v_max, self.v_max), np.zeros(6))
        self._key, self._planned, self._elapsed = None, None, 0.0

    def step_limits(self, acceleration_limits: ArrayLike | None = None
                    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return the acceleration and jerk limits (6,) of a step, given those of now."""
        a_max = self.a_max if acceleration_limits is None \
            else np.asarray(acceleration_limits, dtype=float)
        if a_max is None or not np.all(a_max > 0.0):
            raise ValueError('acceleration limits must be given and > 0')
        if self.j_max is not None:
            return a_max, self.j_max
        # Full speed no sooner than one rise time: beyond v_max / rise an acceleration
        # limit buys nothing but a profile Ruckig cannot resolve numerically (joint 6:
        # 1e6 rad/s^2 against 6 rad/s).
        a_max = np.minimum(a_max, self.v_max / self.jerk_rise_s)
        return a_max, a_max / self.jerk_rise_s

    def plan(self, target: NDArray[np.float64] | None, acceleration_limits: ArrayLike | None = None
             ) -> ruckig.Trajectory:
        """
        Return Ruckig's trajectory from the reference's state to ``target`` at rest.

        ``target`` None: the stop at the limits (to rest wherever that is). The state is
        not changed.
        """
        a_max, j_max = self.step_limits(acceleration_limits)
        position, velocity, acceleration = self.state
        inp = self._input
        inp.max_acceleration = a_max.tolist()
        inp.current_position = position.tolist()
        inp.current_velocity = velocity.tolist()
        inp.current_acceleration = acceleration.tolist()
        if target is None:
            inp.control_interface = ruckig.ControlInterface.Velocity
        else:
            inp.control_interface = ruckig.ControlInterface.Position
            inp.target_position = np.asarray(target, dtype=float).tolist()
        inp.target_velocity = [0.0] * 6
        inp.target_acceleration = [0.0] * 6
        trajectory = ruckig.Trajectory(6)
        # Ruckig's first step (each joint's own time-optimal profile) can fail to resolve a
        # profile numerically at a few states, near the end of a move with a tiny distance
        # left; a jerk limit lower by a part in a thousand resolves them (and is still
        # within the limit).
        for scale in JERK_RETRY_SCALES:
            inp.max_jerk = (scale * j_max).tolist()
            for sync in self.synchronizations:
                inp.synchronization = sync
                try:
                    result = self._otg.calculate(inp, trajectory)
                except ruckig.RuckigError as exc:
                    result = exc
                if result in (ruckig.Result.Working, ruckig.Result.Finished):
                    return trajectory
        raise ArithmeticError(f'Ruckig could not plan the reference: {result}')

    @staticmethod
    def sample(trajectory: ruckig.Trajectory, t: float
               ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Return (position, velocity, acceleration) of ``trajectory`` at ``t`` (s)."""
        position, velocity, acceleration = trajectory.at_time(min(t, trajectory.duration))
        return np.array(position), np.array(velocity), np.array(acceleration)

    def step(self, target: ArrayLike, acceleration_limits: ArrayLike | None = None,
             dt: float | None = None) -> NDArray[np.float64]:
        """
        Advance ``dt`` (default the sample time) toward ``target``; return the reference r.

        Re-planned from the reference's state, under the limits of now, when the target
        changed; on along the plan made for it otherwise (replanning from a sampled state
        would give the same course but for rounding, and under limits that change with
        the configuration it would break the synchronisation: the joints would no longer
        brake together, and the tool would pass the target; the acceleration margin
        covers what the configuration takes from the torque during a move).
        """
        target = np.asarray(target, dtype=float)
        if self.state is None:
            self.reset(target)
            return self.state[0].copy()
        key = target.tobytes()
        if key != self._key:
            self._key, self._elapsed = key, 0.0
            self._planned = self.plan(target, acceleration_limits)
        self._elapsed += self.dt if dt is None else float(dt)
        self.state = self.sample(self._planned, self._elapsed)
        return self.state[0].copy()

    def ahead(self, t: float
              ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Return the plan's state ``t`` s after the last :meth:`step`, state untouched."""
        if self._planned is None:
            return self.state[0].copy(), np.zeros(6), np.zeros(6)
        return self.sample(self._planned, self._elapsed + t)
