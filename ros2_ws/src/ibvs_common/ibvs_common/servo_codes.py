"""
The codes of /ibvs/servo_status and /ibvs/feedback_status (:class:`ServoStatus`), no ROS.

Part of the topic contract (:mod:`.contract` re-exports them) in a module of their own, so
that what reads the codes needs neither rclpy nor the control package: the launcher's
status line, the analysis of a bag, a supervisor, the model-only loop.
"""

from enum import IntEnum


class ServoStatus(IntEnum):
    """
    One code of SERVO_STATUS (and FEEDBACK_STATUS): MoveIt Servo's 0-6 and -1, ours from 10.

    MoveIt Servo's own are ``moveit_servo::StatusCode`` (moveit2 jazzy 4d84106
    ``moveit_ros/moveit_servo/include/moveit_servo/utils/datatypes.hpp`` L51-61), so that a
    supervisor written for Servo reads ours. The joint controller decides them
    (ibvs_control.servo_status).
    """

    INVALID = -1
    NO_WARNING = 0
    DECELERATE_FOR_APPROACHING_SINGULARITY = 1
    HALT_FOR_SINGULARITY = 2
    DECELERATE_FOR_LEAVING_SINGULARITY = 3
    DECELERATE_FOR_COLLISION = 4
    HALT_FOR_COLLISION = 5
    JOINT_BOUND = 6
    #: Not started: an input the first command waits for has never come (nothing is
    #: commanded).
    WAITING = 10
    #: Holding: /joint_states older than their timeout (where the arm is, is not known).
    HOLD_STALE_JOINT_STATES = 11
    #: Holding: no new camera frame within its timeout.
    HOLD_STALE_CAMERA = 12
    #: Holding: frames come but no q_feedback for them within its timeout.
    HOLD_STALE_FEEDBACK = 13
    #: Holding: the node's clock jumped back (a restarted simulator's /clock, an NTP step):
    #: every input's age and stamp order start again, and the arm holds until each input
    #: came again on the new time line.
    HOLD_CLOCK_JUMPED_BACK = 14
    #: Holding: sim time stopped (``use_sim_time``: /clock has not moved for the wall-time
    #: bound of :meth:`.sim_time.ClockWatch.stall_bound_s`): no input can age, and
    #: the simulator is not running.
    HOLD_CLOCK_STOPPED = 15
    #: Holding: a second publisher on an input the arm follows (/joint_states,
    #: /ibvs/q_feedback, the feedforward trajectory) or a second commander on the
    #: controller's own command topic, until it is gone.
    HOLD_SECOND_PUBLISHER = 16
    #: Not holding, a warning: the feedback node reports (on /ibvs/feedback_status) that
    #: the image error is small while the model puts the tool far from the target, the
    #: loop at rest: a local minimum of the image error (ibvs_control.minimum_watch). The arm
    #: stays where the law holds it; the run does not count as a success.
    LOCAL_MINIMUM = 17
