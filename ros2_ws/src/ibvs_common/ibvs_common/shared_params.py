"""
Parameters that several nodes read, declared the same way everywhere, and their groups.

A scenario file (``ibvs_bringup/config/scenario*.yaml``) sets them under ``/**`` so that
every node started with ``--ros-args --params-file`` sees the same values; each node
declares only those it uses (undeclared overrides are ignored by rclpy).

Those that go together are groups (:func:`ibvs_common.params.group_field`), each with its
cross-checks and what follows from it computed once, as ros2_controllers nests a
controller's parameters: :class:`Timing` (the rates and ages of docs/design.md §4 and the
stamp leads), :class:`Target` (the target pose and where its features come from,
:class:`TargetSource`), :class:`Plant` (the simulated robot's departures from the model)
and :class:`Interface` (how the arm is commanded, and with it the time mode). A node's
config holds a group as one field; the parameters keep their ROS names.
"""

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
import enum
from functools import cached_property
import math
from typing import Any, TYPE_CHECKING

from ibvs_model import IRB4600, paper
import numpy as np
from numpy.typing import NDArray

from .params import Param, param_field, ParamConfig, ParameterError
from .timing import check_camera_rate, period_ns, seconds_to_ns, stamp_lead_ns

if TYPE_CHECKING:
    from ibvs_model.robot import RobotParams

SCENARIO = Param('scenario', 1, 'paper scenario (section 5.1) giving the start pose', '-',
                 low=1, high=3)
START_JOINTS = Param(
    'start_joints', [], 'start joint angles (true angles, 6 values) of a task; empty: the '
    "scenario's start pose", 'rad', low=-7.0, high=7.0)
DISTURBANCE_DEG = Param(
    'disturbance_deg', [0.0] * 6,
    'joint disturbance d_q: true angle = encoder angle + d_q (paper: scenarios 1 and 3)',
    'deg', low=-10.0, high=10.0, length=6)
TARGET_POSITION = Param('target_position', list(paper.TARGET_POSITION),
                        'target flange position in {O} (section 5.1)', 'm',
                        low=-3.0, high=3.0, length=3)
TARGET_ROTATION = Param('target_rotation',
                        [float(v) for row in paper.TARGET_ROTATION for v in row],
                        'target flange rotation [n s a] in {O}, row-major 3x3', '-',
                        low=-1.0, high=1.0, length=9)


class TargetSource(str, enum.Enum):
    """Where the target features p_bar come from: the value of ``target_features_source``."""

    #: The paper: the target markers projected with the calibrated camera, F(q_target).
    MODEL = 'model'
    #: Measured by the feature node on a stereo pair of the tool held at the target.
    TAUGHT = 'taught'


TARGET_FEATURES_SOURCE = Param(
    'target_features_source', TargetSource.MODEL.value, "target features p_bar: 'model' "
    '(the paper: the target markers projected with the calibrated camera, F(q_target)) or '
    "'taught' (measured by the feature node on a stereo pair of the tool placed at the "
    'target pose before the run)', '-', choices=tuple(source.value for source in TargetSource))


def taught(values: Mapping[str, Any]) -> bool:
    """Return whether a run of these parameter values (by name) teaches its target."""
    source = values.get(TARGET_FEATURES_SOURCE.name, TARGET_FEATURES_SOURCE.default)
    return TargetSource(source) is TargetSource.TAUGHT


#: The slowest rate a rate parameter takes (Hz): a period of a second at most. A timer and a
#: stamp hold a period as whole nanoseconds; a rate near 0 (``1e-300``) has none that they
#: hold, and no loop of this graph waits seconds between two of its frames or commands.
MIN_RATE_HZ = 1.0
CAMERA_RATE_HZ = Param('camera_rate_hz', 30.0, 'stereo frame rate (ZED 2 HD720: 15/30/60)',
                       'Hz', low=MIN_RATE_HZ, high=100.0)
FEEDBACK_LATENCY_S = Param(
    'feedback_latency_s', 0.0,
    'camera-to-command latency in sim time: q_feedback of a frame acts this long after it '
    '(a ZED 2 delivers a frame 2-3 frame periods after its exposure: 0.067-0.1 s at 30 Hz)',
    's', low=0.0, high=1.0)
PHYSICS_RATE_HZ = Param('physics_rate_hz', 1000.0, 'physics and joint-loop rate', 'Hz',
                        low=100.0, high=10000.0)
TAU_IN = Param('tau_in', paper.TAU_IN, 'inner-loop time constant tau_in (eq. 28-29)', 's',
               low=0.0, high=1.0, low_open=True)
OMEGA_N = Param('omega_n', paper.OMEGA_N, 'outer-loop natural frequency (eq. 36)', 'rad/s',
                low=0.0, high=1000.0, low_open=True)
