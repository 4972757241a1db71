"""The five nodes, each in a :class:`~.harness.Rig` that knows its valid input and action."""

from ibvs_common import contract
from ibvs_common.conversions import (camera_infos, features_msg, image_msg, joint_state,
                                     joint_trajectory, ns_stamp, pose_stamped, stamp_ns)
from ibvs_common.timing import feedback_frame_ns, frame_stamp_ns
from ibvs_model import (CameraRobotModel, default_camera, inverse_kinematics, IRB4600,
                        paper)
import numpy as np
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from . import cases as bad
from .cases import NAMES
from .harness import Case, Rig

MS = 1_000_000
CAMERA_NS = 33_333_333
#: The true joint angles of the scenario 1 start.
Q0 = inverse_kinematics(paper.scenario_start_pose(1))
SIM_TIME = [Parameter('use_sim_time', value=True)]
#: The free-running position interface (docs/design.md §4): sim_node and joint controller.
POSITION = [Parameter('command_interface', value='position')]


def frame_ns(n):
    """Return the stamp of frame ``n`` at 30 Hz on the 1 kHz physics grid."""
    return frame_stamp_ns(n, CAMERA_NS, MS)


class FrameTimeLine:
    """
    The time line of a rig whose inputs are camera frames ``n``: its 'clock set back' part.

    ``OUTPUTS`` names the list of what the node published that :meth:`Rig.valid_step`
    looks for by stamp: a rewound time line stamps its frames again, so it is emptied.
    """

    OUTPUTS = 'out'

    def now_ns(self):
        """Return the stamp of the last frame sent."""
        return frame_ns(self.n - 1)

    def rewind(self, t_ns):
        """Go on with the frames after ``t_ns``; forget what was published of the earlier."""
        self.n = 0
        while frame_ns(self.n) <= t_ns:
            self.n += 1
        getattr(self, self.OUTPUTS).clear()


def build(rig, specs):
    """
    Return a case maker per (name, topic, make) of ``specs``, and the rig's second publishers.

    ``make()`` returns the messages (each a message of ``topic`` or (topic, msg)), or a
    whole :class:`~.harness.Case`. Every rig gets the 'second publisher' class on the
    topics of :data:`.cases.SECOND_PUBLISHER_TOPICS` it reads or commands on, and one that
    reads /clock and can rewind its inputs (``now_ns`` and ``rewind(t_ns)``) the 'clock set
    back' class (:func:`.cases.clock_jumps`), last: its time line starts again.
    """
    makers = []
    for name, topic, make in (list(specs) + bad.second_publishers(rig)
                              + bad.clock_jumps(rig)):
        def maker(name=name, topic=topic, make=make):
            made = make()
            if isinstance(made, Case):
                return made
            messages = [m if isinstance(m, tuple) else (topic, m) for m in made]
            return Case(name, topic, messages)
        makers.append(maker)
    return makers


