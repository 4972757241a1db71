"""
The position joint controller: joint references for the arm's own drive, free-running.

Every 1 / ``command_rate_hz`` of the node's clock it sends the reference of the
time-optimal, jerk-limited move toward the feedforward's target plus q_feedback (the newest:
:class:`.position_interface.FeedbackHold`), re-planned from its own last state within the
arm's limits (:class:`.position_interface.PositionShaper`, Ruckig), on
/forward_position_controller/commands or as a JointTrajectory window on
/joint_trajectory_controller/joint_trajectory (``position_command_type``), or in a dry run
(``dry_run``) on /ibvs/dry_run/commands or /ibvs/dry_run/joint_trajectory instead, the arm's
command topic never opened; the first command that uses a frame's q_feedback goes on
/ibvs/frame_latency. The move starts once the feedforward and a joint state are there: the
camera's first frame and its q_feedback must follow within ``frame_timeout_s``. A stale
input, a clock that jumped back, a sim time that stopped or a second publisher on
/joint_states, the q_feedback, the feedforward or its own command topic stops and holds
the arm (:mod:`.servo_status`, on /ibvs/servo_status, which also relays
the feedback node's local minimum: :mod:`.feedback_relay`). In full:
docs/nodes.md.
"""

from typing import TYPE_CHECKING

from diagnostic_msgs.msg import DiagnosticStatus
from ibvs_common import contract
from ibvs_common.conversions import check_camera_info, InputError, joint_trajectory, ns_stamp
from ibvs_common.kit import publisher, subscription, WaitReporter
from ibvs_common.shared_params import joint_order
from ibvs_common.sim_time import clock_watch, node_time_ns, read_clock_ns
from ibvs_common.timing import ns_to_seconds, period_ns, seconds_to_ns
import numpy as np
from rclpy.clock import Clock, ClockType
from sensor_msgs.msg import CameraInfo, JointState, TimeReference
from std_msgs.msg import Float64MultiArray, Header, Int8
from trajectory_msgs.msg import JointTrajectory

from .feedback_relay import relay
from .joint_controller_mode import JointControllerMode
from .position_interface import FeedbackHold, shaper_for
from .servo_status import clock_stopped, InputWatch, second_publisher, ServoStatus

if TYPE_CHECKING:
    from rclpy.node import Node

    from .node_params import JointControllerConfig

#: The parameters only the effort interface uses: a warning names those set off default.
EFFORT_ONLY = ('actuators', 'torque_limits', 'acceleration_margin')
#: Wall seconds between two looks at whether sim time stopped (free-running only: the
#: lockstep's effort interface waits for its simulator and never looks).
CLOCK_CHECK_S = 0.25
#: The inputs the first command does not wait for: the move starts on the feedforward and
#: the joint states, and the first camera frame and q_feedback must come within
#: ``frame_timeout_s`` of that start (:class:`.servo_status.InputWatch`).
AFTER_START = ('camera', 'feedback')
#: What each input the first command waits for is, in the wait reporter's words.
INPUTS = {'feedforward': f'the feedforward trajectory on {contract.FEEDFORWARD_TRAJECTORY}',
          'joint_states': f'a {contract.JOINT_STATES} (the shaper starts from it)'}


class ForwardCommand:
    """
    ros2_controllers' forward_command_controller: the reference alone, a Float64MultiArray.

    On /forward_position_controller/commands, the values in the controller's joint order
    (``joints``). ``send`` takes what :meth:`PositionController._command` computed.
    """

    #: The command topic, and a dry run's (``dry_run``: never the arm's).
    TOPICS = (contract.POSITION_COMMANDS, contract.DRY_RUN_COMMANDS)

    def __init__(self, node: 'Node', ctrl: 'PositionController') -> None:
        """Open the command topic (a dry run's own topic in a dry run)."""
        self._ctrl = ctrl
        self.pub = publisher(node, Float64MultiArray, self.TOPICS[ctrl.config.dry_run],
                             contract.RELIABLE)

    def send(self, now_ns, q_command, target, q_feedback):
        """Publish ``q_command`` (contract order) in the controller's order."""
        self.pub.publish(Float64MultiArray(data=[float(v) for v in
                                                 q_command[self._ctrl.order]]))


class TrajectoryWindow:
    """
    ros2_controllers' joint_trajectory_controller: a window of the course ahead.

    On /joint_trajectory_controller/joint_trajectory: now (``q_command``) and
    ``trajectory_window_points`` - 1 points one command period apart along the shaper's
    current plan, each with its velocity and acceleration (joint_trajectory_controller sends
    a point's velocity to the hardware: EGM gets its speed reference), in the controller's
    joint order.
    """

    #: The command topic, and a dry run's (``dry_run``: never the arm's).
    TOPICS = (contract.TRAJECTORY_COMMANDS, contract.DRY_RUN_TRAJECTORY)

    def __init__(self, node: 'Node', ctrl: 'PositionController') -> None:
        """Open the command topic (a dry run's own topic in a dry run)."""
        self._ctrl = ctrl
        self._ahead = ctrl.config.trajectory_window_points - 1
        self.pub = publisher(node, JointTrajectory, self.TOPICS[ctrl.config.dry_run],
                             contract.RELIABLE)

    def send(self, now_ns, q_command, target, q_feedback):
        """Publish the window from ``q_command`` (module docstring)."""
        ctrl = self._ctrl
        _, velocity, acceleration = ctrl.shaper.state
        ahead = ctrl.shaper.preview(self._ahead)
        window = [np.vstack([now, later]) for now, later
                  in zip((q_command, velocity, acceleration), ahead)]
        self.pub.publish(joint_trajectory(now_ns, ctrl.command_period_ns,
                                          window[0][:, ctrl.order], ctrl.joints,
                                          velocities=window[1][:, ctrl.order],
                                          accelerations=window[2][:, ctrl.order]))


