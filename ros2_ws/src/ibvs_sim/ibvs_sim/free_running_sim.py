"""
The free-running simulator: a position-controlled arm on a real cell's timing.

After step 0 a steady-clock timer advances the physics at ``real_time_factor`` (never
skipping sim time; the factor held is reported); /joint_states go out on
joint_state_broadcaster's cycle (``joint_state_rate_hz``, ``joint_state_phase_s``), each
frame ``feedback_latency_s`` after its exposure, none within ``camera_outage_s``. The drive
model (:class:`.position_servo.PositionServo`) follows the references of
/forward_position_controller/commands (positions only: no speed reference) or
/joint_trajectory_controller/joint_trajectory (:class:`.position_servo.TrajectoryFollower`:
positions and the points' velocities, EGM's speed reference) and holds the arm when they go stale
(``command_timeout_s``); a command ros2_controllers would refuse, or out of a joint's
range, is rejected and counted. In full: docs/nodes.md.
"""

import time
from typing import TYPE_CHECKING

from diagnostic_msgs.msg import DiagnosticStatus
from ibvs_common import contract
from ibvs_common.conversions import duration_ns, InputError, read_command_trajectory, stamp_ns
from ibvs_common.kit import subscription
from ibvs_common.msg_trajectory import command_velocities
from ibvs_common.params import ParameterError
from ibvs_common.shared_params import joint_permutation
from ibvs_common.timing import period_ns, seconds_to_ns
from ibvs_model import IRB4600
from ibvs_model.drive import SPEED_LIMITS
import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from .position_servo import PositionServo, TrajectoryFollower

if TYPE_CHECKING:
    from rclpy.node import Node

    from .node_params import SimNodeConfig

#: The longest the stepping timer waits (wall s), and the most physics steps one of its
#: calls takes before it lets the executor run other callbacks.
FREE_RUN_TICK_S = 0.005
MAX_STEPS_PER_TICK = 20
#: The wall-clock window over which the real-time factor held is measured, and the share
#: of the set factor below which the node reports that it falls behind.
RTF_WINDOW_S = 2.0
RTF_TOLERANCE = 0.9
#: The wall-clock window of the factor held while servoing (from the first position
#: reference): its minimum over these windows and its mean over all of them.
SERVO_RTF_WINDOW_S = 1.0


