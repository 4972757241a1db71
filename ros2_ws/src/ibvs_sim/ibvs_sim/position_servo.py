"""
The simulated arm's own position servo, as a position-controlled IRB 4600 behaves (no ROS).

With ``command_interface: position`` the simulator is driven as a real cell's arm is through
ros2_control and ABB's EGM: joint position references come at the controller's rate, and
the drive's own loop tracks them. The model (numbers and their sources:
:mod:`ibvs_model.drive`), per physics step of ``dt``:

1. zero-order hold: the last reference received holds until a new one comes;
2. dead time: the drive acts on the reference of ``delay_s`` ago (a delay line of whole
   physics steps);
3. position loop of bandwidth ``bandwidth_hz`` (omega = 2 pi f) with EGM's speed
   reference added: desired speed v = v_ref + omega e, e = delayed reference - position,
   v_ref the delayed speed reference (0 when none is given: forward_command_controller
   claims the position interface only, and abb_ros2 sets EGM's velocity command to 0 on
   activation); the correction omega e is capped by the braking curve sqrt(2 a |e|) (the
   speed from which the acceleration limit still stops the joint at the reference, so a
   feasible reference is tracked without overshoot), v by the speed limits;
4. acceleration limit: the speed moves toward v by at most a dt; position += speed dt.

Kinematic, not torques: the result is a joint trajectory (q, qdot) that the simulator sets
in PyBullet each step (``World.reset``). A position-controlled industrial drive has a
current and speed loop far faster than its position loop, and its closed-loop response to
a reference is what the EGM user sees and what ABB documents; the rigid-body dynamics are
inside that loop. Driving PyBullet's own position motor instead would give an ideal,
unbounded loop, and driving it with torques would need a drive's gains tuned against the
simulated inertia, a model of the drive's tuning we have no numbers for.

Hold. :meth:`hold` (the reference went stale) replaces the reference by the position at
which each joint stops under its acceleration limit, as a drive's supervision stops the
arm; the next :meth:`command` resumes tracking.
"""

from collections import deque
import math

from ibvs_model.drive import (ACCELERATION_LIMITS, check_limits, EGM_BANDWIDTH_HZ,
                              EGM_DELAY_S, SPEED_LIMITS)
import numpy as np
from numpy.typing import ArrayLike, NDArray


