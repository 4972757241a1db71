"""
What both joint controllers share: the common inputs.

:class:`.node_params.JointControllerConfig` holds the parameters of
``joint_controller_node``; the time mode follows from the interface
(:attr:`ibvs_common.shared_params.Interface.lockstep`): effort in lockstep, position
free-running. :class:`JointControllerMode` reads the feedforward trajectory and the
q_feedback for either command interface (:mod:`.effort_controller`,
:mod:`.position_controller`) and hands them
on, as ros2_controllers' controllers share their reference and state interfaces while each
claims its own command interface.
"""

from typing import TYPE_CHECKING

from ibvs_common import contract
from ibvs_common.conversions import (check_finite, ignored_joints, InputError,
                                     position_bounds, read_joints, read_stamp, read_trajectory,
                                     trajectory_arrays, velocity_bounds)
from ibvs_common.kit import subscription
from ibvs_model import IRB4600
import numpy as np
from numpy.typing import NDArray
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

if TYPE_CHECKING:
    from builtin_interfaces.msg import Time
    from rclpy.node import Node

    from .node_params import JointControllerConfig

#: Largest |q_feedback| per joint (rad) that is taken as meant: the joint's whole travel.
FEEDBACK_BOUND_RAD = np.asarray(IRB4600.q_max) - np.asarray(IRB4600.q_min)


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

    def __init__(self, node: 'Node', config: 'JointControllerConfig') -> None:
        """Take the periods and stamp leads of ``config``; no topic is opened yet."""
        self.node = node
        self.config = config
        self.diagnostics = node.diagnostics
        self.dt_ns = config.timing.step_ns
        self.camera_ns = config.timing.camera_period_ns
        self.state_lead_ns = config.timing.step_lead_ns
        self.frame_lead_ns = config.timing.frame_lead_ns
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