class FreeRunningSim:
    """
    Steps on a steady-clock timer; a position drive follows the references (module doc).

    ``node``: the :class:`ibvs_sim.sim_node.SimNode` whose simulator, publishers and step
    (:meth:`~ibvs_sim.sim_node.SimNode.advance`) it drives.
    """

    #: No effort command is ever refused here: the drive has no torque input.
    held_steps = 0

    def __init__(self, node: 'Node', config: 'SimNodeConfig') -> None:
        """Build the drive and the command subscription (ParameterError naming a bad one)."""
        self.node = node
        self.sim = sim = node.sim
        self.diagnostics = node.diagnostics
        if config.min_frame_joint_state_subscribers > 0:
            node.get_logger().warn(
                "parameter 'min_frame_joint_state_subscribers' = "
                f'{config.min_frame_joint_state_subscribers} is ignored free-running: no '
                f'{contract.FRAME_JOINT_STATES} (a real cell has none)')
        self.frame_joint_subscribers = 0
        # A sim-time timer fires only when /clock moves: the command timer needs it.
        self.clock_rate_hz = max(config.clock_rate_hz, config.interface.command_rate_hz)
        self.delivery_delay_ns = config.timing.latency_ns
        self.stamp_offset_ns = seconds_to_ns(config.image_stamp_offset_s)
        self._joint_state_period_ns = period_ns(config.joint_state_rate_hz)
        self._next_joint_state_ns = seconds_to_ns(config.joint_state_phase_s)
        start_s, span_s = config.camera_outage_s
        self._outage = (seconds_to_ns(start_s), seconds_to_ns(start_s + span_s)) \
            if span_s > 0.0 else None
        self._joints = list(config.interface.joints)  # each joint once: SimNodeConfig checked it
        # Command value i is joint self._joints[i]; _to_contract reorders to joint_1..6.
        self._to_contract = joint_permutation(contract.JOINT_NAMES, self._joints)
        try:
            # EGM's speed setting (the RAPID's \MaxSpeedDeviation) caps the drive as the
            # joint controller's shaper is capped: max_joint_speed_deg_s, both.
            self.servo = PositionServo(
                sim.dt_ns * 1e-9, sim.q_start, bandwidth_hz=config.drive_bandwidth_hz,
                delay_s=config.drive_delay_s,
                speed_limits=np.minimum(SPEED_LIMITS, np.radians(config.max_joint_speed_deg_s)))
        except ValueError as exc:
            raise ParameterError(f"parameter 'drive_bandwidth_hz' = "
                                 f'{config.drive_bandwidth_hz!r} is invalid: {exc}') from None
        self._command_timeout_ns = seconds_to_ns(config.command_timeout_s)
        self._rtf = config.real_time_factor
        self._command_ns = None
        self._stale = False
        self._servo_start = self._servo_window = self._servo_min = None
        self._servo_windows = 0
        self.commands = 0
        # joint_trajectory: the trajectory controller, updated at command_rate_hz (abb_ros2's
        # controller manager: 250 Hz), samples each trajectory window for the drive.
        self._follower = None
        if config.interface.position_command_type == 'joint_trajectory':
            self._follower = TrajectoryFollower(config.interface.command_rate_hz)
            self.command_sub = subscription(node, JointTrajectory, contract.TRAJECTORY_COMMANDS,
                                            self._on_trajectory_command, contract.RELIABLE)
        else:
            self.command_sub = subscription(node, Float64MultiArray, contract.POSITION_COMMANDS,
                                            self._on_position_command, contract.RELIABLE)
        self.diagnostics.update(command='none yet', commands=0, real_time_factor=self._rtf)
        self._run_timer = None

    def exposes(self, t_ns: int) -> bool:
        """
        Return whether the camera takes the frame due at ``t_ns``.

        Not in an outage, and not before its stamp can be (a negative image_stamp_offset_s
        would stamp the first frames before time 0: the camera starts with the first it can
        stamp).
        """
        if t_ns + self.stamp_offset_ns < 0:
            return False
        return self._outage is None or not self._outage[0] <= t_ns < self._outage[1]

    def publish_joints(self, t_ns: int, joints: JointState, frame_step: bool) -> None:
        """Publish /joint_states on joint_state_broadcaster's cycle, from its own phase."""
        if t_ns >= self._next_joint_state_ns:
            self.node.pub_joints.publish(self.node.with_extra_joints(joints))
            self._next_joint_state_ns += self._joint_state_period_ns * (
                (t_ns - self._next_joint_state_ns) // self._joint_state_period_ns + 1)

    def start(self) -> None:
        """Step 0 is out: start the stepping timer."""
        outage = '' if self._outage is None else (
            f', camera out over [{self._outage[0]}, {self._outage[1]}) ns')
        self.node.get_logger().info(
            f'free-running at real_time_factor {self._rtf:g}, /clock every '
            f'{self.node.clock_period_ns} ns, commands stale after '
            f'{self._command_timeout_ns} ns, /joint_states every '
            f'{self._joint_state_period_ns} ns from {self._next_joint_state_ns} ns, frames '
            f'delivered {self.delivery_delay_ns} ns after exposure and stamped '
            f'{self.stamp_offset_ns} ns after it{outage}')
        self._anchor = (time.monotonic(), self.sim.t_ns)
        self._window = (time.monotonic(), self.sim.t_ns)
        self._run_timer = self.node.create_timer(
            min(FREE_RUN_TICK_S, self.sim.dt_ns * 1e-9 / self._rtf), self._run,
            clock=self.node.steady)

    def stop(self) -> None:
        """Stop the stepping timer."""
        if self._run_timer is not None:
            self._run_timer.cancel()

    def waiting_line(self) -> str | None:
        """Return what the arm waits for: its first position reference (None after)."""
        if self._command_ns is not None:
            return None
        return (f'no position reference yet on {self.command_sub.topic_name}: holding the arm '
                f'at its start (t = {self.sim.t_ns * 1e-9:.3f} s)')

    def _run(self):
        """Advance the physics to where real_time_factor puts sim time now (module docs)."""
        wall0, sim0 = self._anchor
        now = time.monotonic()
        due_ns = sim0 + int((now - wall0) * self._rtf * 1e9)
        steps = 0
        while self.sim.t_ns + self.sim.dt_ns <= due_ns and steps < MAX_STEPS_PER_TICK:
            self._free_step()
            steps += 1
            if self.node.finished:
                return
        if self.sim.t_ns + self.sim.dt_ns <= due_ns and \
                due_ns - self.sim.t_ns > 10 * MAX_STEPS_PER_TICK * self.sim.dt_ns:
            # Behind by more than ten ticks' worth: go on from here at the set pace rather
            # than rush (sim time is never skipped, only the lost wall time is not made up).
            self._anchor = (now, self.sim.t_ns)
        if self._servo_window is not None and now - self._servo_window[0] >= SERVO_RTF_WINDOW_S:
            self._close_servo_window(now)
        start, sim_start = self._window
        if now - start >= RTF_WINDOW_S:
            held = (self.sim.t_ns - sim_start) * 1e-9 / (now - start)
            self._window = (now, self.sim.t_ns)
            self.diagnostics.update(real_time_factor_held=held)
            if held < RTF_TOLERANCE * self._rtf:
                message = (f'falling behind: real_time_factor {held:.3f} held over the last '
                           f'{now - start:.1f} s of wall time, {self._rtf:g} set')
                self.node.get_logger().warn(message)
                self.diagnostics.set_level(DiagnosticStatus.WARN, message)
            elif not self._stale:
                self.diagnostics.set_level(DiagnosticStatus.OK, 'ok')

    def _close_servo_window(self, now):
        """End a 1 s wall window of the servoing: its factor, the minimum and the mean."""
        wall0, sim0 = self._servo_window
        held = (self.sim.t_ns - sim0) * 1e-9 / (now - wall0)
        self._servo_window = (now, self.sim.t_ns)
        self._servo_min = held if self._servo_min is None else min(self._servo_min, held)
        wall_start, sim_start = self._servo_start
        self.diagnostics.update(
            real_time_factor_servo_min_1s=self._servo_min,
            real_time_factor_servo_mean=(self.sim.t_ns - sim_start) * 1e-9 / (now - wall_start),
            servo_windows=self._servo_windows + 1)
        self._servo_windows += 1

    def _free_step(self):
        """One physics step of the position drive, then the next step's outputs."""
        sim = self.sim
        if self._command_ns is not None and not self._stale and \
                sim.t_ns - self._command_ns > self._command_timeout_ns:
            self._stale = True
            self.servo.hold()
            message = (f'command stale: no position reference for '
                       f'{(sim.t_ns - self._command_ns) * 1e-9:.3f} s of sim time (command_'
                       f'timeout_s {self._command_timeout_ns * 1e-9:g}): holding the arm')
            self.node.get_logger().warn(message)
            self.diagnostics.set_level(DiagnosticStatus.WARN, message)
            self.diagnostics.update(command='stale')
        if self._follower is not None and not self._stale and self._follower.due(sim.t_ns):
            written = self._follower.update(sim.t_ns, self.servo.q - sim.d_q)
            if written is not None:  # position and velocity: EGM's speed reference
                self.servo.command(written[0] + sim.d_q, written[1])
        with self.diagnostics.timing.section('physics'):
            q, qd = self.servo.step()
            sim.move_to(q, qd)
        self.node.advance()

    def _beyond_range(self, q_encoder):
        """Return, per row of encoder angles, whether a true angle (+ d_q) leaves its range."""
        q_true = np.atleast_2d(q_encoder) + self.sim.d_q
        return np.any((q_true < np.asarray(IRB4600.q_min))
                      | (q_true > np.asarray(IRB4600.q_max)), axis=1)

    def _take_reference(self, q_encoder, source, trajectory=None):
        """
        Take a reference in encoder angles (contract order): range check, then the drive.

        ``trajectory`` (stamp ns, times ns, positions, velocities or None): a
        joint_trajectory command whose points were range-checked already, for the
        trajectory controller (:class:`.position_servo.TrajectoryFollower`).
        """
        if trajectory is None and self._beyond_range(q_encoder)[0]:
            self.diagnostics.reject(source, 'out of range', f'{q_encoder.tolist()} rad: '
                                    'beyond a joint range')
            return
        if trajectory is None:
            self.servo.command(q_encoder + self.sim.d_q)
        else:
            self._follower.receive(*trajectory)
        if self._command_ns is None:  # the servoing starts: its factor held from here
            self._servo_start = self._servo_window = (time.monotonic(), self.sim.t_ns)
        self._command_ns = self.sim.t_ns
        self.commands += 1
        if self._stale:
            self._stale = False
            self.node.get_logger().info('position references again: tracking')
            self.diagnostics.set_level(DiagnosticStatus.OK, 'ok')
        self.diagnostics.update(command='tracking', commands=self.commands)

    def _on_position_command(self, msg):
        """Take a forward_command_controller command: values in the order of ``joints``."""
        source = self.command_sub.topic_name
        values = np.asarray(msg.data, dtype=float)
        if values.shape != (6,):
            self.diagnostics.reject(source, 'wrong length',
                                    f'{values.size} values, expected 6 ({self._joints})')
            return
        if not np.all(np.isfinite(values)):
            self.diagnostics.reject(source, 'not finite', f'{values.tolist()}')
            return
        self._take_reference(values[self._to_contract], source)

    def _on_trajectory_command(self, msg):
        """
        Take a joint_trajectory_controller command: the last point, mapped by name.

        Refused as joint_trajectory_controller refuses it
        (:func:`ibvs_common.conversions.read_command_trajectory`, which cites its source),
        and for a point anywhere outside a joint's range.
        """
        source = self.command_sub.topic_name
        try:
            positions = read_command_trajectory(msg, self.sim.t_ns, self._command_timeout_ns)
        except InputError as exc:
            self.diagnostics.reject(source, exc.reason, exc.detail)
            return
        outside = np.flatnonzero(self._beyond_range(positions))
        if outside.size:
            self.diagnostics.reject(source, 'out of range',
                                    f'point {int(outside[0])}: '
                                    f'{positions[outside[0]].tolist()} rad: beyond a joint '
                                    'range')
            return
        self._take_reference(positions[-1], source, trajectory=(
            stamp_ns(msg.header.stamp), [duration_ns(p.time_from_start) for p in msg.points],
            positions, command_velocities(msg)))
