"""
The simulated arm's own position servo, as a position-controlled IRB 4600 behaves (no ROS).

With ``command_interface: position`` the simulator is driven as a real cell's arm is through
ros2_control and ABB's EGM: joint position references come at the controller's rate, and
the drive's own loop tracks them. The model (numbers and their sources:
:mod:`ibvs_model.drive`), per physics step of ``dt``:

1. zero-order hold: the last reference received holds until a new one comes;
2. dead time: the drive acts on the reference of ``delay_s`` ago (a delay line of whole
   physics steps);
3. position loop of bandwidth ``bandwidth_hz`` (omega = 2 pi f): desired speed
   v = omega e, e = delayed reference - position; capped by the speed limits and by the
   braking curve sqrt(2 a |e|) (the speed from which the acceleration limit still stops the
   joint at the reference, so a feasible reference is tracked without overshoot);
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
        self._line = deque([q0.copy()] * (self.delay_steps + 1), maxlen=self.delay_steps + 1)

    def command(self, reference: ArrayLike) -> None:
        """Take a new reference (6,) rad; it holds until the next (zero-order hold)."""
        reference = np.asarray(reference, dtype=float)
        if reference.shape != (6,) or not np.all(np.isfinite(reference)):
            raise ValueError('a reference must be 6 finite values')
        self.reference = reference.copy()
        self.holding = False

    def hold(self) -> None:
        """Stop each joint under its acceleration limit and hold it there (stale reference)."""
        if not self.holding:
            stop = self.qd * np.abs(self.qd) / (2.0 * self.a_max)
            self.reference = self.q + stop
            self._line.extend([self.reference.copy()] * len(self._line))
            self.holding = True

    def step(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Advance one physics step; return the joint (position, velocity), two (6,) arrays."""
        self._line.append(self.reference.copy())
        error = self._line[0] - self.q
        magnitude = np.abs(error)
        half = 0.5 * self.a_max * self.dt
        brake = -half + np.sqrt(half * half + 2.0 * self.a_max * magnitude)
        v_des = np.sign(error) * np.minimum(np.minimum(self.omega * magnitude, brake),
                                            self.v_max)
        change = self.a_max * self.dt
        self.qd = self.qd + np.clip(v_des - self.qd, -change, change)
        self.q = self.q + self.qd * self.dt
        return self.q.copy(), self.qd.copy()
