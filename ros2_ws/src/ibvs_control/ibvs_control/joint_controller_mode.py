"""
What both joint controllers share: the typed configuration and the common inputs.

:class:`JointControllerConfig` holds the parameters of ``joint_controller_node`` (each a
Param, checked at construction, and the rules across them: the position interface's joint
order; a dry run is of the position interface). The time mode follows from the interface
(:attr:`JointControllerConfig.lockstep`): effort in lockstep, position free-running.
:class:`JointControllerMode` reads the feedforward trajectory and the q_feedback for either
command interface (:mod:`.effort_controller`, :mod:`.position_controller`) and hands them
on, as ros2_controllers' controllers share their reference and state interfaces while each
claims its own command interface.
"""

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ibvs_common import contract
from ibvs_common import shared_params as shared
from ibvs_common.conversions import (check_finite, ignored_joints, InputError,
                                     position_bounds, read_joints, read_stamp, read_trajectory,
                                     stamp_lead_ns, trajectory_arrays, velocity_bounds)
from ibvs_common.kit import subscription
from ibvs_common.params import param_field, ParamConfig, ParameterError
from ibvs_common.timing import period_ns
from ibvs_model import IRB4600
import numpy as np
from numpy.typing import NDArray
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from . import node_params as own

if TYPE_CHECKING:
    from builtin_interfaces.msg import Time
    from rclpy.node import Node

#: Largest |q_feedback| per joint (rad) that is taken as meant: the joint's whole travel.
FEEDBACK_BOUND_RAD = np.asarray(IRB4600.q_max) - np.asarray(IRB4600.q_min)


@dataclass(frozen=True)
class JointControllerConfig(ParamConfig):
    """The parameters of joint_controller_node (each field: the parameter of its name)."""

    #: Rules between parameters, run at start and by ``ibvs run`` before any node starts.
    RULES = (shared.check_camera_rate_param,)

    tau_in: float = param_field(shared.TAU_IN)
    physics_rate_hz: float = param_field(shared.PHYSICS_RATE_HZ)
    camera_rate_hz: float = param_field(shared.CAMERA_RATE_HZ)
    feedback_latency_s: float = param_field(shared.FEEDBACK_LATENCY_S)
    actuators: str = param_field(shared.ACTUATORS)
    torque_limits: tuple[float, ...] = param_field(own.TORQUE_LIMITS)
    speed_margin: float = param_field(own.SPEED_MARGIN)
    feedforward_method: str = param_field(own.FEEDFORWARD_METHOD)
    acceleration_margin: float = param_field(own.ACCELERATION_MARGIN)
    drive_acceleration_margin: float = param_field(own.DRIVE_ACCELERATION_MARGIN)
    stale_timeout_s: float = param_field(shared.STALE_TIMEOUT_S)
    command_interface: str = param_field(shared.COMMAND_INTERFACE)
    command_rate_hz: float = param_field(shared.COMMAND_RATE_HZ)
    position_command_type: str = param_field(shared.POSITION_COMMAND_TYPE)
    joints: tuple[str, ...] = param_field(shared.JOINTS)
    joint_state_timeout_s: float = param_field(own.JOINT_STATE_TIMEOUT_S)
    frame_timeout_s: float = param_field(own.FRAME_TIMEOUT_S)
    max_joint_speed_deg_s: float = param_field(shared.MAX_JOINT_SPEED_DEG_S)
    trajectory_window_points: int = param_field(own.TRAJECTORY_WINDOW_POINTS)
    dry_run: bool = param_field(own.DRY_RUN)

    def __post_init__(self):
        """Check each value, then the joints (position) or that no dry run is asked (effort)."""
        super().__post_init__()
        if self.command_interface == 'position':
            shared.joint_order(self.joints)  # the ros2_control controller's joint order
        elif self.dry_run:
            raise ParameterError("parameter 'dry_run' = True is invalid with command_interface "
                                 "'effort': a dry run is of the position interface (the "
                                 "lockstep's simulator waits for every effort command); "
                                 "allowed: false (or command_interface 'position')")

    @property
    def lockstep(self) -> bool:
        """Return whether it runs in lockstep, by :func:`ibvs_common.shared_params.lockstep`."""
        return shared.lockstep(vars(self))