class JointControllerRig(Rig):
    """joint_controller_node: acts by answering /joint_states with an effort command."""

    def __init__(self, context):
        """Create the node (sim time) and its rig."""
        from ibvs_control.joint_controller_node import JointControllerNode
        node = JointControllerNode(context=context, parameter_overrides=SIM_TIME)
        super().__init__(context, node, node.diagnostics)
        self.k = 0
        self.feedback_sent = set()
        self.efforts = []
        self.driver.create_subscription(JointState, contract.EFFORT_COMMANDS,
                                        lambda m: self.efforts.append(m), contract.RELIABLE)

    def setup(self):
        """Send the feedforward trajectory: the arm held at Q0."""
        self.deliver(contract.FEEDFORWARD_TRAJECTORY,
                     joint_trajectory(0, MS, np.tile(Q0, (5, 1))))

    def next_ns(self):
        """Return the stamp of the next joint state."""
        return self.k * MS

    def valid_step(self):
        """Send the q_feedback it needs (if new) and the next joint state."""
        t = self.next_ns()
        frame = feedback_frame_ns(t, CAMERA_NS, 0, MS)
        if frame not in self.feedback_sent:
            self.deliver(contract.Q_FEEDBACK, joint_state(frame, np.zeros(6)))
            self.feedback_sent.add(frame)
        self.deliver(contract.JOINT_STATES, joint_state(t, Q0, np.zeros(6)))
        self.k += 1
        return lambda: any(stamp_ns(m.header.stamp) == t for m in self.efforts)

    def next_frame_ns(self):
        """Return the stamp of the frame the next joint state will need after this one."""
        t = self.next_ns() + CAMERA_NS
        return feedback_frame_ns(t, CAMERA_NS, 0, MS)

    def now_ns(self):
        """Return the stamp of the last joint state sent."""
        return self.next_ns() - MS

    def rewind(self, t_ns):
        """Go on with the joint states after ``t_ns`` (and their q_feedback) as new."""
        self.k = t_ns // MS + 1
        self.feedback_sent.clear()
        self.efforts.clear()

    def cases(self):
        """Return every case of every topic it subscribes."""
        held = np.tile(Q0, (5, 1))
        specs = (bad.joint_states(contract.JOINT_STATES, self.next_ns, Q0,
                                  ('position', 'velocity'),
                                  last_ns=lambda: self.next_ns() - MS)
                 + bad.joint_states(contract.Q_FEEDBACK, self.next_frame_ns, np.zeros(6))
                 + bad.headers(contract.FRAME_LOST, self.next_frame_ns)
                 + bad.trajectories(contract.FEEDFORWARD_TRAJECTORY, self.next_ns, held)
                 + bad.huge_trajectories(contract.FEEDFORWARD_TRAJECTORY, held,
                                         lambda n: _holds(self.node, n))
                 + bad.feedback_statuses()
                 + bad.clocks())
        return build(self, specs)


def _holds(node, points):
    """Return whether the joint controller ``node`` holds a feedforward of ``points`` points."""
    trajectory = node.mode._trajectory
    return trajectory is not None and len(trajectory[1]) == points


class SimRig(Rig):
    """sim_node: acts by taking a physics step on the command stamped with its step."""

    def __init__(self, context):
        """Create the node (no images: its inputs are the commands and /clock)."""
        from ibvs_sim.sim_node import SimNode
        node = SimNode(context=context, parameter_overrides=SIM_TIME + [
            Parameter('publish_images', value=False)])
        self.joints = []
        super().__init__(context, node, node.diagnostics)
        self.driver.create_subscription(JointState, contract.JOINT_STATES,
                                        lambda m: self.joints.append(m), contract.RELIABLE)

    def setup(self):
        """Wait for step 0."""
        assert self.spin_until(lambda: self.joints, 'step 0')

    def next_ns(self):
        """Return the stamp of the step the simulator waits for."""
        return self.node.sim.t_ns

    def valid_step(self):
        """Send the holding torque of the current step."""
        t = self.next_ns()
        torque = self.node.sim.hold_torque()
        self.deliver(contract.EFFORT_COMMANDS, joint_state(t, effort=torque))
        return lambda: self.node.sim.t_ns > t and any(
            stamp_ns(m.header.stamp) == self.node.sim.t_ns for m in self.joints)

    def cases(self):
        """Return every case of every topic it subscribes."""
        specs = (bad.joint_states(contract.EFFORT_COMMANDS, self.next_ns, np.zeros(6),
                                  ('effort',), scale=1e6) + bad.clocks())
        return build(self, specs)