ZETA = Param('zeta', paper.ZETA, 'outer-loop damping ratio (eq. 36)', '-',
             low=0.0, high=10.0, low_open=True)
L2_SCALE = Param('l2_scale', 1.0, 'factor on link length L2 of the simulated robot only '
                 '(model uncertainty, Figure 13)', '-', low=0.1, high=2.0)
L4_SCALE = Param('l4_scale', 1.0, 'factor on link length L4 of the simulated robot only '
                 '(model uncertainty, Figure 13)', '-', low=0.1, high=2.0)
ACTUATORS = Param('actuators', 'ideal', "'ideal' (the paper: no limits) or 'limited' "
                  '(IRB 4600 speed and torque limits)', '-', choices=('ideal', 'limited'))
MAX_JOINT_SPEED_DEG_S = Param(
    'max_joint_speed_deg_s', 20.0,
    "command_interface 'position': no joint reference moves faster than this, whatever the "
    "arm's own limits (the joint controller's shaper takes the smaller of it and "
    "speed_margin times the IRB 4600's per joint), and the simulated EGM drive caps each "
    "joint's speed at it, as the RAPID's EGMActJoint \\MaxSpeedDeviation is set to the "
    "same value on a cell. 20: abb_ros2's example RAPID (docs/real_cell.md); raise both "
    'together',
    'deg/s', low=0.0, high=1000.0, low_open=True)
STALE_TIMEOUT_S = Param('stale_timeout_s', 0.5,
                        'inputs older than this (sim time) are rejected as stale, and '
                        '/joint_states stamped further than this ahead of the newest time a '
                        'node knows as from a bad publisher', 's',
                        low=0.0, high=60.0, low_open=True)


def target_from_parameters(values: Mapping[str, Any]) -> NDArray[np.float64]:
    """
    Return the target T_E^O of the 'target_position' / 'target_rotation' values by name.

    :func:`ibvs_model.paper.target_pose` (a rotation given with few digits is made
    orthonormal, as the IK target of eq. 43 needs); a parameter missing from ``values``
    takes its default. Raises ParameterError naming 'target_rotation' when it is not a
    rotation.
    """
    position, rotation = (values.get(spec.name, spec.default)
                          for spec in (TARGET_POSITION, TARGET_ROTATION))
    try:
        return paper.target_pose(position, rotation)
    except ValueError as exc:
        raise ParameterError(f"parameter 'target_rotation' = {rotation!r} is invalid: {exc}; "
                             'allowed: a rotation matrix, row-major') from None


# -- a real cell: position interface and free-running time (docs/design.md §4) --------------
COMMAND_INTERFACE = Param(
    'command_interface', 'effort', "how the joint controller drives the arm: 'effort' (the "
    'paper: computed torque at physics_rate_hz on /joint_effort_commands, in lockstep) or '
    "'position' (joint position references at command_rate_hz for a ros2_control position "
    "controller, the arm's own drive closing the loop, free-running: the simulator runs on "
    'its own at real_time_factor, as a real cell does)', '-',
    choices=('effort', 'position'))
POSITION_COMMAND_TYPE = Param(
    'position_command_type', 'forward_command', "with command_interface 'position': "
    "'forward_command' (std_msgs/Float64MultiArray for ros2_controllers' "
    'forward_command_controller on /forward_position_controller/commands) or '
    "'joint_trajectory' (trajectory_msgs/JointTrajectory for a joint_trajectory_controller "
    'on /joint_trajectory_controller/joint_trajectory)', '-',
    choices=('forward_command', 'joint_trajectory'))
COMMAND_RATE_HZ = Param(
    'command_rate_hz', 250.0, "with command_interface 'position': the rate of the position "
    "references (ABB EGM: 250 Hz); free-running, the simulator's /clock runs at least this "
    'fast, so that sim-time timers fire at it', 'Hz', low=MIN_RATE_HZ, high=1000.0)
JOINTS = Param(
    'joints', ['joint_1', 'joint_2', 'joint_3', 'joint_4', 'joint_5', 'joint_6'],
    "the position controller's joints parameter: the order of the values in each command "
    "(ros2_control's forward_command_controller takes them in exactly this order); each "
    'of joint_1 ... joint_6 once', '-', length=6)


def lockstep(values: Mapping[str, Any]) -> bool:
    """
    Return whether a run of these parameter values (by name) runs in lockstep.

    The time mode follows from ``command_interface``, as ros2_controllers' controller class
    fixes its command interface: 'effort' (the computed-torque loop answers every physics
    step, so the simulator steps on each effort command) runs in lockstep, 'position' (the
    arm's drive waits for nobody) free-running, the simulator on its own at
    real_time_factor. A missing ``command_interface`` takes its default ('effort').
    """
    return values.get(COMMAND_INTERFACE.name, COMMAND_INTERFACE.default) == 'effort'


