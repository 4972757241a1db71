"""
feedforward_node: the feedforward of section 4.3, one /ibvs/q_feedforward per /joint_states.

q_target = IK of the target pose (eq. 43), on the branch nearest the encoder joints of the
first /joint_states; q_feedforward = T_forward(z) q_target (eq. 44-45, at the physics
rate). Initial condition: the filter starts at rest at those joints q(0), and the target
enters right after t = 0 (:class:`ibvs_control.controllers.Feedforward`), so
q_feedforward(0) = q(0): the arm is asked to stay where it is at t = 0 and to move from
the next step on.

Stamps: every /joint_states stamped t_k is answered by one /ibvs/q_feedforward stamped
t_k (the lockstep rule, DESIGN section 4). The filter advances by the number of physics
steps between stamps (t - t_0) / dt, so a missed message does not shift later outputs.
A /joint_states that is malformed, or not newer than the last one, is rejected (counted on
/diagnostics) and not answered.
"""

from ibvs_common import contract
from ibvs_common.conversions import InputError, joint_state, read_joints, stamp_ns
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.node_main import run
from ibvs_common.params import declare
from ibvs_common.shared_params import (OMEGA_N, PHYSICS_RATE_HZ, TARGET_POSITION,
                                       TARGET_ROTATION, TAU_IN)
from ibvs_common.timing import period_ns
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import JointState

from .controllers import Feedforward
from .node_params import check_gains, FEEDFORWARD_METHOD, target_from

PARAMS = (TAU_IN, OMEGA_N, PHYSICS_RATE_HZ, TARGET_POSITION, TARGET_ROTATION,
          FEEDFORWARD_METHOD)

#: Most physics steps the filter is advanced for one message (a jump in sim time beyond
#: this restarts it at rest on the target: its transient is long over).
MAX_CATCH_UP_STEPS = 100_000


class FeedforwardNode(Node):
    """IK of the target (eq. 43) filtered by T_forward (eq. 44-45) (module docstring)."""

    def __init__(self, **kwargs):
        """Declare and check the parameters, design the filter, create the interfaces."""
        super().__init__('feedforward_node', **kwargs)
        values = declare(self, PARAMS)
        check_gains(values)
        self.pose = target_from(values)
        self.dt_ns = period_ns(values['physics_rate_hz'])
        self.ff = Feedforward(self.pose, values['tau_in'], self.dt_ns * 1e-9,
                              method=values['feedforward_method'])
        self.t0_ns = None
        self.last_ns = None
        self.samples = 0
        self.diagnostics = Diagnostics(self, 'feedforward')
        self.diagnostics.update(started=False, samples=0)
        self._pub = self.create_publisher(JointState, contract.Q_FEEDFORWARD, contract.RELIABLE)
        self._sub = self.create_subscription(JointState, contract.JOINT_STATES,
                                             self._on_joint_state, contract.RELIABLE)
        self.get_logger().info(
            f'target {np.round(self.pose[:3, 3], 4).tolist()} m; T_forward '
            f"'{values['feedforward_method']}' at {1e9 / self.dt_ns:g} Hz")

    def _on_joint_state(self, msg):
        source = contract.JOINT_STATES
        t_ns = stamp_ns(msg.header.stamp)
        try:
            q = read_joints(msg)
        except InputError as exc:
            self.diagnostics.reject(source, exc.reason, exc.detail)
            return
        if self.last_ns is not None and t_ns <= self.last_ns:
            self.diagnostics.reject(source, 'stale stamp',
                                    f'{t_ns} ns, last answered {self.last_ns} ns')
            return
        if self.t0_ns is None:
            self._start(t_ns, q)
            q_ff = self.ff.step()
        else:
            k = round((t_ns - self.t0_ns) / self.dt_ns)
            steps = k + 1 - self.ff.filter.steps
            if steps > MAX_CATCH_UP_STEPS:
                self.ff.filter.reset(rest_input=self.ff.q_target)
                self.ff.filter.steps = k
                steps = 1
            for _ in range(max(steps, 1)):
                q_ff = self.ff.step()
        self.last_ns = t_ns
        self.samples += 1
        self._pub.publish(joint_state(t_ns, position=q_ff))
        self.diagnostics.update(samples=self.samples)

    def _start(self, t_ns, q):
        self.t0_ns = t_ns
        q_target = self.ff.start(q)
        dpos, drot = self.ff.pose_error()
        self.get_logger().info(
            f'start at t = {t_ns * 1e-9:.6f} s from q = {np.round(np.degrees(q), 3).tolist()} '
            f'deg; IK branch nearest it: {np.round(np.degrees(q_target), 3).tolist()} deg '
            f'(residual {dpos:.1e} m, {drot:.1e} rad)')
        self.diagnostics.update(started=True, start_ns=t_ns, q_target=q_target,
                                ik_residual_m=dpos, ik_residual_rad=drot)


def main(args=None):
    """Run the feedforward node (``ros2 run ibvs_control feedforward_node``)."""
    run(FeedforwardNode, args=args, name='feedforward_node')


if __name__ == '__main__':
    main()