class PositionServo:
    """A joint position servo with dead time, finite bandwidth and speed/acceleration limits."""

    def __init__(self, dt: float, q0: ArrayLike, bandwidth_hz: float = EGM_BANDWIDTH_HZ,
                 delay_s: float = EGM_DELAY_S, speed_limits: ArrayLike = SPEED_LIMITS,
                 acceleration_limits: ArrayLike = ACCELERATION_LIMITS) -> None:
        """
        Start at rest at ``q0`` (6,) rad with the reference q0; ``dt`` the physics step (s).

        Raises ValueError for dt or bandwidth not > 0, a negative delay, a bandwidth at which
        the sampled loop is not well damped (omega dt > 0.5), or bad limits.
        """
        self.dt = float(dt)
        if not (math.isfinite(self.dt) and self.dt > 0.0):
            raise ValueError(f'dt must be > 0, got {dt}')
        self.omega = 2.0 * math.pi * float(bandwidth_hz)
        if not (math.isfinite(self.omega) and self.omega > 0.0):
            raise ValueError(f'bandwidth_hz must be > 0, got {bandwidth_hz}')
        if self.omega * self.dt > 0.5:
            raise ValueError(f'bandwidth_hz {bandwidth_hz} is too high for a step of {dt} s '
                             f'(2 pi f dt must be <= 0.5)')
        if not (math.isfinite(delay_s) and delay_s >= 0.0):
            raise ValueError(f'delay_s must be >= 0, got {delay_s}')
        self.v_max, self.a_max = check_limits(speed_limits, acceleration_limits)
        self.delay_steps = int(round(delay_s / self.dt))
        q0 = np.asarray(q0, dtype=float)
        if q0.shape != (6,) or not np.all(np.isfinite(q0)):
            raise ValueError('q0 must be 6 finite values')
        self.q = q0.copy()
        self.qd = np.zeros(6)
        self.reference = q0.copy()
        self.holding = False
        self.speed_reference = np.zeros(6)
        self._line = deque([(q0.copy(), self.speed_reference)] * (self.delay_steps + 1),
                           maxlen=self.delay_steps + 1)

    def command(self, reference: ArrayLike, speed: ArrayLike | None = None) -> None:
        """
        Take a new reference (6,) rad and its speed (6,) rad/s; both hold until the next.

        ``speed`` None: no speed reference (0), as through forward_command_controller.
        """
        reference = np.asarray(reference, dtype=float)
        if reference.shape != (6,) or not np.all(np.isfinite(reference)):
            raise ValueError('a reference must be 6 finite values')
        speed = np.zeros(6) if speed is None else np.asarray(speed, dtype=float)
        if speed.shape != (6,) or not np.all(np.isfinite(speed)):
            raise ValueError('a speed reference must be 6 finite values')
        self.reference = reference.copy()
        self.speed_reference = speed.copy()
        self.holding = False

    def hold(self) -> None:
        """Stop each joint under its acceleration limit and hold it there (stale reference)."""
        if not self.holding:
            stop = self.qd * np.abs(self.qd) / (2.0 * self.a_max)
            self.reference = self.q + stop
            self.speed_reference = np.zeros(6)
            self._line.extend([(self.reference.copy(), self.speed_reference)]
                              * len(self._line))
            self.holding = True

    def step(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Advance one physics step; return the joint (position, velocity), two (6,) arrays."""
        self._line.append((self.reference.copy(), self.speed_reference.copy()))
        reference, speed = self._line[0]
        error = reference - self.q
        magnitude = np.abs(error)
        half = 0.5 * self.a_max * self.dt
        brake = -half + np.sqrt(half * half + 2.0 * self.a_max * magnitude)
        v_des = np.clip(speed + np.sign(error) * np.minimum(self.omega * magnitude, brake),
                        -self.v_max, self.v_max)
        change = self.a_max * self.dt
        self.qd = self.qd + np.clip(v_des - self.qd, -change, change)
        self.q = self.q + self.qd * self.dt
        return self.q.copy(), self.qd.copy()


class TrajectoryFollower:
    """
    joint_trajectory_controller as it feeds a position interface: the drive's reference.

    The controller manager updates the controller every 1 / ``update_rate_hz``; at each
    update the controller samples its trajectory at the update's time and writes the
    position to the hardware, which holds it until the next update. What is modelled is
    ros2_controllers' jazzy branch (commit ed360c9, ``joint_trajectory_controller/src/``):

    - a new trajectory replaces the current one at the next update
      (``joint_trajectory_controller.cpp`` ``update``, lines 276-283: the realtime buffer's
      newest message, ``current_trajectory_->update``);
    - the first time a trajectory is sampled, a header stamp of 0 becomes the time of that
      update (``trajectory.cpp`` ``sample``, lines 125-134), and the state before it is the
      measured one at that time (``joint_trajectory_controller.cpp`` lines 300-313,
      ``interpolate_from_desired_state`` false by default);
    - before its first point the sample is interpolated from that state to the first point
      (``trajectory.cpp`` lines 147-168), between points from the point at or before the
      time to the next (lines 175-195), and after the last point it is the last point
      (lines 208-240);
    - positions only (no velocities): the interpolation is linear
      (``interpolate_between_points``, lines 315-333), and the velocity it writes is the
      segment's slope; with the points' velocities it interpolates a cubic (quintic with
      accelerations) and writes its velocity. Here the position is the linear one in
      both cases (at the joint controller's 4 ms between points the spline differs from
      it by far less than the encoders resolve) and the velocity the points' own,
      interpolated linearly, where they carry it. abb_ros2's joint_trajectory_controller
      claims the position and velocity command interfaces (``abb_bringup/config/
      abb_controllers.yaml`` at 713c4c2), so the velocity reaches EGM as its speed reference.

    Times are integer nanoseconds of the simulator's clock.
    """

    def __init__(self, update_rate_hz: float) -> None:
        """Update every 1 / ``update_rate_hz`` s; no trajectory yet."""
        if not (math.isfinite(update_rate_hz) and update_rate_hz > 0.0):
            raise ValueError(f'update_rate_hz must be > 0, got {update_rate_hz}')
        self.period_ns = int(round(1e9 / update_rate_hz))
        self._pending = None
        self._current = None
        self._next_update_ns = None
        #: Updates that found no trajectory to sample (before the first one comes).
        self.idle_updates = 0

    @property
    def active(self) -> bool:
        """Return whether a trajectory has been received."""
        return self._current is not None or self._pending is not None

    def receive(self, stamp_ns: int, times_ns: ArrayLike, positions: ArrayLike,
                velocities: ArrayLike | None = None) -> None:
        """
        Take a trajectory; it replaces the current one at the next update.

        ``stamp_ns``: its header stamp (0: it starts at its first sampling);
        ``times_ns``: the points' time_from_start (N,), increasing; ``positions``: (N, 6);
        ``velocities``: (N, 6), the points' own, or None. Checked by the caller
        (:func:`ibvs_common.conversions.read_command_trajectory`).
        """
        times = np.asarray(times_ns, dtype=np.int64)
        positions = np.asarray(positions, dtype=float)
        if positions.ndim != 2 or positions.shape != (len(times), 6) or not len(times):
            raise ValueError('a trajectory must be N >= 1 points of 6 positions')
        if velocities is not None:
            velocities = np.asarray(velocities, dtype=float).copy()
            if velocities.shape != positions.shape:
                raise ValueError('velocities must be one row of 6 per point')
        self._pending = (int(stamp_ns), times, positions.copy(), velocities)

    def due(self, t_ns: int) -> bool:
        """Return whether the controller updates at ``t_ns`` (its first update: the first call)."""
        if self._next_update_ns is None:
            self._next_update_ns = int(t_ns)
        return t_ns >= self._next_update_ns

    def update(self, t_ns: int, q_measured: ArrayLike
               ) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """
        One controller update at ``t_ns``: return the (position, velocity) it writes, or None.

        Each (6,). None: no trajectory yet (the hardware keeps what it has). ``q_measured``
        (6,) is the joint state at ``t_ns``, the start of a trajectory's interpolation.
        """
        t_ns = int(t_ns)
        self._next_update_ns = t_ns + self.period_ns
        if self._pending is not None:
            stamp_ns, times, positions, velocities = self._pending
            self._pending = None
            start_ns = stamp_ns if stamp_ns != 0 else t_ns
            self._current = (start_ns + times, positions, velocities, t_ns,
                             np.asarray(q_measured, dtype=float).copy())
        if self._current is None:
            self.idle_updates += 1
            return None
        point_ns, positions, velocities, before_ns, before = self._current
        if t_ns < point_ns[0]:
            if point_ns[0] == before_ns:
                return positions[0].copy(), self._velocity(0, None)
            span = point_ns[0] - before_ns
            s = (t_ns - before_ns) / span
            return (before + max(s, 0.0) * (positions[0] - before),
                    (positions[0] - before) / (span * 1e-9))
        k = int(np.searchsorted(point_ns, t_ns, side='right')) - 1
        if k >= len(point_ns) - 1:
            return positions[-1].copy(), self._velocity(len(point_ns) - 1, None)
        span = point_ns[k + 1] - point_ns[k]
        s = (t_ns - point_ns[k]) / span
        slope = (positions[k + 1] - positions[k]) / (span * 1e-9)
        return positions[k] + s * (positions[k + 1] - positions[k]), self._velocity(k, s, slope)

    def _velocity(self, k: int, s: float | None,
                  slope: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """Return the velocity written at point k (s None) or s of the way to point k + 1."""
        velocities = self._current[2]
        if velocities is None:
            return np.zeros(6) if slope is None else slope
        if s is None:
            return velocities[k].copy()
        return velocities[k] + s * (velocities[k + 1] - velocities[k])