def check_camera_rate_param(values: Mapping[str, Any]) -> None:
    """
    Refuse a camera rate above the physics rate (ParameterError naming both).

    A frame is taken on a physics step (:func:`ibvs_common.timing.check_camera_rate`).
    """
    try:
        check_camera_rate(values['camera_rate_hz'], values['physics_rate_hz'])
    except ValueError as exc:
        raise ParameterError(f"parameter 'camera_rate_hz' = {values['camera_rate_hz']!r} "
                             f'is invalid: {exc}') from None


CAMERA_POSE = Param(
    'camera_pose', [0.0] * 7, 'the stereo camera frame {C} (midway between the lenses, x '
    'right, y down, z forward) in the robot base frame, as x, y, z, qx, qy, qz, qw: a '
    "hand-eye calibration's result, used instead of /stereo/pose; all zeros: take "
    '/stereo/pose', 'm, -', low=-20.0, high=20.0, length=7)


def camera_pose_from(values: Mapping[str, Any]) -> NDArray[np.float64] | None:
    """
    Return the 'camera_pose' parameter as a 4x4 T_C^O, or None when it is all zeros.

    Raises ParameterError naming it when its quaternion is not of unit length (within 1e-6).
    """
    import numpy as np
    from scipy.spatial.transform import Rotation

    pose = np.asarray(values.get(CAMERA_POSE.name, CAMERA_POSE.default), dtype=float)
    if not pose.any():
        return None
    if abs(np.linalg.norm(pose[3:]) - 1.0) > 1e-6:
        raise ParameterError(f"parameter 'camera_pose' = {pose.tolist()!r} is invalid: the "
                             f'quaternion (qx, qy, qz, qw) has length '
                             f'{np.linalg.norm(pose[3:]):.6g}, not 1; allowed: '
                             f'{CAMERA_POSE.allowed()}')
    tf = np.eye(4)
    tf[:3, :3] = Rotation.from_quat(pose[3:]).as_matrix()
    tf[:3, 3] = pose[:3]
    return tf


def start_joints(values: Any) -> NDArray[np.float64] | None:
    """
    Return ``start_joints`` as 6 angles (rad), or None when empty (the scenario's start).

    Raises :class:`ParameterError` naming it unless it is empty or has 6 values, each
    within its joint's range (``IRB4600.q_min``, ``q_max``: a start the arm cannot be in
    would leave the feedforward nothing to plan from). The simulator, its config's check
    before start and the model-only loop take it alike (a task's start is data).
    """
    values = START_JOINTS.check(list(values))
    if not values:
        return None
    if len(values) != 6:
        raise ParameterError(f"parameter 'start_joints' = {list(values)!r} is invalid: has "
                             f"{len(values)} values; allowed: empty (the scenario's start) "
                             'or 6 joint angles (rad)', START_JOINTS.name)
    q = np.asarray(values, dtype=float)
    low, high = np.asarray(IRB4600.q_min), np.asarray(IRB4600.q_max)
    for j in np.flatnonzero((q < low) | (q > high)):
        raise ParameterError(
            f"parameter 'start_joints' = {list(values)!r} is invalid: joint {j + 1} at "
            f'{math.degrees(q[j]):.1f} deg is outside its range [{math.degrees(low[j]):.1f}, '
            f'{math.degrees(high[j]):.1f}] deg', START_JOINTS.name)
    return q


def joint_permutation(joints: Iterable[str], names: Iterable[str]) -> NDArray[np.int_]:
    """
    Return the indices that reorder values given in ``names`` order into ``joints`` order.

    ``values[joint_permutation(joints, names)]`` lists them as ``joints`` does. ``joints``
    is the ros2_control controller's ``joints`` parameter: forward_command_controller takes
    Float64MultiArray data in exactly that order. Raises ValueError unless ``joints`` names
    each of ``names`` once.
    """
    joints, names = list(joints), list(names)
    if sorted(joints) != sorted(names) or len(set(joints)) != len(joints):
        raise ValueError(f'{joints} must name each of {names} exactly once')
    return np.array([names.index(j) for j in joints])


def joint_order(joints: Iterable[str]) -> NDArray[np.int_]:
    """
    Return :func:`joint_permutation` of ``joints`` (a ros2_control controller's) from ours.

    ``values[joint_order(joints)]`` lists contract-order values (``contract.JOINT_NAMES``)
    as ``joints`` does. Raises ParameterError naming ``joints`` unless it names each of
    them once: the joint controller's and the free-running simulator's configurations
    check it, so that ``ibvs run`` refuses it before any node starts.
    """
    from . import contract  # here: it imports rclpy, which the model-only loop does without
    try:
        return joint_permutation(joints, contract.JOINT_NAMES)
    except ValueError as exc:
        raise ParameterError(f"parameter 'joints' = {list(joints)!r} is invalid: {exc}",
                             'joints') from None