class SimPositionRig(Rig):
    """
    sim_node free-running with the position drive: acts by tracking a new valid reference.

    ``command_type`` is the ``position_command_type``: 'forward_command'
    (Float64MultiArray) or 'joint_trajectory' (JointTrajectory).
    """

    def __init__(self, context, command_type='forward_command'):
        """Create the node (no images; the default real_time_factor)."""
        from ibvs_sim.sim_node import SimNode
        node = SimNode(context=context, parameter_overrides=POSITION + [
            Parameter('position_command_type', value=command_type),
            Parameter('publish_images', value=False)])
        self.joints = []
        self.topic = node.mode.command_sub.topic_name
        self.n = 0
        super().__init__(context, node, node.diagnostics)
        self.driver.create_subscription(JointState, contract.JOINT_STATES,
                                        lambda m: self.joints.append(m), contract.RELIABLE)

    def setup(self):
        """Wait for the free run to start (trajectories: until :meth:`past_ns` is positive)."""
        assert self.spin_until(lambda: self.joints, 'free-running /joint_states')
        if self.topic == contract.TRAJECTORY_COMMANDS:
            assert self.spin_until(lambda: self.past_ns() > MS, 'a stamp in the past')

    def past_ns(self):
        """Return a stamp whose two-point trajectory ended a command timeout ago and more."""
        return self.node.sim.t_ns - 2 * self.node.mode._command_timeout_ns - 2 * MS

    @property
    def q_start(self):
        """Return the encoder angles (contract order) of the start pose."""
        return self.node.sim.q_start - self.node.sim.d_q

    def command(self, q, names=NAMES):
        """Return the command message of encoder angles ``q`` given in ``names`` order."""
        if self.topic == contract.POSITION_COMMANDS:
            return Float64MultiArray(data=[float(v) for v in q])
        return joint_trajectory(0, MS, np.atleast_2d(q), names)

    def valid_step(self):
        """Send a new reference (0.01 rad either side of the start); tracked from the next step."""
        self.n += 1
        q = self.q_start + (0.01 if self.n % 2 else -0.01)
        before, t = self.node.mode.commands, self.node.sim.t_ns
        self.deliver(self.topic, self.command(q))
        return lambda: (self.node.mode.commands > before and self.node.sim.t_ns > t
                        and np.allclose(self.node.mode.servo.reference, q + self.node.sim.d_q)
                        and self.node.diagnostics.values['command'] == 'tracking')

    def cases(self):
        """Return every case of every topic it subscribes."""
        q = self.q_start
        beyond = np.r_[q[:3], 10.0, q[4:]]  # joint_4 past its travel (+-6.98 rad)
        if self.topic == contract.POSITION_COMMANDS:
            specs = bad.arrays(self.topic, q, beyond)
        else:
            specs = [c for c in bad.trajectories(self.topic, lambda: 0, np.tile(q, (5, 1)))
                     if c[0] != 'wrong sample times']  # the drive takes the last point only
            specs += bad.command_trajectories(self.topic, q, beyond, self.past_ns)
        return build(self, specs)  # no /clock: the sim is the clock