#: One sender a ``position_command_type``, as ros2_control has a controller a interface.
COMMAND_TYPES = {'forward_command': ForwardCommand, 'joint_trajectory': TrajectoryWindow}


class PositionController(JointControllerMode):
    """Position references for the arm's drive, free-running (module docstring)."""

    def __init__(self, node: 'Node', config: 'JointControllerConfig') -> None:
        """Check the joints, build the shaper and the input watch, open the topics."""
        super().__init__(node, config)
        #: Contract order -> the controller's ``joints`` order (checked by the config).
        self.order = joint_order(config.interface.joints)
        self._warn_ignored(node, config)
        self.joints = list(config.interface.joints)
        self.command_period_ns = period_ns(config.interface.command_rate_hz)
        self.shaper = shaper_for(config.values())
        self._hold = FeedbackHold(np.zeros(6))
        self._measured = None
        frame_timeout_ns = seconds_to_ns(config.frame_timeout_s)
        self._watch = InputWatch({'joint_states': seconds_to_ns(config.joint_state_timeout_s),
                                  'camera': frame_timeout_ns, 'feedback': frame_timeout_ns},
                                 required=('feedforward',), after_start=AFTER_START)
        self._verdict = None
        self._hold_target = None
        self.holds = 0
        self.frames_used = 0
        self.last_command_ns = None
        self.diagnostics.update(command_interface='position', commands=0,
                                position_command_type=config.interface.position_command_type,
                                dry_run=config.dry_run)
        self._sender = COMMAND_TYPES[config.interface.position_command_type](node, self)
        self._pub_latency = publisher(node, TimeReference, contract.FRAME_LATENCY,
                                      contract.RELIABLE)
        self._pub_status = publisher(node, Int8, contract.SERVO_STATUS, contract.LATCHED)
        measured = subscription(node, JointState, contract.JOINT_STATES, self._on_measured,
                                contract.RELIABLE).topic_name
        self._camera_topic = subscription(node, CameraInfo, contract.LEFT_INFO, self._on_camera,
                                          contract.CAMERA_INFO).topic_name
        self.subscribe_inputs()
        node.create_timer(ns_to_seconds(self.command_period_ns), self._command)
        self._clock = clock_watch(node)
        self._clock.on_back(self._clock_back)
        node.create_timer(CLOCK_CHECK_S, self._check_clock,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))
        #: The topics whose second publisher holds the arm: what it follows, and its own.
        self.hold_topics = (measured, node.resolve_topic_name(contract.Q_FEEDBACK),
                            node.resolve_topic_name(contract.FEEDFORWARD_TRAJECTORY),
                            self._sender.pub.topic_name)
        self._second = None  # HOLD_SECOND_PUBLISHER's verdict while one is there
        self._feedback_status = relay(node, self.diagnostics)  # the feedback's, relayed
        self.diagnostics.publishers.command(self._sender.pub.topic_name,
                                            self._publishers_changed)
        self.waiting = WaitReporter(node, self._waiting)
        self.diagnostics.log_progress(self._progress_line)
        node.get_logger().info(
            f'position references at {config.interface.command_rate_hz:g} Hz on '
            f'{self._sender.pub.topic_name} ({config.interface.position_command_type}), joints '
            f'{self.joints}' + (': DRY RUN, nothing goes to the arm (its command topic, '
                                f'{node.resolve_topic_name(type(self._sender).TOPICS[0])}, '
                                'is not opened)' if config.dry_run else ''))

    @staticmethod
    def _warn_ignored(node, config):
        """Log one warning naming the effort-only parameters set off their defaults."""
        ignored = [f'{name} = {value!r}' for name, value in config.off_default(EFFORT_ONLY)]
        if ignored:
            node.get_logger().warn(
                "ignored with command_interface 'position' (the arm's drive limits it, not "
                f"this node's torque model; a known gap): {', '.join(ignored)}")

    def now_ns(self) -> int:
        """Return the newest time the node knows: its clock and its last joint state."""
        return node_time_ns(self.node, self._measured[0] if self._measured else None)

    def _on_measured(self, msg):
        state = self.read_joint_state(msg)
        if state is None:
            return
        t_ns, q, _ = state
        if self._measured is not None and self._measured[0] is not None \
                and t_ns <= self._measured[0]:
            self.diagnostics.reject(contract.JOINT_STATES, 'out of order',
                                    f'{t_ns} ns, not newer than {self._measured[0]} ns')
            return
        self._measured = (t_ns, q)
        self._watch.heard('joint_states', t_ns)

    def _on_camera(self, msg):
        """Note a camera frame (its camera_info, stamped with the exposure): its age only."""
        try:  # an all-zero or impossible CameraInfo is no camera's frame
            check_camera_info(msg)
        except InputError as exc:
            self.diagnostics.reject(self._camera_topic, exc.reason, exc.detail)
            return
        t_ns = self.read_frame_stamp(self._camera_topic, msg.header.stamp)
        if t_ns is not None:
            self._watch.heard('camera', t_ns)

    def trajectory_arrived(self, start_ns):
        """Note the feedforward: the first command waits for it."""
        self._watch.heard('feedforward', start_ns)

    def take_feedback(self, t_ns, q):
        """Hold the q_feedback for the next command (newest wins)."""
        rejection = self._hold.offer(t_ns, q)
        if rejection is None:
            self._watch.heard('feedback', t_ns)
        return rejection

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
                self.node.get_logger().warn(f'{verdict.status.name}: {verdict.detail}')
            elif previous is not None and previous.holding:
                self.node.get_logger().info(f'fresh input at {now_ns * 1e-9:.3f} s: servoing '
                                            'resumes')
            level = (DiagnosticStatus.WARN if verdict.holding else DiagnosticStatus.OK)
            self.diagnostics.set_level(level, verdict.detail)
            self.diagnostics.update(servo_status=verdict.status.name, holds=self.holds)
        if verdict is not None:
            self._pub_status.publish(Int8(data=int(verdict.status)))

    def _clock_back(self, from_ns, to_ns):
        """Hold at once on a jump back of the clock; ages and stamp orders start again."""
        self._watch.forget(from_ns, to_ns)
        if self._measured is not None:  # the pose is still known; its stamp is not newer
            self._measured = (None, self._measured[1])
        self._hold.stamp_ns = None  # the held q_feedback's frame is of the old time line
        self.diagnostics.update(clock_jumps_back=self._clock.jumps_back)
        self._report(to_ns, self._watch.verdict(to_ns))

    def _verdict_at(self, now_ns):
        """
        Return the status at ``now_ns``: the input watch's, a second publisher first.

        Where neither has anything to say (NO_WARNING), the feedback node's warning.
        """
        verdict = self._watch.verdict(now_ns)
        if self._second is not None and verdict.status != ServoStatus.WAITING:
            return self._second
        return self._feedback_status.over(verdict)

    def _publishers_changed(self, found):
        """Hold while a second publisher is on a topic of ``hold_topics``; report at once."""
        self._second = second_publisher({t: found[t] for t in self.hold_topics if t in found})
        now_ns = self.node.get_clock().now().nanoseconds
        self._report(now_ns, self._verdict_at(now_ns))

    def _check_clock(self):
        """With sim time, hold (the status) when /clock has not moved for the wall bound."""
        if not self.node.get_clock().ros_time_is_active:
            return
        verdict = clock_stopped(self._clock.stalled_s(), self._clock.stall_bound_s())
        if verdict is not None:
            self._report(self.node.get_clock().now().nanoseconds, verdict)

    def _command(self):
        """Send one position reference (module docstring)."""
        now_ns = read_clock_ns(self.node)
        verdict = self._verdict_at(now_ns)
        self._report(now_ns, verdict)
        if verdict.status == ServoStatus.WAITING:
            return
        if not self.shaper.started:
            self.shaper.start(self._measured[1])
            self.last_command_ns = now_ns - self.command_period_ns
        if verdict.holding:
            if self._hold_target is None:  # a controlled stop
                self._hold_target = self.shaper.stopping_point()
            target, first_frame_ns, q_feedback = self._hold_target, None, None
        else:
            self._hold_target = None
            q_feedback, first_frame_ns = self._hold.use()
            target = self.feedforward_target() + q_feedback
        q_command = self.shaper.step(target, ns_to_seconds(now_ns - self.last_command_ns))
        self.last_command_ns = now_ns
        self._sender.send(now_ns, q_command, target, q_feedback)
        if first_frame_ns is not None:
            self._pub_latency.publish(TimeReference(
                header=Header(stamp=ns_stamp(now_ns)), time_ref=ns_stamp(first_frame_ns),
                source=contract.Q_FEEDBACK))
            self.frames_used += 1
        self.commands += 1
        self.waiting.progress()
        self.diagnostics.update(commands=self.commands, frames_used=self.frames_used,
                                last_command_ns=now_ns)

    def _progress_line(self):
        """Return the progress line: references sent, up to when (None before the first)."""
        if not self.commands:
            return None
        return (f'{self.commands} position references sent (last at '
                f'{self.last_command_ns * 1e-9:.3f} s), {self.frames_used} frames of '
                'q_feedback used')

    def _waiting(self):
        """Report the servo status; return the wait reporter's line (None when ready)."""
        missing = [INPUTS[name] for name in self._watch.awaited()]
        self._report(self.node.get_clock().now().nanoseconds)
        return 'waiting to send position references for ' + ', '.join(missing) \
            if missing else None
