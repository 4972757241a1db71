"""
joint_controller_node: the inner joint loop of section 4.1, one effort command a step.

On each /joint_states (encoder q, qdot; stamp t_k) it computes, with q_ref = q_feedforward
(t_k) + q_feedback, v = G_c(q_ref - q) (the sampled eq. 28 at the physics rate) and the
feedback linearisation u = M(q) v + h(q, qdot) (eq. 23-27), M and h of the nominal robot
from PyBullet (:class:`.dynamics.RobotDynamics`), and publishes /joint_effort_commands
(JointState with effort) stamped t_k. Actuators: 'ideal' (the paper) or 'limited' (IRB
4600 speed and torque limits, reference governor and anti-windup:
:class:`.controllers.JointLoop`).

Lockstep (docs/design.md §4). The answer to t_k needs the feedforward trajectory
(/ibvs/feedforward_trajectory, published once at the start: q_feedforward(t_k) is its point
at t_k, its first point before it starts and its last after it ends) and the q_feedback of
frame ibvs_common.contract.feedback_frame_ns(t_k, T_cam, latency, dt) (zero before the first
frame takes effect). A frame the camera lost (/stereo/frame_lost, stamped with the frame's
stamp: ibvs_sim.sim_node) will have no q_feedback: for it the controller holds the
q_feedback of the latest frame before it that was not lost, as a real controller holds its
last output until a new frame comes. A joint state whose inputs have not all arrived is
buffered and answered as soon as they have, in stamp order; nothing is answered early or
twice, so a run is the same however the executor interleaves the callbacks. While it waits
it logs once a second (steady clock) what for. These rules are
:class:`.feedback_lockstep.FeedbackLockstep` (plain Python, tested without rclpy); the node
reads the messages, keeps the feedforward and answers.

Bad input (rejected, logged, counted on /diagnostics, never raised): malformed messages
(wrong length, NaN, missing or unknown joint names: values are mapped by name; a trajectory
not sampled at the physics period or with a non-finite value in any field (its positions are
not bounded by the travel: a feedforward leads the arm and overshoots it); positions beyond
1000 rad or velocities beyond 1e4 rad/s (:mod:`ibvs_common.conversions`:
``POSITION_BOUND_RAD``, ``SPEED_BOUND_RAD_S``), a /joint_states not newer than the last
one, a q_feedback older than what is still needed. Every stamp goes through the one stamp
rule (:func:`ibvs_common.conversions.read_stamp`): malformed, or more than
``stale_timeout_s`` and one input period ahead of the newest time the node knows (its last
answered stamp, or its /clock; 0 before either) is refused and never stored, so that a bad
publisher cannot hold a buffer and leave the good inputs after it unanswered; a q_feedback
or frame_lost must carry a frame's stamp in lockstep
(:func:`ibvs_common.timing.is_frame_stamp`). A new
trajectory replaces the old one. A command that would not be finite is not published: the
state is rejected ('non-finite command') and the holding torque h(q, 0) goes out instead.

Position interface (``command_interface: position``, free-running only: ``lockstep``
false; docs/design.md §4). The arm's own drive closes the joint loop (ros2_control and
ABB's EGM on a real cell, :class:`ibvs_sim.position_servo.PositionServo` in simulation).
Every 1 / ``command_rate_hz`` of the node's clock (sim time with use_sim_time) the node
sends q_ref = q_feedforward(t) + q_feedback, shaped to the arm's speed and acceleration
limits (:class:`.position_interface.PositionShaper`, started from the measured joints), as
std_msgs/Float64MultiArray on /forward_position_controller/commands in the order of the
``joints`` parameter (ros2_controllers' forward_command_controller), or with
``position_command_type: joint_trajectory`` as a trajectory_msgs/JointTrajectory window on
/joint_trajectory_controller/joint_trajectory, as MoveIt Servo sends one (joint_names =
``joints``; header stamp = now, the command's time, not 0; ``trajectory_window_points``
points, point k at time_from_start k command periods: the reference now, then its course
ahead as the shaper will take it toward q_feedforward(t + k T) + the q_feedback held:
:meth:`.position_interface.PositionShaper.preview`). joint_trajectory_controller samples
the window at its own update times and interpolates between points, so that at a rate
other than ``command_rate_hz``, or with a command late, it neither holds a point nor skips
one; each new window replaces the last. Nobody waits: a command uses the newest
q_feedback that has arrived (:class:`.position_interface.FeedbackHold`), and the first
command that uses a frame's q_feedback is reported on /ibvs/frame_latency
(sensor_msgs/TimeReference: header.stamp = the command's time, time_ref = the frame's
stamp). Until the feedforward trajectory and a /joint_states have come nothing is sent
(the drive holds the arm) and the node logs once a second what it waits for.

Stopping safely (position interface; :mod:`.servo_status`). The node watches its inputs:
/joint_states (``joint_state_timeout_s``), the camera (the left camera_info, one per frame,
stamped with its exposure) and the q_feedback (``frame_timeout_s`` each), by their age on
the node's clock, and the feedforward trajectory (once). It commands nothing until each has
come once (status WAITING), and while one is older than its timeout it stops the arm and
holds it: a controlled stop, the reference braked at the acceleration limits to where it
comes to rest (:meth:`.position_interface.PositionShaper.stopping_point`; commanding the
last measured position instead would make a moving arm turn back), and no q_feedback is
used. Fresh input resumes the servoing from where the reference is, without a jump. The
status is one std_msgs/Int8 code on /ibvs/servo_status (latched; on each change and once a
second:
:class:`.servo_status.ServoStatus`, MoveIt Servo's codes and ours: which input is stale),
and /diagnostics says the same in words (WARN while holding). With the effort interface the
controller runs in lockstep: no input can go stale in sim time (the simulator waits).

/ibvs/q_feedback contract: six finite positions, mapped by joint name, each within
:data:`FEEDBACK_BOUND_RAD` (the joint's whole travel: no correction can be larger). Velocity
and effort are not read; they may be empty, but a non-finite value there rejects the
message. A rejected q_feedback is not stored, so a good one with the same stamp still gets in
and the loop goes on as if the bad one had never come.
"""

