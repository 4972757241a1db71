"""
feedforward_node: the feedforward of section 4.3, published once as a joint trajectory.

q_target = IK of the target pose (eq. 43) near the first good /joint_states, filtered by
T_forward(z) (eq. 44-45, :class:`.controllers.Feedforward`) from that state's stamp until
settled; then the node leaves the lockstep (it unsubscribes). With ``command_interface``
'position' or 'limited' ``actuators`` the trajectory is that state and the goal only
(:func:`.controllers.makes_own_move`): the joint controller makes the time-optimal move to it
itself (T_forward is the inverse of an ideal computed-torque inner loop, which neither the
arm's drive nor a torque-limited one is).

Subscribes: /joint_states (until it has published). Publishes:
/ibvs/feedforward_trajectory (trajectory_msgs/JointTrajectory, latched), /diagnostics.
Parameters: :class:`.node_params.FeedforwardConfig` (docs/parameters.md). Initial condition
and rejections: docs/nodes.md.
"""

from typing import Any

from ibvs_common import contract
from ibvs_common.conversions import (ignored_joints, InputError, read_joints, read_stamp,
                                     travel_bounds)
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.kit import config, publisher, subscription
from ibvs_common.msg_trajectory import joint_trajectory_bytes
from ibvs_common.node_main import run
from ibvs_common.sim_time import node_time_ns
from ibvs_common.timing import ns_to_seconds
from ibvs_model import ModelError
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from .controllers import Feedforward, makes_own_move
from .node_params import FeedforwardConfig, target_from

#: The node's typed configuration, built by ``ibvs run`` before any node starts.
CONFIG = FeedforwardConfig
PARAMS = CONFIG.params()
RULES = CONFIG.RULES


class FeedforwardNode(Node):
    """IK of the target (eq. 43) filtered by T_forward (eq. 44-45) (module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare and check the parameters, design the filter, create the interfaces."""
        super().__init__('feedforward_node', **kwargs)
        self.config = c = config(self, FeedforwardConfig)
        self.pose = target_from(c.values())
        self.dt_ns = c.timing.step_ns
        self.lead_ns = c.timing.step_lead_ns
        self.ff = Feedforward(self.pose, c.tau_in, ns_to_seconds(self.dt_ns),
                              feedforward_ratio=c.feedforward_ratio,
                              feedforward_method=c.feedforward_method)
        self.t0_ns = None
        self.diagnostics = Diagnostics(self, 'feedforward')
        self.diagnostics.update(started=False)
        self.diagnostics.log_progress(self._progress)
        self._pub = publisher(self, JointTrajectory, contract.FEEDFORWARD_TRAJECTORY,
                              contract.LATCHED)
        self._sub = subscription(self, JointState, contract.JOINT_STATES, self._on_joint_state,
                                 contract.RELIABLE)
        self.get_logger().info(
            f'target {np.round(self.pose[:3, 3], 4).tolist()} m; T_forward '
            f"'{c.feedforward_method}' at {1e9 / self.dt_ns:g} Hz, double pole at "
            f'{c.feedforward_ratio:g} tau_in')

    def _progress(self):
        """Return the progress line: the trajectory published (None before the start)."""
        if self.t0_ns is None:
            return None
        points = self.diagnostics.values['trajectory_points']
        return (f'trajectory of {points} points published at t = {self.t0_ns * 1e-9:.6f} s, '
                f'{points * self.dt_ns * 1e-9:.3f} s long, its last point held after; nothing '
                'more to do')

    def _on_joint_state(self, msg):
        if self.t0_ns is not None:
            return  # a message already queued when the subscription was destroyed
        try:
            t_ns = read_stamp(msg.header.stamp, node_time_ns(self), self.lead_ns)
            q = read_joints(msg, bound=travel_bounds())
        except InputError as exc:
            self.diagnostics.reject(contract.JOINT_STATES, exc.reason, exc.detail)
            return
        self.diagnostics.note_ignored(contract.JOINT_STATES, ignored_joints(msg))
        try:
            q_target = self.ff.start(q)
            # The joint controller plans the move itself (time-optimal, jerk-limited:
            # governor.ReferenceGovernor) toward the last point: the start and the goal
            # are all it needs.
            c = self.config
            positions = (np.array([q, self.ff.goal])
                         if makes_own_move(c.command_interface, c.actuators)
                         else self.ff.trajectory())
        except ModelError as exc:
            self.diagnostics.reject(contract.JOINT_STATES, type(exc).__name__, str(exc))
            return
        if not np.all(np.isfinite(positions)):  # never published: a node's outputs are finite
            self.diagnostics.reject(contract.JOINT_STATES, 'non-finite trajectory',
                                    f'from q = {q.tolist()}')
            return
        self.t0_ns = t_ns
        # as bytes: a message object of T_forward's thousands of points would hold the
        # process for rclpy's conversion (ibvs_common.cdr)
        self._pub.publish(joint_trajectory_bytes(self.t0_ns, self.dt_ns, positions))
        self.destroy_subscription(self._sub)
        dpos, drot = self.ff.pose_error()
        self.get_logger().info(
            f'start at t = {self.t0_ns * 1e-9:.6f} s from q = '
            f'{np.round(np.degrees(q), 3).tolist()} deg; IK branch nearest it: '
            f'{np.round(np.degrees(q_target), 3).tolist()} deg (residual {dpos:.1e} m, '
            f'{drot:.1e} rad); published {len(positions)} points '
            f'({len(positions) * self.dt_ns * 1e-9:.3f} s), the last one held')
        self.diagnostics.update(started=True, start_ns=self.t0_ns, q_target=q_target,
                                ik_residual_m=dpos, ik_residual_rad=drot,
                                trajectory_points=len(positions))


def main(args: list[str] | None = None) -> None:
    """Run the feedforward node (``ros2 run ibvs_control feedforward_node``)."""
    run(FeedforwardNode, args=args, name='feedforward_node')


if __name__ == '__main__':
    main()
