"""
The lockstep simulator: one physics step per effort command, nobody runs ahead.

After step k's outputs (:meth:`.sim_node.SimNode.publish_step`: /joint_states every step,
and on a camera frame's step the same state on /stereo/joint_states before the frame, as on
the step its q_feedback starts to act) it
waits for /joint_effort_commands stamped t_k; that message, and only that one, applies its
torques for one step and moves to k + 1, inside the subscription callback: nothing spins
or sleeps, so any number of nodes can share one executor. A frame goes out at its own
step (the joint controller applies ``feedback_latency_s``). A command with another stamp
is rejected as stale or early and ignored; one with the right stamp but a wrong length,
unknown joint names, a non-finite value or an effort beyond :data:`EFFORT_BOUND_FACTOR`
times its joint's rated torque is rejected too, and the step happens with the holding
torque (:meth:`.simulator.Simulator.hold_torque`): the arm holds its position.
"""

import time
from typing import TYPE_CHECKING

from ibvs_common import contract
from ibvs_common.conversions import InputError, read_joints, read_stamp, stamp_ns
from ibvs_common.kit import subscription
from ibvs_common.timing import feedback_frame_ns
from ibvs_model.mass_model import joint_efforts
import numpy as np
from sensor_msgs.msg import JointState

if TYPE_CHECKING:
    from rclpy.node import Node

    from .node_params import SimNodeConfig

#: Largest |effort| of a command, in multiples of its joint's rated torque
#: (ibvs_model.mass_model.joint_efforts). Not the rating itself: the paper's ideal actuators
#: command thousands of times it while the feedforward starts (scenario 1: 4.6e7 N m on
#: joint 1, 6e3 times its rating, in the first steps), and the 'limited' actuators clip to it
#: in the controller. Beyond this bound a command is absurd and would only break the physics.
EFFORT_BOUND_FACTOR = 1e6
#: The parameters that only free-running uses: lockstep warns when one is not its default.
FREE_RUNNING_ONLY = ('real_time_factor', 'command_timeout_s', 'drive_bandwidth_hz',
                     'drive_delay_s', 'joint_state_rate_hz', 'joint_state_phase_s',
                     'max_joint_speed_deg_s')


class LockstepSim:
    """
    Steps on each effort command of the current stamp (module docstring).

    ``node``: the :class:`ibvs_sim.sim_node.SimNode` whose simulator, publishers and step
    (:meth:`~ibvs_sim.sim_node.SimNode.advance`) it drives.
    """

    #: Frames go out at their exposure's step: the joint controller applies the latency.
    delivery_delay_ns = 0
    stamp_offset_ns = 0

    def __init__(self, node: 'Node', config: 'SimNodeConfig') -> None:
        """Warn about the free-running parameters set; subscribe to the effort commands."""
        self.node = node
        self.sim = node.sim
        self.diagnostics = node.diagnostics
        for name, value in config.off_default(FREE_RUNNING_ONLY):
            node.get_logger().warn(f"parameter '{name}' = {value!r} is ignored in lockstep "
                                   "(it applies to free-running, command_interface 'position')")
        self.clock_rate_hz = config.clock_rate_hz
        self.frame_joint_subscribers = config.min_frame_joint_state_subscribers
        limit = EFFORT_BOUND_FACTOR * np.asarray(joint_efforts(self.sim.params), dtype=float)
        self._effort_bound = (-limit, limit)
        self.held_steps = 0
        self._frame_step = False
        self._published_at = None
        self._camera_ns = config.timing.camera_period_ns
        self._step_ns = config.timing.step_ns
        self._latency_ns = config.timing.latency_ns
        self.command_sub = subscription(node, JointState, contract.EFFORT_COMMANDS,
                                        self._on_command, contract.RELIABLE)

    def exposes(self, t_ns: int) -> bool:
        """Return whether the camera takes the frame due at ``t_ns``: always."""
        return True

    def action_step(self, t_ns: int) -> bool:
        """
        Return whether a frame's q_feedback starts to act at ``t_ns`` (with latency only).

        The step :func:`ibvs_common.timing.feedback_action_ns` gives: the feedback node
        predicts that frame's features to this step's joint state, so it has it on
        /stereo/joint_states as well (ibvs_control.prediction).
        """
        if self._latency_ns == 0:
            return False
        frame = feedback_frame_ns(t_ns, self._camera_ns, self._latency_ns, self._step_ns)
        return frame is not None and frame != feedback_frame_ns(
            t_ns - self._step_ns, self._camera_ns, self._latency_ns, self._step_ns)

    def publish_joints(self, t_ns: int, joints: JointState, frame_step: bool) -> None:
        """
        Publish /joint_states every step, and /stereo/joint_states on a frame's step.

        And on the step a frame's q_feedback starts to act (:meth:`action_step`).
        """
        self._frame_step = frame_step
        self.node.pub_joints.publish(self.node.with_extra_joints(joints))
        self._published_at = time.perf_counter()
        if frame_step or self.action_step(t_ns):
            self.node.pub_frame_joints.publish(joints)

    def start(self) -> None:
        """Step 0 is out: the commands drive the rest."""

    def stop(self) -> None:
        """Nothing runs on its own."""

    def waiting_line(self) -> str:
        """Return what the next step waits for."""
        return (f'waiting for {contract.EFFORT_COMMANDS} stamped {self.sim.t_ns} ns '
                f'(t = {self.sim.t_ns * 1e-9:.6f} s, step {self.sim.k})')

    def _on_command(self, msg):
        """Apply the effort command stamped t_k: one physics step, then step k + 1."""
        source = contract.EFFORT_COMMANDS
        if not self.node.started:
            self.diagnostics.reject(source, 'before start',
                                    f'stamp {stamp_ns(msg.header.stamp)} ns')
            return
        try:
            stamp = read_stamp(msg.header.stamp)
        except InputError as exc:
            self.diagnostics.reject(source, exc.reason, exc.detail)
            return
        if stamp != self.sim.t_ns:
            reason = 'stale stamp' if stamp < self.sim.t_ns else 'early stamp'
            self.diagnostics.reject(source, reason, f'{stamp} ns, waiting for '
                                    f'{self.sim.t_ns} ns')
            return
        try:
            torque = read_joints(msg, 'effort', bound=self._effort_bound)
        except InputError as exc:
            self.diagnostics.reject(source, exc.reason,
                                    f'{exc.detail}; holding the arm at step {self.sim.k}')
            torque = None
            self.held_steps += 1
        if not self._frame_step:
            # Joint states out, effort command back: the lockstep's round trip, with the
            # controller's own work but without a camera frame to wait for.
            self.diagnostics.timing.add('lockstep_round_trip',
                                        time.perf_counter() - self._published_at)
        with self.diagnostics.timing.section('physics'):
            self.sim.step(torque)
        self.node.waiting.progress()
        self.node.advance()