from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from ibvs_common import contract
from ibvs_common.conversions import (check_finite, ignored_joints, InputError, joint_state,
                                     joint_trajectory, ns_stamp, position_bounds, read_joints,
                                     read_stamp,
                                     read_trajectory, stamp_lead_ns, velocity_bounds)
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.kit import publisher, subscription, WaitReporter
from ibvs_common.node_main import run
from ibvs_common.params import declare, ParameterError
from ibvs_common.shared_params import (ACTUATORS, CAMERA_RATE_HZ, check_camera_rate_param,
                                       check_command_interface, COMMAND_INTERFACE,
                                       COMMAND_RATE_HZ, FEEDBACK_LATENCY_S, JOINTS, LOCKSTEP,
                                       MAX_JOINT_SPEED_DEG_S, PHYSICS_RATE_HZ,
                                       POSITION_COMMAND_TYPE, STALE_TIMEOUT_S, TAU_IN)
from ibvs_common.sim_time import node_time_ns
from ibvs_common.timing import ns_to_seconds, period_ns, seconds_to_ns
from ibvs_model import IRB4600
import numpy as np
from numpy.typing import NDArray
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, JointState, TimeReference
from std_msgs.msg import Float64MultiArray, Header, Int8
from trajectory_msgs.msg import JointTrajectory

from .controllers import JointLoop
from .dynamics import RobotDynamics
from .feedback_lockstep import FeedbackLockstep
from .node_params import (ACCELERATION_MARGIN, FRAME_TIMEOUT_S, JOINT_STATE_TIMEOUT_S,
                          SPEED_MARGIN, TORQUE_LIMITS, TRAJECTORY_WINDOW_POINTS)
from .position_interface import FeedbackHold, joint_permutation, PositionShaper
from .servo_status import InputWatch, ServoStatus

PARAMS = (TAU_IN, PHYSICS_RATE_HZ, CAMERA_RATE_HZ, FEEDBACK_LATENCY_S, ACTUATORS,
          TORQUE_LIMITS, SPEED_MARGIN, ACCELERATION_MARGIN, STALE_TIMEOUT_S,
          COMMAND_INTERFACE, COMMAND_RATE_HZ, POSITION_COMMAND_TYPE, JOINTS, LOCKSTEP,
          JOINT_STATE_TIMEOUT_S, FRAME_TIMEOUT_S, MAX_JOINT_SPEED_DEG_S,
          TRAJECTORY_WINDOW_POINTS)