class JointControllerMode:
    """
    The inputs both command interfaces read; a subclass answers them.

    Reads /ibvs/feedforward_trajectory (latched; the last one received is used; taken as
    its serialized bytes and read as arrays, :mod:`ibvs_common.cdr`, so that a trajectory of
    thousands of points holds the executor, and the command timer with it, for
    milliseconds, not the time rclpy takes to build a Python object of each point) and
    /ibvs/q_feedback (six finite positions mapped by joint name, each within
    :data:`FEEDBACK_BOUND_RAD`; velocity and effort may be empty, a non-finite value there
    rejects it), every stamp through :func:`ibvs_common.conversions.read_stamp`. A subclass
    defines :meth:`now_ns`, :meth:`take_feedback` and :meth:`trajectory_arrived`.
    """

    #: The frame grid of q_feedback stamps ((camera period, physics period) in lockstep:
    #: :func:`ibvs_common.timing.is_frame_stamp`), None when any stamp is allowed.
    frames = None

    def __init__(self, node: 'Node', config: JointControllerConfig) -> None:
        """Take the periods and stamp leads of ``config``; no topic is opened yet."""
        self.node = node
        self.config = config
        self.diagnostics = node.diagnostics
        self.dt_ns = period_ns(config.physics_rate_hz)
        self.camera_ns = period_ns(config.camera_rate_hz)
        self.state_lead_ns = stamp_lead_ns(config.stale_timeout_s, self.dt_ns)
        self.frame_lead_ns = stamp_lead_ns(config.stale_timeout_s, self.camera_ns)
        self._trajectory = None
        self.commands = 0

    def subscribe_inputs(self) -> None:
        """Subscribe to the feedforward trajectory and the q_feedback."""
        subscription(self.node, JointTrajectory, contract.FEEDFORWARD_TRAJECTORY,
                     self._on_trajectory, contract.LATCHED, raw=True)
        subscription(self.node, JointState, contract.Q_FEEDBACK, self._on_feedback,
                     contract.RELIABLE)

    def close(self) -> None:
        """Release what the mode holds (nothing here)."""

    def _on_trajectory(self, raw):
        """Take a feedforward trajectory, read from its bytes as arrays (class docstring)."""
        try:
            arrays = trajectory_arrays(raw)
            read_stamp(arrays.stamp, self.now_ns(), self.state_lead_ns)
            trajectory = read_trajectory(arrays, self.dt_ns)
        except InputError as exc:
            self.diagnostics.reject(contract.FEEDFORWARD_TRAJECTORY, exc.reason, exc.detail)
            return
        self._trajectory = trajectory
        start_ns, positions = trajectory
        self.diagnostics.update(feedforward_start_ns=start_ns,
                                feedforward_points=len(positions))
        self.trajectory_arrived(start_ns)

    def _on_feedback(self, msg):
        source = contract.Q_FEEDBACK
        try:
            t_ns = read_stamp(msg.header.stamp, self.now_ns(), self.frame_lead_ns, self.frames)
            q = read_joints(msg)
            check_finite(msg, ('velocity', 'effort'))
        except InputError as exc:
            self.diagnostics.reject(source, exc.reason, exc.detail)
            return
        if np.any(np.abs(q) > FEEDBACK_BOUND_RAD):
            self.diagnostics.reject(source, 'out of range',
                                    f'{q.tolist()} rad: a joint beyond its whole travel')
            return
        rejection = self.take_feedback(t_ns, q)
        if rejection is not None:
            self.diagnostics.reject(source, *rejection)

    def read_joint_state(self, msg: JointState, velocity: bool = False
                         ) -> tuple[int, NDArray[np.float64], NDArray[np.float64] | None] | None:
        """Return a /joint_states' (stamp ns, q, qd or None), or None once rejected."""
        try:
            t_ns = read_stamp(msg.header.stamp, self.now_ns(), self.state_lead_ns)
            q = read_joints(msg, bound=position_bounds())
            qd = read_joints(msg, 'velocity', bound=velocity_bounds()) if velocity else None
        except InputError as exc:
            self.diagnostics.reject(contract.JOINT_STATES, exc.reason, exc.detail)
            return None
        self.diagnostics.note_ignored(contract.JOINT_STATES, ignored_joints(msg))
        return t_ns, q, qd

    def read_frame_stamp(self, source: str, stamp: 'Time') -> int | None:
        """Return a frame's stamp (ns) by the stamp rule, or None once rejected."""
        try:
            return read_stamp(stamp, self.now_ns(), self.frame_lead_ns, self.frames)
        except InputError as exc:
            self.diagnostics.reject(source, exc.reason, exc.detail)
            return None

    def q_feedforward(self, t_ns: int) -> NDArray[np.float64]:
        """Return the feedforward at ``t_ns``: the trajectory's point, held past its ends."""
        start_ns, positions = self._trajectory
        k = (t_ns - start_ns) // self.dt_ns
        return positions[min(max(k, 0), len(positions) - 1)]

    def feedforward_target(self) -> NDArray[np.float64]:
        """Return where the feedforward goes: its trajectory's last point (IK, eq. 43)."""
        return self._trajectory[1][-1]

    def now_ns(self) -> int:
        """Return the newest time the node knows (its clock and the stamps it accepted)."""
        raise NotImplementedError

    def take_feedback(self, t_ns: int, q: NDArray[np.float64]) -> tuple[str, str] | None:
        """Take a checked q_feedback; return (reason, detail) when it is refused."""
        raise NotImplementedError

    def trajectory_arrived(self, start_ns: int) -> None:
        """React to a new feedforward trajectory (stored in ``_trajectory``)."""
        raise NotImplementedError
