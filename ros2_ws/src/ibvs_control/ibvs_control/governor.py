"""
Reference governor of the 'limited' actuator mode (no ROS).

The inner loop of eq. (28)-(29) is a high-gain linear loop (bandwidth 1/tau_in = 100 rad/s).
Behind speed and torque limits its gain collapses when it saturates, the crossover falls
below the lead zero of G_c, where a double integrator has no phase margin, and the arm
limit-cycles (seen in the model-only loop: +-0.15 rad on joint 1 with 30 rad/s^2). So in
'limited' mode the reference q_ref = q_ff + q_fb first passes through this governor,
which turns it into a trajectory r the real arm can follow (|r'| <= speed limit,
|r''| <= acceleration limit) and the linear loop then tracks r with a small error, out of
saturation. Small references (the feedback's corrections) pass almost unchanged.

Each joint follows its target with a bang-bang law on a braking curve: the desired speed
is the largest from which the acceleration limit still stops it at the target,
v = -a dt / 2 + sqrt((a dt / 2)^2 + 2 a |e|) (the exact stopping distance of the discrete
semi-implicit integration), capped by the speed limit and by |e| / dt (no overshoot in one
step); the speed then moves toward it by at most a dt per step.
"""

import numpy as np
from numpy.typing import ArrayLike, NDArray


class ReferenceGovernor:
    """Shape a reference into a trajectory with bounded speed and acceleration, per joint."""

    def __init__(self, dt: float, speed_limits: ArrayLike,
                 acceleration_limits: ArrayLike | None = None) -> None:
        """
        Sample time ``dt`` (s); limits (6,) in rad/s and rad/s^2, all > 0.

        The acceleration limits may instead be given at each :meth:`step` (they depend on
        the configuration through M(q) and h(q, qdot)).
        """
        self.dt = float(dt)
        self.v_max = np.asarray(speed_limits, dtype=float)
        self.a_max = None if acceleration_limits is None \
            else np.asarray(acceleration_limits, dtype=float)
        if self.dt <= 0.0 or np.any(self.v_max <= 0.0) or (
                self.a_max is not None and np.any(self.a_max <= 0.0)):
            raise ValueError('dt, speed and acceleration limits must be > 0')
        self.r = None
        self.rd = None

    def reset(self, position: ArrayLike, velocity: ArrayLike | None = None) -> None:
        """Start at ``position`` with ``velocity`` (default at rest)."""
        self.r = np.asarray(position, dtype=float).copy()
        self.rd = np.zeros_like(self.r) if velocity is None \
            else np.asarray(velocity, dtype=float).copy()

    def step(self, target: ArrayLike, acceleration_limits: ArrayLike | None = None
             ) -> NDArray[np.float64]:
        """Advance one sample toward ``target``; return the shaped reference r."""
        target = np.asarray(target, dtype=float)
        a_max = self.a_max if acceleration_limits is None \
            else np.asarray(acceleration_limits, dtype=float)
        if a_max is None or np.any(a_max <= 0.0):
            raise ValueError('acceleration limits must be given and > 0')
        if self.r is None:
            self.reset(target)
            return self.r.copy()
        error = target - self.r
        half = 0.5 * a_max * self.dt
        brake = -half + np.sqrt(half * half + 2.0 * a_max * np.abs(error))
        v_des = np.sign(error) * np.minimum(np.minimum(self.v_max, brake),
                                            np.abs(error) / self.dt)
        step = a_max * self.dt
        self.rd = self.rd + np.clip(v_des - self.rd, -step, step)
        self.r = self.r + self.rd * self.dt
        return self.r.copy()