#: Rules between parameters, run at start and by ``ibvs run`` before any node starts.
RULES = (check_command_interface, check_camera_rate_param)

#: Most buffered inputs of each kind (lockstep keeps one or two; this bounds a flood).
MAX_BUFFER = 1000
#: Largest |q_feedback| per joint (rad) that is taken as meant: the joint's whole travel.
FEEDBACK_BOUND_RAD = np.asarray(IRB4600.q_max) - np.asarray(IRB4600.q_min)


class JointControllerNode(Node):
    """Computed torque with the sampled Youla G_c, in lockstep (module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare and check the parameters, load the dynamics model, create interfaces."""
        super().__init__('joint_controller_node', **kwargs)
        values = declare(self, PARAMS, RULES)
        self.command_interface = values['command_interface']
        self.dynamics = None
        if self.command_interface == 'position':
            self._setup_position(values)
            return
        self.dt_ns = period_ns(values['physics_rate_hz'])
        self.camera_ns = period_ns(values['camera_rate_hz'])
        self.latency_ns = seconds_to_ns(values['feedback_latency_s'])
        self.state_lead_ns = stamp_lead_ns(values['stale_timeout_s'], self.dt_ns)
        self.frame_lead_ns = stamp_lead_ns(values['stale_timeout_s'], self.camera_ns)
        self._frames = (self.camera_ns, self.dt_ns)
        self.dynamics = RobotDynamics(IRB4600, with_tool=True)
        limits = np.asarray(values['torque_limits'], dtype=float)
        self.torque_limits = np.where(limits > 0.0, limits, self.dynamics.torque_limits)
        self.loop = JointLoop(values['tau_in'], ns_to_seconds(self.dt_ns), values['actuators'],
                              IRB4600.qd_max, self.torque_limits,
                              speed_margin=values['speed_margin'],
                              acceleration_margin=values['acceleration_margin'])
        # Before the first frame acts, q_feedback = 0; a lost frame holds the last one.
        self._lockstep = FeedbackLockstep(
            self.camera_ns, self.latency_ns, self.dt_ns, max_buffer=MAX_BUFFER,
            initial=np.zeros(6), feedback_name=contract.Q_FEEDBACK,
            lost_name=contract.FRAME_LOST)
        self._trajectory = None
        self.commands = 0
        self.frames_lost = 0
        self.diagnostics = Diagnostics(self, 'joint controller')
        self.diagnostics.update(actuators=values['actuators'], commands=0,
                                torque_limits=self.torque_limits)
        self._pub = publisher(self, JointState, contract.EFFORT_COMMANDS, contract.RELIABLE)
        subscription(self, JointState, contract.JOINT_STATES, self._on_joint_state,
                     contract.RELIABLE)
        subscription(self, JointTrajectory, contract.FEEDFORWARD_TRAJECTORY, self._on_trajectory,
                     contract.LATCHED)
        subscription(self, JointState, contract.Q_FEEDBACK, self._on_feedback, contract.RELIABLE)
        subscription(self, Header, contract.FRAME_LOST, self._on_frame_lost, contract.RELIABLE)
        self.waiting = WaitReporter(self, self._effort_waiting)
        self.diagnostics.log_progress(self._progress_line)
        self.get_logger().info(
            f"{values['actuators']} actuators, G_c at {1e9 / self.dt_ns:g} Hz, frames every "
            f'{self.camera_ns} ns, latency {self.latency_ns} ns')

    def _setup_position(self, values):
        """Position interface (module docstring): shaper, publishers, command timer."""
        try:
            self._order = joint_permutation(values['joints'], contract.JOINT_NAMES)
        except ValueError as exc:
            raise ParameterError(f"parameter 'joints' = {values['joints']!r} is invalid: "
                                 f'{exc}') from None
        self.joints = list(values['joints'])
        self.dt_ns = period_ns(values['physics_rate_hz'])
        self.command_period_ns = period_ns(values['command_rate_hz'])
        self.camera_ns = period_ns(values['camera_rate_hz'])
        # The one stamp rule (ibvs_common.conversions.read_stamp), as in the effort mode.
        self.state_lead_ns = stamp_lead_ns(values['stale_timeout_s'], self.dt_ns)
        self.frame_lead_ns = stamp_lead_ns(values['stale_timeout_s'], self.camera_ns)
        # No frame grid: a real camera stamps its frames on its own clock, not on the
        # simulator's physics steps (the lockstep's rule, ibvs_common.timing.is_frame_stamp).
        self._frames = None
        self.shaper = PositionShaper(values['command_rate_hz'],
                                     speed_margin=values['speed_margin'],
                                     max_speed=np.radians(values['max_joint_speed_deg_s']))
        self._hold = FeedbackHold(np.zeros(6))
        self.window_points = values['trajectory_window_points']
        self._trajectory = None
        self._measured = None
        frame_timeout_ns = seconds_to_ns(values['frame_timeout_s'])
        self._watch = InputWatch({'joint_states': seconds_to_ns(values['joint_state_timeout_s']),
                                  'camera': frame_timeout_ns, 'feedback': frame_timeout_ns},
                                 required=('feedforward',))
        self._verdict = None
        self._hold_target = None
        self.holds = 0
        self.commands = 0
        self.frames_used = 0
        self.diagnostics = Diagnostics(self, 'joint controller')
        self.diagnostics.update(command_interface='position', commands=0,
                                position_command_type=values['position_command_type'])
        if values['position_command_type'] == 'forward_command':
            self._pub = publisher(self, Float64MultiArray, contract.POSITION_COMMANDS,
                                  contract.RELIABLE)
        else:
            self._pub = publisher(self, JointTrajectory, contract.TRAJECTORY_COMMANDS,
                                  contract.RELIABLE)
        self._pub_latency = publisher(self, TimeReference, contract.FRAME_LATENCY,
                                      contract.RELIABLE)
        self._pub_status = publisher(self, Int8, contract.SERVO_STATUS, contract.LATCHED)
        subscription(self, JointState, contract.JOINT_STATES, self._on_measured, contract.RELIABLE)
        self._camera_topic = subscription(self, CameraInfo, contract.LEFT_INFO, self._on_camera,
                                          contract.CAMERA_INFO).topic_name
        subscription(self, JointTrajectory, contract.FEEDFORWARD_TRAJECTORY, self._on_trajectory,
                     contract.LATCHED)
        subscription(self, JointState, contract.Q_FEEDBACK, self._on_feedback, contract.RELIABLE)
        self.create_timer(ns_to_seconds(self.command_period_ns), self._command)
        self.waiting = WaitReporter(self, self._position_waiting)
        self.get_logger().info(
            f"position references at {values['command_rate_hz']:g} Hz on "
            f'{self._pub.topic_name} ({values["position_command_type"]}), joints '
            f'{self.joints}')

    def destroy_node(self) -> None:
        """Release the PyBullet client with the node."""
        if self.dynamics is not None:
            self.dynamics.close()
        return super().destroy_node()

    # -- position interface ----------------------------------------------------------------
    def _on_measured(self, msg):
        source = contract.JOINT_STATES
        try:
            t_ns = read_stamp(msg.header.stamp, self.now_ns(), self.state_lead_ns)
            q = read_joints(msg, bound=position_bounds())
        except InputError as exc:
            self.diagnostics.reject(source, exc.reason, exc.detail)
            return
        self.diagnostics.note_ignored(source, ignored_joints(msg))
        if self._measured is not None and t_ns <= self._measured[0]:
            self.diagnostics.reject(source, 'out of order',
                                    f'{t_ns} ns, not newer than {self._measured[0]} ns')
            return
        self._measured = (t_ns, q)
        self._watch.heard('joint_states', t_ns)

    def _on_camera(self, msg):
        """Note a camera frame (its camera_info, stamped with the exposure): its age only."""
        try:
            t_ns = read_stamp(msg.header.stamp, self.now_ns(), self.frame_lead_ns)
        except InputError as exc:
            self.diagnostics.reject(self._camera_topic, exc.reason, exc.detail)
            return
        self._watch.heard('camera', t_ns)

    def _report(self, now_ns, verdict=None):
        """Publish the status on a change (and with ``verdict`` None, once a second)."""
        if verdict is None:
            verdict = self._verdict
        elif self._verdict is not None and verdict.status == self._verdict.status:
            self._verdict = verdict  # the same status; its words (an age) may move on
            return
        else:
            previous, self._verdict = self._verdict, verdict
            if verdict.holding:
                self.holds += 1
                self.get_logger().warn(f'{verdict.status.name}: {verdict.detail}')
            elif previous is not None and previous.holding:
                self.get_logger().info(f'fresh input at {now_ns * 1e-9:.3f} s: servoing '
                                       'resumes')
            level = (DiagnosticStatus.WARN if verdict.holding else DiagnosticStatus.OK)
            self.diagnostics.set_level(level, verdict.detail)
            self.diagnostics.update(servo_status=verdict.status.name, holds=self.holds)
        if verdict is not None:
            self._pub_status.publish(Int8(data=int(verdict.status)))

    def _position_missing(self):
        """Return what the first position command still waits for (empty when ready)."""
        inputs = {'feedforward': f'the feedforward trajectory on '
                                 f'{contract.FEEDFORWARD_TRAJECTORY}',
                  'joint_states': f'a {contract.JOINT_STATES} (the shaper starts from it)',
                  'camera': f'a camera frame ({self._camera_topic})',
                  'feedback': f'a {contract.Q_FEEDBACK}'}
        return [inputs[name] for name in self._watch.missing()]

    def _command(self):
        """Send one position reference (module docstring, position interface)."""
        now_ns = self.get_clock().now().nanoseconds
        verdict = self._watch.verdict(now_ns)
        self._report(now_ns, verdict)
        if verdict.status == ServoStatus.WAITING:
            return
        if not self.shaper.started:
            self.shaper.start(self._measured[1])
            self._last_command_ns = now_ns - self.command_period_ns
        if verdict.holding:
            if self._hold_target is None:  # a controlled stop
                self._hold_target = self.shaper.stopping_point()
            target, first_frame_ns, q_feedback = self._hold_target, None, None
        else:
            self._hold_target = None
            q_feedback, first_frame_ns = self._hold.use()
            target = self.q_feedforward(now_ns) + q_feedback
        q_command = self.shaper.step(target, ns_to_seconds(now_ns - self._last_command_ns))
        self._last_command_ns = now_ns
        if self._pub.msg_type is Float64MultiArray:
            self._pub.publish(Float64MultiArray(data=[float(v) for v in q_command[self._order]]))
        else:  # the window: now and its course ahead (module docstring)
            ahead = np.arange(1, self.window_points) * self.command_period_ns
            targets = (np.tile(target, (len(ahead), 1)) if q_feedback is None
                       else [self.q_feedforward(now_ns + t) + q_feedback for t in ahead])
            window = np.vstack([q_command, self.shaper.preview(targets)])
            self._pub.publish(joint_trajectory(now_ns, self.command_period_ns,
                                               window[:, self._order], self.joints))
        if first_frame_ns is not None:
            self._pub_latency.publish(TimeReference(
                header=Header(stamp=ns_stamp(now_ns)), time_ref=ns_stamp(first_frame_ns),
                source=contract.Q_FEEDBACK))
            self.frames_used += 1
        self.commands += 1
        self.waiting.progress()
        self.diagnostics.update(commands=self.commands, frames_used=self.frames_used,
                                last_command_ns=now_ns)

    # -- inputs ----------------------------------------------------------------------------
    def now_ns(self) -> int:
        """Return the newest time the node knows: its clock and its last answered stamp."""
        if self.command_interface == 'position':
            return node_time_ns(self, self._measured[0] if self._measured else None)
        return node_time_ns(self, self._lockstep.last_answered_ns)

    def _on_joint_state(self, msg):
        source = contract.JOINT_STATES
        try:
            t_ns = read_stamp(msg.header.stamp, self.now_ns(), self.state_lead_ns)
            q = read_joints(msg, bound=position_bounds())
            qd = read_joints(msg, 'velocity', bound=velocity_bounds())
        except InputError as exc:
            self.diagnostics.reject(source, exc.reason, exc.detail)
            return
        self.diagnostics.note_ignored(source, ignored_joints(msg))
        rejection = self._lockstep.offer_state(t_ns, (q, qd))
        if rejection is not None:
            self.diagnostics.reject(source, *rejection)
            return
        self._drain()

    def _on_trajectory(self, msg):
        try:
            read_stamp(msg.header.stamp, self.now_ns(), self.state_lead_ns)
            trajectory = read_trajectory(msg, self.dt_ns)
        except InputError as exc:
            self.diagnostics.reject(contract.FEEDFORWARD_TRAJECTORY, exc.reason, exc.detail)
            return
        self._trajectory = trajectory
        start_ns, positions = trajectory
        if self.command_interface == 'position':
            self._watch.heard('feedforward', start_ns)
        self.diagnostics.update(feedforward_start_ns=start_ns,
                                feedforward_points=len(positions))
        if self.command_interface == 'effort':
            self._drain()

    def _on_feedback(self, msg):
        source = contract.Q_FEEDBACK
        try:
            t_ns = read_stamp(msg.header.stamp, self.now_ns(), self.frame_lead_ns,
                              self._frames)
            q = read_joints(msg)
            check_finite(msg, ('velocity', 'effort'))
        except InputError as exc:
            self.diagnostics.reject(source, exc.reason, exc.detail)
            return
        if np.any(np.abs(q) > FEEDBACK_BOUND_RAD):
            self.diagnostics.reject(source, 'out of range',
                                    f'{q.tolist()} rad: a joint beyond its whole travel')
            return
        if self.command_interface == 'position':
            rejection = self._hold.offer(t_ns, q)
            if rejection is not None:
                self.diagnostics.reject(source, *rejection)
            else:
                self._watch.heard('feedback', t_ns)
            return
        rejection = self._lockstep.offer_feedback(t_ns, q)
        if rejection is not None:
            self.diagnostics.reject(source, *rejection)
            return
        self._drain()

    def _on_frame_lost(self, msg):
        source = contract.FRAME_LOST
        try:
            t_ns = read_stamp(msg.stamp, self.now_ns(), self.frame_lead_ns, self._frames)
        except InputError as exc:
            self.diagnostics.reject(source, exc.reason, exc.detail)
            return
        rejection = self._lockstep.offer_lost(t_ns)
        if rejection is not None:
            self.diagnostics.reject(source, *rejection)
            return
        self.frames_lost += 1
        self.diagnostics.update(frames_lost=self.frames_lost)
        self._drain()

    def q_feedforward(self, t_ns: int) -> NDArray[np.float64]:
        """Return the feedforward at ``t_ns``: the trajectory's point, held past its ends."""
        start_ns, positions = self._trajectory
        k = (t_ns - start_ns) // self.dt_ns
        return positions[min(max(k, 0), len(positions) - 1)]

    # -- lockstep ---------------------------------------------------------------------------
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
            self._answer(t_ns, q, qd, self.q_feedforward(t_ns) + q_feedback)

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
        self.waiting.progress()
        self.diagnostics.update(commands=self.commands, last_answered_ns=t_ns,
                                saturated_joints=int(np.count_nonzero(self.loop.saturated)))

    def _progress_line(self):
        """Return the progress line: commands sent, up to when, and how (None before)."""
        values = self.diagnostics.values
        if not self.commands:
            return None
        if self.command_interface == 'position':
            return (f'{self.commands} position references sent (last at '
                    f"{values['last_command_ns'] * 1e-9:.3f} s), {self.frames_used} frames "
                    'of q_feedback used')
        return (f'{self.commands} effort commands sent (last for t = '
                f"{values['last_answered_ns'] * 1e-9:.3f} s), {values['actuators']} "
                f"actuators, {values['saturated_joints']} joints at their torque limit, "
                f'{self.frames_lost} frames lost')

    def _position_waiting(self):
        """Report the servo status; return the wait reporter's line (position interface)."""
        missing = self._position_missing()
        self._report(self.get_clock().now().nanoseconds)
        return 'waiting to send position references for ' + ', '.join(missing) \
            if missing else None

    def _effort_waiting(self):
        """Return the wait reporter's line (effort interface): the oldest unanswered state."""
        t_ns = self._lockstep.states.first_ns
        if t_ns is None:
            return None
        return f'waiting to answer /joint_states {t_ns} ns for ' + ', '.join(self._missing(t_ns))


def main(args: list[str] | None = None) -> None:
    """Run the joint controller node (``ros2 run ibvs_control joint_controller_node``)."""
    run(JointControllerNode, args=args, name='joint_controller_node')


if __name__ == '__main__':
    main()
