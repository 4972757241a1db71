r"""
The IRB 4600's position interface as ABB's Externally Guided Motion (EGM) presents it (no ROS).

One place for the numbers that both sides of a position-controlled cell use: the joint
controller shapes its reference with them (:class:`ibvs_control.position_interface.
PositionShaper`) and the simulator's drive model tracks the reference with them
(:class:`ibvs_sim.position_servo.PositionServo`).

- ``EGM_RATE_HZ`` = 250: EGM exchanges a position reference and the feedback every 4 ms
  (ABB, *Application manual - Externally Guided Motion*, 3HAC073318-001, section "EGM
  Position Guidance": "This can be done every 4 ms").
- ``EGM_DELAY_S`` = 0.05: the dead time from a reference to the motion. ABB's manual
  (the same section) gives "a control lag of 10-20 ms depending on the robot type"; users
  of EGM through abb_libegm measure more: "a dead time of ~50 ms" with joint position and
  velocity references in raw mode (ros-industrial/abb_libegm #111), and a lag of 40-50 ms
  once tuned, 70-80 ms before (#49). A large arm (IRB 4600) is taken at what users
  measure: 50 ms.
- ``EGM_BANDWIDTH_HZ`` = 6.4: the bandwidth of the position loop seen through EGM, the
  speed it asks for per unit of position error, v = 2 pi f e + v_ref (EGM's "Proportional
  Position Gain" with the speed reference v_ref added; #111 tracks with gains of 0 to 10).
  With no speed reference a steady move lags by the dead time plus 1 / (2 pi f) = 25 ms:
  75 ms, #49's 70-80 ms untuned; with it, by the dead time alone, #111's 50 ms.
  forward_command_controller claims only the position interface and abb_ros2 sets the
  velocity command to 0 on activation (``abb_hardware_interface.cpp`` at 05cbabe,
  ``on_activate``), so the forward_command path tracks on the gain alone;
  joint_trajectory_controller, which abb_ros2 configures with the position and velocity
  interfaces (``abb_bringup/config/abb_controllers.yaml`` at 713c4c2), sends each point's velocity.
  Assumptions to measure on the cell (docs/real_cell.md): a step of 1 deg on one joint
  through EGM gives the dead time and the time constant 1 / (2 pi f).
- ``SPEED_LIMITS``, ``ACCELERATION_LIMITS``, ``JERK_LIMITS``: the arm's joint_limits file
  (:data:`.joint_limits.IRB4600_60_205`, where each number's source is written). ABB
  publishes the IRB 4600's axis speeds but not its accelerations: these are half of what
  the model's motor torques give against gravity at the paper's start poses for joints 1-3
  (174, 28 and 123 rad/s^2 for joint 1, 2, 3; the wrists' inertia is small), rounded down
  and made uniform: 10 rad/s^2 for joints 1-3, 20 rad/s^2 for the wrist. Half, as the
  effort mode's ``acceleration_margin``: what the drive can do at any pose, not at the best
  one. Nor its jerk: each is its joint's acceleration limit over ``JERK_RISE_S`` = 0.1 s,
  the time the reference takes to reach full acceleration: four time constants of the
  position loop (25 ms each) and twice EGM's dead time, so the drive follows a reference
  whose acceleration ramps that slowly without lagging into saturation; MoveIt
  Servo's Ruckig smoother needs the same three limits per joint (moveit2 53de800,
  ``moveit_core/online_signal_smoothing/src/ruckig_filter.cpp``,
  ``getVelAccelJerkBounds``). Assumptions to measure on the cell, as the others.
"""

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .joint_limits import IRB4600_60_205

EGM_RATE_HZ = 250.0
EGM_DELAY_S = 0.05
EGM_BANDWIDTH_HZ = 6.4
ACCELERATION_LIMITS = IRB4600_60_205.max_acceleration
#: What the jerk limits are derived from: each joint's acceleration over this (s).
JERK_RISE_S = 0.1
JERK_LIMITS = IRB4600_60_205.max_jerk
SPEED_LIMITS = IRB4600_60_205.max_velocity


def check_limits(speed_limits: ArrayLike, acceleration_limits: ArrayLike
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return the speed and acceleration limits as two (6,) float arrays.

    Parameters
    ----------
    speed_limits : array_like, shape (6,)
        Joint speed limits (rad/s).
    acceleration_limits : array_like, shape (6,)
        Joint acceleration limits (rad/s^2).

    Returns
    -------
    tuple of ndarray
        Both, as float arrays of shape (6,).

    Raises
    ------
    ValueError
        Unless both are six finite values > 0.

    """
    out = []
    for name, values in (('speed limits', speed_limits),
                         ('acceleration limits', acceleration_limits)):
        array = np.asarray(values, dtype=float)
        if array.shape != (6,) or not np.all(np.isfinite(array)) or np.any(array <= 0.0):
            raise ValueError(f'{name} must be 6 finite values > 0, got {list(values)}')
        out.append(array)
    return tuple(out)