# -- the groups (module docstring) -----------------------------------------------------------
@dataclass(frozen=True)
class Timing(ParamConfig):
    """
    The rates and ages of docs/design.md §4, and the periods and stamp leads they give.

    Cross-check (at construction, so by ``ibvs run`` before any node starts): frames come
    no faster than physics steps (:func:`check_camera_rate_param`). Each derived time is
    computed once, in integer nanoseconds (:mod:`ibvs_common.timing`).
    """

    camera_rate_hz: float = param_field(CAMERA_RATE_HZ)
    physics_rate_hz: float = param_field(PHYSICS_RATE_HZ)
    stale_timeout_s: float = param_field(STALE_TIMEOUT_S)
    feedback_latency_s: float = param_field(FEEDBACK_LATENCY_S)

    def __post_init__(self):
        """Check each value, then the camera rate against the physics rate."""
        super().__post_init__()
        check_camera_rate_param(self.values())

    @cached_property
    def camera_period_ns(self) -> int:
        """Return the frame period T_cam (ns)."""
        return period_ns(self.camera_rate_hz)

    @cached_property
    def step_ns(self) -> int:
        """Return the physics step (ns)."""
        return period_ns(self.physics_rate_hz)

    @cached_property
    def latency_ns(self) -> int:
        """Return ``feedback_latency_s`` (ns)."""
        return seconds_to_ns(self.feedback_latency_s)

    @cached_property
    def stale_timeout_ns(self) -> int:
        """Return ``stale_timeout_s`` (ns)."""
        return seconds_to_ns(self.stale_timeout_s)

    @cached_property
    def frame_lead_ns(self) -> int:
        """Return how far a frame-rate input's stamp may lead (:func:`.timing.stamp_lead_ns`)."""
        return stamp_lead_ns(self.stale_timeout_s, self.camera_period_ns)

    @cached_property
    def step_lead_ns(self) -> int:
        """Return how far a step-rate input's stamp may lead (/joint_states in lockstep)."""
        return stamp_lead_ns(self.stale_timeout_s, self.step_ns)


@dataclass(frozen=True)
class Target(ParamConfig):
    """The target flange pose T_E^O and the source of its features (:class:`TargetSource`)."""

    target_position: tuple[float, ...] = param_field(TARGET_POSITION)
    target_rotation: tuple[float, ...] = param_field(TARGET_ROTATION)
    target_features_source: str = param_field(TARGET_FEATURES_SOURCE)

    @property
    def source(self) -> TargetSource:
        """Return ``target_features_source`` as a :class:`TargetSource`."""
        return TargetSource(self.target_features_source)

    @property
    def taught(self) -> bool:
        """Return whether the target's features come from a teach (:data:`TargetSource.TAUGHT`)."""
        return self.source is TargetSource.TAUGHT

    @property
    def pose(self) -> NDArray[np.float64]:
        """
        Return T_E^O, a new array each time (:func:`target_from_parameters`).

        Raises ParameterError naming 'target_rotation' when it is not a rotation.
        """
        return target_from_parameters(self.values())


@dataclass(frozen=True)
class Plant(ParamConfig):
    """The simulated robot's departures from the model: the joint offsets and link lengths."""

    disturbance_deg: tuple[float, ...] = param_field(DISTURBANCE_DEG)
    l2_scale: float = param_field(L2_SCALE)
    l4_scale: float = param_field(L4_SCALE)

    @property
    def d_q(self) -> NDArray[np.float64]:
        """Return the joint disturbance in rad, a new array: true angle = encoder angle + d_q."""
        return np.radians(np.asarray(self.disturbance_deg, dtype=float))

    @property
    def robot(self) -> 'RobotParams':
        """Return the simulated robot's parameters: IRB 4600 with L2 and L4 scaled."""
        return IRB4600.scaled(self.l2_scale, self.l4_scale)


@dataclass(frozen=True)
class Interface(ParamConfig):
    """
    How the joint controller commands the arm, and with it the time mode (:func:`lockstep`).

    Cross-check: with the position interface, ``joints`` names each joint once
    (:func:`joint_order`), the controller's order of the values in a command.
    """

    command_interface: str = param_field(COMMAND_INTERFACE)
    position_command_type: str = param_field(POSITION_COMMAND_TYPE)
    command_rate_hz: float = param_field(COMMAND_RATE_HZ)
    joints: tuple[str, ...] = param_field(JOINTS)

    def __post_init__(self):
        """Check each value, then the position controller's joint order."""
        super().__post_init__()
        if not self.lockstep:
            joint_order(self.joints)

    @property
    def lockstep(self) -> bool:
        """Return whether the graph runs in lockstep: the effort interface (:func:`lockstep`)."""
        return lockstep(self.values())
