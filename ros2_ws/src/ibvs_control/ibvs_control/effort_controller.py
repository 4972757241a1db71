"""
The effort joint controller: computed torque with the sampled Youla G_c, in lockstep.

On each /joint_states (encoder q, qdot; stamp t_k) it answers with one effort command
stamped t_k on /joint_effort_commands: with q_ref = q_feedforward(t_k) + q_feedback ('limited'
actuators: the feedforward's target + q_feedback, the governor making the move),
v = G_c(q_ref - q) (the sampled eq. 28 at the physics rate) and u = M(q) v + h(q, qdot)
(eq. 23-27; M and h of the nominal robot, :class:`.dynamics.RobotDynamics`), 'ideal' or
'limited' actuators (:class:`.controllers.JointLoop`). Which frame's q_feedback answers
t_k, lost frames (/stereo/frame_lost), buffering and answering in stamp order are
:class:`.feedback_lockstep.FeedbackLockstep` (docs/design.md §4, docs/nodes.md). A command
that would not be finite is not published: the state is rejected ('non-finite command')
and the holding torque h(q, 0) goes out instead. It never holds (its simulator waits for
every command): its status on /ibvs/servo_status is NO_WARNING from the first command on,
or the local minimum the feedback node reports (:mod:`.feedback_relay`), on each change.
"""

from typing import TYPE_CHECKING

from ibvs_common import contract
from ibvs_common.conversions import joint_state
from ibvs_common.kit import publisher, subscription, WaitReporter
from ibvs_common.sim_time import clock_watch, node_time_ns
from ibvs_common.timing import ns_to_seconds
from ibvs_model import IRB4600
import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Header, Int8

from .controllers import JointLoop, makes_own_move, synchronised_move
from .dynamics import RobotDynamics
from .feedback_lockstep import FeedbackLockstep
from .feedback_relay import relay
from .joint_controller_mode import JointControllerMode
from .servo_status import ServoStatus, Verdict

if TYPE_CHECKING:
    from rclpy.node import Node

    from .node_params import JointControllerConfig

#: Most buffered inputs of each kind (lockstep keeps one or two; this bounds a flood).
MAX_BUFFER = 1000