class JointControllerPositionRig(Rig):
    """joint_controller_node, position interface: acts by a reference per command period."""

    def __init__(self, context):
        """Create the node (sim time: its command timer fires as the driver moves /clock)."""
        from ibvs_control.joint_controller_node import JointControllerNode
        node = JointControllerNode(context=context, parameter_overrides=SIM_TIME + POSITION)
        super().__init__(context, node, node.diagnostics)
        self.t_ns = 0
        self.commands = []
        self.driver.create_subscription(Float64MultiArray, contract.POSITION_COMMANDS,
                                        lambda m: self.commands.append(m), contract.RELIABLE)

    def setup(self):
        """Send the feedforward (the arm held at Q0), the first joint state and frame."""
        self.deliver(contract.FEEDFORWARD_TRAJECTORY,
                     joint_trajectory(0, MS, np.tile(Q0, (5, 1))))
        self.deliver(contract.JOINT_STATES, joint_state(0, Q0))
        self.frame = 0
        self._deliver_frame()

    def _deliver_frame(self):
        """Send the camera's frame ``self.frame`` (its camera_info) and its q_feedback."""
        t_ns = frame_ns(self.frame)
        info = camera_infos(default_camera('VGA').intrinsics, t_ns)[0]
        self.deliver(contract.LEFT_INFO, info)
        self.deliver(contract.Q_FEEDBACK, joint_state(t_ns, np.zeros(6)))

    def next_ns(self):
        """Return the stamp of the next joint state."""
        return self.t_ns + self.node.mode.command_period_ns

    def next_frame_ns(self):
        """Return the stamp of the first camera frame after the next joint state."""
        return frame_ns(-(-self.next_ns() // CAMERA_NS) + 1)

    def valid_step(self):
        """Send the next joint state, then move /clock one command period on."""
        self.t_ns = self.next_ns()
        before = len(self.commands)
        self.deliver(contract.JOINT_STATES, joint_state(self.t_ns, Q0))
        while frame_ns(self.frame + 1) <= self.t_ns:  # the camera and the feedback go on
            self.frame += 1
            self._deliver_frame()
        self.deliver(contract.CLOCK, Clock(clock=ns_stamp(self.t_ns)))
        return lambda: len(self.commands) > before

    def published_finite(self):
        """Return whether every position reference it sent was finite."""
        return bool(self.commands) and all(np.all(np.isfinite(m.data)) for m in self.commands)

    def now_ns(self):
        """Return the time of the last joint state and /clock sent."""
        return self.t_ns

    def rewind(self, t_ns):
        """Go on from ``t_ns`` (the /clock sent): its joint states and frames as new."""
        self.t_ns = t_ns
        self.frame = 0
        self._deliver_frame()

    def cases(self):
        """Return every case of every topic it subscribes."""
        held = np.tile(Q0, (5, 1))
        specs = (bad.joint_states(contract.JOINT_STATES, self.next_ns, Q0,
                                  last_ns=lambda: self.t_ns)
                 + bad.joint_states(contract.Q_FEEDBACK, self.next_frame_ns, np.zeros(6))
                 + bad.trajectories(contract.FEEDFORWARD_TRAJECTORY, self.next_ns, held)
                 + bad.huge_trajectories(contract.FEEDFORWARD_TRAJECTORY, held,
                                         lambda n: _holds(self.node, n))
                 + bad.camera_info_stamps(contract.LEFT_INFO, camera_infos(
                     default_camera('VGA').intrinsics, 0)[0])
                 + bad.feedback_statuses()
                 + bad.clocks())
        return build(self, specs)


class VizRig(FrameTimeLine, Rig):
    """
    viz_node: acts by /ibvs/markers at each joint state, stamped with its stamp.

    ``marker_rate_hz`` 1000: a frame's joint state (33 ms after the last) always draws.
    """

    OUTPUTS = 'drawn'

    def __init__(self, context):
        """Create the node (sim time, as ``ibvs run`` starts it)."""
        from ibvs_viz.viz_node import VizNode
        node = VizNode(context=context, parameter_overrides=SIM_TIME + [
            Parameter('marker_rate_hz', value=1000.0)])
        super().__init__(context, node, node._diag)
        self.camera = default_camera('HD720')
        self.model = CameraRobotModel(self.camera, IRB4600)
        self.n = 0
        self.drawn = []
        self.driver.create_subscription(MarkerArray, contract.MARKERS,
                                        lambda m: self.drawn.append(m), 10)

    def setup(self):
        """Send the camera: both CameraInfo and /stereo/pose."""
        left, right = camera_infos(self.camera.intrinsics, 0)
        self.deliver(contract.STEREO_POSE, pose_stamped(self.camera.pose_C_O, 0))
        self.deliver(contract.LEFT_INFO, left)
        self.deliver(contract.RIGHT_INFO, right)
        assert self.node._camera is not None

    def next_ns(self):
        """Return the stamp of the next frame."""
        return frame_ns(self.n)

    def valid_step(self):
        """Send the next frame's CameraInfo, joint state, features and feature status."""
        t = self.next_ns()
        self.n += 1
        for topic, info in zip((contract.LEFT_INFO, contract.RIGHT_INFO),
                               camera_infos(self.camera.intrinsics, t)):
            self.deliver(topic, info)  # every frame's, as the simulator and the ZED send
        self.deliver(contract.FEATURES, features_msg(self.model.features(Q0), t))
        self.deliver(contract.FEATURE_STATUS, bad.status(t, 'measured'))
        self.deliver(contract.JOINT_STATES, joint_state(t, Q0, np.zeros(6)))
        return lambda: any(stamp_ns(m.markers[0].header.stamp) == t for m in self.drawn)

    def off_image(self):
        """Return a measured frame's features and status, its features 1e6 px off."""
        t = self.next_ns()
        self.n += 1  # the frame is used: the next valid one has the next stamp
        far = self.model.features(Q0) + np.r_[1e6, 1e6, 0.0, 0.0, 0.0, 0.0]
        return [(contract.FEATURES, features_msg(far, t)),
                (contract.FEATURE_STATUS, bad.status(t, contract.FEATURE_MEASURED))]

    def published_finite(self):
        """Return whether every /ibvs/markers it sent was finite (poses and points)."""
        return bool(self.drawn) and all(
            np.all(np.isfinite([[p.x, p.y, p.z] for p in m.points]
                               + [[m.pose.position.x, m.pose.position.y, m.pose.position.z]]))
            for a in self.drawn for m in a.markers)

    def cases(self):
        """Return every case of every topic it subscribes."""
        left, right = camera_infos(self.camera.intrinsics, 0)
        specs = (bad.joint_states(contract.JOINT_STATES, self.next_ns, Q0,
                                  last_ns=lambda: frame_ns(self.n - 1))
                 + bad.polygons(contract.FEATURES, self.next_ns, self.model.features(Q0),
                                last_ns=lambda: frame_ns(self.n - 1))
                 + [('measured features 1e6 px off the image', contract.FEATURES,
                     self.off_image)]
                 + bad.statuses(contract.FEATURE_STATUS, self.next_ns,
                                last_ns=lambda: frame_ns(self.n - 1))
                 + bad.camera_infos(contract.LEFT_INFO, left)
                 + bad.camera_infos(contract.RIGHT_INFO, right)
                 + bad.poses(contract.STEREO_POSE, self.camera.pose_C_O)
                 + bad.clocks())
        return build(self, specs)


class RobotStateRig(FrameTimeLine, Rig):
    """robot_state_node: acts by publishing /tf at each joint state, stamped with its stamp."""

    OUTPUTS = 'tf'

    def __init__(self, context):
        """Create the node (sim time, as ``ibvs run`` starts it)."""
        from ibvs_sim.robot_state_node import RobotStateNode
        node = RobotStateNode(context=context, parameter_overrides=SIM_TIME)
        super().__init__(context, node, node._diag)
        self.n = 0
        self.tf = []
        self.driver.create_subscription(TFMessage, contract.TF, lambda m: self.tf.append(m),
                                        100)

    def next_ns(self):
        """Return the stamp of the next frame."""
        return frame_ns(self.n)

    def valid_step(self):
        """Send the next frame's joint state."""
        t = self.next_ns()
        self.n += 1
        self.deliver(contract.JOINT_STATES, joint_state(t, Q0, np.zeros(6)))
        return lambda: any(stamp_ns(m.transforms[0].header.stamp) == t for m in self.tf)

    def published_finite(self):
        """Return whether every /tf it sent was finite."""
        return bool(self.tf) and all(
            np.all(np.isfinite([t.transform.translation.x, t.transform.translation.y,
                                t.transform.translation.z, t.transform.rotation.w]))
            for m in self.tf for t in m.transforms)

    def cases(self):
        """Return every case of every topic it subscribes."""
        specs = (bad.joint_states(contract.JOINT_STATES, self.next_ns, Q0,
                                  last_ns=lambda: frame_ns(self.n - 1))
                 + bad.clocks())
        return build(self, specs)


class FeedforwardRig(Rig):
    """feedforward_node: acts once, on its first valid /joint_states, by a trajectory."""

    def __init__(self, context):
        """Create the node (sim time, no /clock yet: time unknown)."""
        from ibvs_control.feedforward_node import FeedforwardNode
        node = FeedforwardNode(context=context, parameter_overrides=SIM_TIME)
        super().__init__(context, node, node.diagnostics)
        self.trajectories = []
        self.driver.create_subscription(JointTrajectory, contract.FEEDFORWARD_TRAJECTORY,
                                        lambda m: self.trajectories.append(m),
                                        contract.LATCHED)

    def recovered(self):
        """Still listening: no trajectory yet, its input open (the valid state comes last)."""
        return not self.trajectories and self.node.t0_ns is None

    def valid_step(self):
        """Send the first valid state, at t = 0."""
        self.deliver(contract.JOINT_STATES, joint_state(0, Q0, np.zeros(6)))
        return lambda: len(self.trajectories) == 1

    def cases(self):
        """Return every case of every topic it subscribes."""
        specs = bad.joint_states(contract.JOINT_STATES, lambda: 0, Q0) + bad.clocks()
        specs += [('position 100 rad', contract.JOINT_STATES,
                   lambda: [joint_state(0, np.r_[100.0, Q0[1:]], np.zeros(6))]),
                  ('position -1e6 rad', contract.JOINT_STATES,
                   lambda: [joint_state(0, np.r_[Q0[:5], -1e6], np.zeros(6))])]
        return build(self, specs)


class AdaptiveFeedbackRig(FrameTimeLine, Rig):
    """adaptive_feedback_node: acts by answering each frame's features with a q_feedback."""

    def __init__(self, context):
        """Create the node (sim time, the paper's law, the model target)."""
        from ibvs_control.adaptive_feedback_node import AdaptiveFeedbackNode
        node = AdaptiveFeedbackNode(context=context, parameter_overrides=SIM_TIME)
        super().__init__(context, node, node.diagnostics)
        self.camera = default_camera('HD720')
        self.model = CameraRobotModel(self.camera, IRB4600)
        self.n = 0
        self.out = []
        self.driver.create_subscription(JointState, contract.Q_FEEDBACK,
                                        lambda m: self.out.append(m), contract.RELIABLE)

    def setup(self):
        """Send the camera model: both CameraInfo and /stereo/pose."""
        left, right = camera_infos(self.camera.intrinsics, 0)
        self.deliver(contract.STEREO_POSE, pose_stamped(self.camera.pose_C_O, 0))
        self.deliver(contract.LEFT_INFO, left)
        self.deliver(contract.RIGHT_INFO, right)
        assert self.spin_until(lambda: self.node.feedback is not None, 'camera model')

    def next_ns(self):
        """Return the stamp of the next frame."""
        return frame_ns(self.n)

    def valid_step(self):
        """Send the next frame's joint state and features."""
        t = self.next_ns()
        self.n += 1
        self.deliver(contract.JOINT_STATES, joint_state(t, Q0, np.zeros(6)))
        self.deliver(contract.FEATURES, features_msg(self.model.features(Q0), t))
        return lambda: any(stamp_ns(m.header.stamp) == t for m in self.out)

    def cases(self):
        """Return every case of every topic it subscribes."""
        left, right = camera_infos(self.camera.intrinsics, 0)
        specs = (bad.joint_states(contract.JOINT_STATES, self.next_ns, Q0,
                                  ('position', 'velocity'),
                                  last_ns=lambda: frame_ns(self.n - 1))
                 + bad.polygons(contract.FEATURES, self.next_ns, self.model.features(Q0),
                                last_ns=lambda: frame_ns(self.n - 1))
                 + bad.camera_infos(contract.LEFT_INFO, left)
                 + bad.camera_infos(contract.RIGHT_INFO, right)
                 + bad.poses(contract.STEREO_POSE, self.camera.pose_C_O)
                 + bad.clocks())
        return build(self, specs)


class FeatureRig(FrameTimeLine, Rig):
    """
    feature_node: acts by publishing the features of each complete stereo frame.

    ``resolution`` is the ZED 2's of the frames; at full size (HD720) the cases add
    valid images costly to search (:func:`.cases.contents`).
    """

    def __init__(self, context, resolution='VGA'):
        """Create the node (sim time); frames are black (the estimate is published)."""
        from ibvs_vision.feature_node import FeatureNode
        from geometry_msgs.msg import PolygonStamped
        node = FeatureNode(context=context, parameter_overrides=SIM_TIME)
        super().__init__(context, node, node._diag)
        self.resolution = resolution
        self.camera = default_camera(resolution)
        self.n = 0
        self.out = []
        self.driver.create_subscription(PolygonStamped, contract.FEATURES,
                                        lambda m: self.out.append(m), contract.RELIABLE)

    def setup(self):
        """Send /stereo/pose."""
        self.deliver(contract.STEREO_POSE, pose_stamped(self.camera.pose_C_O, 0))

    def next_ns(self):
        """Return the stamp of the next frame."""
        return frame_ns(self.n)

    def image(self, t_ns):
        """Return a black VGA image stamped ``t_ns``."""
        k = self.camera.intrinsics
        return image_msg(np.zeros((k.height, k.width, 3), dtype=np.uint8), t_ns)

    def frame(self, left=None, right=None):
        """Return the next frame's messages; ``left``/``right`` change that image."""
        t = self.next_ns()
        self.n += 1
        infos = camera_infos(self.camera.intrinsics, t)
        images = [self.image(t), self.image(t)]
        for i, change in enumerate((left, right)):
            if change is not None:
                images[i] = change(images[i])
        return [(contract.LEFT_INFO, infos[0]), (contract.RIGHT_INFO, infos[1]),
                (contract.JOINT_STATES, joint_state(t, Q0, np.zeros(6))),
                (contract.LEFT_IMAGE, images[0]), (contract.RIGHT_IMAGE, images[1])]

    def answered(self, messages):
        """
        Return the predicate that the frame of ``messages`` was answered.

        Published (its features), or dropped with a count under its images or as a stereo
        frame; made before the frame is sent.
        """
        t = stamp_ns(messages[-1][1].header.stamp)
        topics = ('stereo frame', self.node._topics['left'], self.node._topics['right'])

        def drops():
            return sum(n for key, n in self.diagnostics.rejections.items()
                       if key.split(': ')[0] in topics)
        before = drops()
        return lambda: (any(stamp_ns(m.header.stamp) == t for m in self.out)
                        or drops() > before)

    def valid_step(self):
        """Send the next complete frame."""
        t = self.next_ns()
        for topic, msg in self.frame():
            self.deliver(topic, msg)
        return lambda: any(stamp_ns(m.header.stamp) == t for m in self.out)

    def cases(self):
        """Return every case of every topic it subscribes."""
        left, right = camera_infos(self.camera.intrinsics, 0)
        specs = (bad.joint_states(contract.JOINT_STATES, self.next_ns, Q0,
                                  last_ns=lambda: frame_ns(self.n - 1))
                 + bad.images(contract.LEFT_IMAGE, self.frame, self.image)
                 + bad.images(contract.RIGHT_IMAGE, self.frame, self.image)
                 + bad.camera_infos(contract.LEFT_INFO, left)
                 + bad.camera_infos(contract.RIGHT_INFO, right)
                 + bad.poses(contract.STEREO_POSE, self.camera.pose_C_O)
                 + bad.clocks())
        if self.resolution == 'HD720':
            k = self.camera.intrinsics
            specs += bad.contents(contract.LEFT_IMAGE, self.frame, self.answered, k.width,
                                  k.height)
        for topic in (contract.TEACH_LEFT_IMAGE, contract.TEACH_RIGHT_IMAGE):
            specs += [(name, topic, make) for name, make in (
                ('encoding 16UC1', lambda: [_encoding(self.image(0), '16UC1')]),
                ('data length', lambda: [_truncated(self.image(0))]))]
        return build(self, specs)


def _encoding(msg, encoding):
    msg.encoding = encoding
    return msg


def _truncated(msg):
    msg.data = bytes(msg.data)[:-5]
    return msg