class EffortController(JointControllerMode):
    """Computed torque with the sampled Youla G_c, in lockstep (module docstring)."""

    def __init__(self, node: 'Node', config: 'JointControllerConfig') -> None:
        """Load the dynamics model, open the effort topics (the rates: the node's RULES)."""
        super().__init__(node, config)
        self.frames = (self.camera_ns, self.dt_ns)
        self.latency_ns = config.timing.latency_ns
        self.dynamics = RobotDynamics(IRB4600, with_tool=True)
        limits = np.asarray(config.torque_limits, dtype=float)
        self.torque_limits = np.where(limits > 0.0, limits, self.dynamics.torque_limits)
        self.loop = JointLoop(config.tau_in, ns_to_seconds(self.dt_ns), config.actuators,
                              IRB4600.qd_max, self.torque_limits,
                              speed_margin=config.speed_margin,
                              acceleration_margin=config.acceleration_margin,
                              synchronised=synchronised_move(config.feedforward_method))
        self.own_move = makes_own_move('effort', config.actuators)
        self._lockstep = self._new_lockstep()
        clock_watch(node).on_back(self._clock_back)
        self.frames_lost = 0
        self.saturated_joints = 0
        self.last_answered_ns = None
        self.diagnostics.update(actuators=config.actuators, commands=0,
                                torque_limits=self.torque_limits)
        self._pub = publisher(node, JointState, contract.EFFORT_COMMANDS, contract.RELIABLE)
        self.diagnostics.publishers.command(self._pub.topic_name)  # reported, never held on
        subscription(node, JointState, contract.JOINT_STATES, self._on_joint_state,
                     contract.RELIABLE)
        self.subscribe_inputs()
        subscription(node, Header, contract.FRAME_LOST, self._on_frame_lost, contract.RELIABLE)
        self._pub_status = publisher(node, Int8, contract.SERVO_STATUS, contract.LATCHED)
        self._status = None  # the status published last (None before the first command)
        self._feedback_status = relay(node, self.diagnostics, self._report)
        self.waiting = WaitReporter(node, self._waiting)
        self.diagnostics.log_progress(self._progress_line)
        node.get_logger().info(
            f'{config.actuators} actuators, G_c at {1e9 / self.dt_ns:g} Hz, frames every '
            f'{self.camera_ns} ns, latency {self.latency_ns} ns')

    def close(self) -> None:
        """Release the PyBullet client."""
        self.dynamics.close()

    def _new_lockstep(self):
        """Return the lockstep rule with nothing buffered or answered."""
        # Before the first frame acts, q_feedback = 0; a lost frame holds the last one.
        return FeedbackLockstep(
            self.camera_ns, self.latency_ns, self.dt_ns, max_buffer=MAX_BUFFER,
            initial=np.zeros(6), feedback_name=contract.Q_FEEDBACK,
            lost_name=contract.FRAME_LOST)

    def _clock_back(self, from_ns, to_ns):
        """Answer a restarted simulator's steps from the start (the clock jumped back)."""
        self._lockstep = self._new_lockstep()
        self.last_answered_ns = None

    def now_ns(self) -> int:
        """Return the newest time the node knows: its clock and its last answered stamp."""
        return node_time_ns(self.node, self._lockstep.last_answered_ns)

    def _on_joint_state(self, msg):
        state = self.read_joint_state(msg, velocity=True)
        if state is None:
            return
        t_ns, q, qd = state
        rejection = self._lockstep.offer_state(t_ns, (q, qd))
        if rejection is not None:
            self.diagnostics.reject(contract.JOINT_STATES, *rejection)
            return
        self._drain()

    def trajectory_arrived(self, start_ns):
        """Answer the states that waited for the feedforward."""
        self._drain()

    def take_feedback(self, t_ns, q):
        """Offer the q_feedback to the lockstep; answer what it completes."""
        rejection = self._lockstep.offer_feedback(t_ns, q)
        if rejection is None:
            self._drain()
        return rejection

    def _on_frame_lost(self, msg):
        t_ns = self.read_frame_stamp(contract.FRAME_LOST, msg.stamp)
        if t_ns is None:
            return
        rejection = self._lockstep.offer_lost(t_ns)
        if rejection is not None:
            self.diagnostics.reject(contract.FRAME_LOST, *rejection)
            return
        self.frames_lost += 1
        self.diagnostics.update(frames_lost=self.frames_lost)
        self._drain()

    def _missing(self, t_ns):
        """Return what the answer to ``t_ns`` still waits for (empty when ready)."""
        missing = []
        if self._trajectory is None:
            missing.append(f'the feedforward trajectory on {contract.FEEDFORWARD_TRAJECTORY}')
        return missing + self._lockstep.waiting_for(t_ns)

    def _drain(self):
        """Answer the buffered joint states in order, as far as their inputs are here."""
        while self._trajectory is not None:
            ready = self._lockstep.pop_ready()
            if ready is None:
                return
            t_ns, (q, qd), q_feedback = ready
            # limited actuators: the joint loop's governor makes the move to the target
            q_ff = self.feedforward_target() if self.own_move else self.q_feedforward(t_ns)
            self._answer(t_ns, q, qd, q_ff + q_feedback)

    def _answer(self, t_ns, q, qd, q_ref):
        with self.diagnostics.timing.section('joint_loop'):
            mass = self.dynamics.mass_matrix(q)
            bias = self.dynamics.bias(q, qd)
            torque = self.loop.step(q_ref, q, qd, mass, bias)
        if not np.all(np.isfinite(torque)):
            self.diagnostics.reject(contract.JOINT_STATES, 'non-finite command',
                                    f'{torque.tolist()} at {t_ns} ns: holding torque sent')
            torque = self.dynamics.bias(q, np.zeros(6))
            if not np.all(np.isfinite(torque)):
                return
        self.diagnostics.timing.reached(t_ns)
        self._pub.publish(joint_state(t_ns, effort=torque))
        self.commands += 1
        if self._status is None:
            self._report()
        self.last_answered_ns = t_ns
        self.saturated_joints = int(np.count_nonzero(self.loop.saturated))
        self.waiting.progress()
        self.diagnostics.update(commands=self.commands, last_answered_ns=t_ns,
                                saturated_joints=self.saturated_joints)

    def _report(self):
        """Publish the status on a change, from the first command on (module docstring)."""
        if not self.commands:
            return
        verdict = self._feedback_status.over(Verdict(ServoStatus.NO_WARNING, 'ok'))
        if verdict.status == self._status:
            return
        self._status = verdict.status
        self._pub_status.publish(Int8(data=int(verdict.status)))
        self.diagnostics.update(servo_status=verdict.status.name)

    def _progress_line(self):
        """Return the progress line: commands sent, up to when, and how (None before)."""
        if not self.commands:
            return None
        return (f'{self.commands} effort commands sent (last for t = '
                f'{self.last_answered_ns * 1e-9:.3f} s), {self.config.actuators} actuators, '
                f'{self.saturated_joints} joints at their torque limit, '
                f'{self.frames_lost} frames lost')

    def _waiting(self):
        """Return the wait reporter's line: the oldest unanswered state and its inputs."""
        t_ns = self._lockstep.states.first_ns
        if t_ns is None:
            return None
        return f'waiting to answer /joint_states {t_ns} ns for ' + ', '.join(self._missing(t_ns))
