"""
sim_node: the simulated plant (paper Figure 3) on the contract of docs/design.md §3 and §4.

Lockstep. At step k (sim time t_k, from 0) the node publishes, in this order: when /clock is
due (``clock_rate_hz``, 10 Hz: the first step at or after each multiple of its period; sim
time for the nodes' clocks, at gazebo_ros's default rate; no result depends on it), first
the evaluation's batches of the steps since the last one: /ibvs/tool_path with the true
flange poses and /ibvs/joint_path with their /joint_states (:func:`ibvs_common.conversions.
joint_path`), then /clock, so that when /clock says T every tool pose and joint state
stamped before T is out; /joint_states (encoder angles q - d_q, velocities, the torque of
the previous step); on a camera frame's step, the same joint state on /stereo/joint_states,
then the frame (both images and CameraInfo, stamped t_k), which it renders while the joint
controller works on step k. Every consumer matches its inputs by stamp, so the order
changes no result. It then waits for /joint_effort_commands stamped t_k; that message (and
only that one) applies its torques for one step and moves to k + 1, inside the subscription
callback: nothing spins or sleeps, so any number of nodes can share one executor. While it
waits, a steady-clock timer logs once a second what it waits for. When the node is
destroyed (the end of a run) it publishes the batches of the steps since the last /clock.

Who gets the per-step messages: whoever subscribes to them. In a run, /joint_states goes to
the joint controller, in this process, and to the feedforward until its first state; the
recorder takes /ibvs/joint_path instead of /joint_states and /joint_effort_commands, so no
message leaves the process at every step (one to another process costs the lockstep more
than one within it: docs/speed.md). A viewer that wants the 1 kHz states (Foxglove,
``ros2 topic echo``) subscribes to /joint_states and gets them: there is nothing to switch
on here.

Start. Step 0 is published once somebody will answer and listen: /joint_effort_commands
has a publisher, /joint_states a subscriber (and /stereo/joint_states, /ibvs/tool_path and
/ibvs/joint_path as many as the runner says) and, with publish_images, both image topics a
subscriber (so that no lockstep message is published before its reader is matched). Until
then it logs once a second what is missing.

A real camera (ibvs_sim.camera_effects, all off by default). Images are rendered with the
true camera and get Gaussian noise (image_noise_stddev); /stereo/pose and camera_info carry
the calibrated camera (camera_pose_error_xyz_m, camera_pose_error_rpy_deg,
focal_length_error), so every controller-side consumer sees what a calibration would give
it while the images show the truth. A lost frame (frame_drop_probability) has no images and
no CameraInfo: in their place one std_msgs/Header stamped with the frame's stamp goes to
/stereo/frame_lost, and the step is published as usual. Downstream: the feature node gets
nothing for that stamp and publishes nothing; the adaptive feedback gets no features, so
its controller skips that sample and its q_feedback holds; the joint controller, which
would wait for the q_feedback of that frame, learns from /stereo/frame_lost that none will
come and holds the previous frame's (what a real controller does with a missing frame; the
notice exists only so that the lockstep needs no timeout). Draws come from one Generator
seeded with camera_seed. With target_features_source 'taught' the tool is first placed at
the target pose and a stereo pair rendered (true camera, noise added); it is published
latched on /stereo/teach/{left,right}/image_raw for the feature node to measure p_bar.

Free-running (``lockstep: false``, with ``command_interface: position``: a real cell's
timing, docs/design.md §4.1). After the same start, a steady-clock timer advances the
physics on its own, ``real_time_factor`` sim seconds per wall second (Gazebo's setting),
publishing each step's outputs as above, as the real components do (issue 34):
/joint_states as joint_state_broadcaster publishes them, at ``joint_state_rate_hz`` (the
controller manager's rate, 250 Hz on abb_ros2) on its own cycle from
``joint_state_phase_s`` (the first step at or after each update time, stamped with it),
the arm's six joints and ``extra_joints`` at 0; no /stereo/joint_states (a real cell has
none: the frame's readers interpolate /joint_states, and ``min_frame_joint_state_
subscribers`` is ignored with a warning); each frame rendered when it is due, stamped with
its exposure time (the step it shows) and delivered ``feedback_latency_s`` of sim time
later, whether or not anybody is ready (the camera's latency; in lockstep the joint
controller applies that parameter instead); none exposed within ``camera_outage_s``
([start, duration], a test hook refused in lockstep: no images, no CameraInfo, no
/stereo/frame_lost). The parameters only free-running uses are ignored in lockstep with a
warning when set off their defaults. /clock goes out at least at ``command_rate_hz`` (so
that the joint controller's sim-time command timer fires at its rate). The arm is a
position-controlled IRB 4600: joint references on /forward_position_controller/commands
(std_msgs/Float64MultiArray, values in the order of the ``joints`` parameter, as
ros2_controllers' forward_command_controller takes them) or, with ``position_command_type:
joint_trajectory``, on /joint_trajectory_controller/joint_trajectory (trajectory_msgs/
JointTrajectory, mapped by joint name; a window of stamped points sampled as
joint_trajectory_controller samples it, at ``command_rate_hz``:
:class:`.position_servo.TrajectoryFollower`), tracked by the drive model
:class:`.position_servo.PositionServo` (dead time, bandwidth, speed and acceleration
limits), the last reference held (zero-order hold). A reference
older than ``command_timeout_s`` (sim time) is stale: the drive stops the arm and holds it,
logs it and says so on /diagnostics (``command: stale``) until a new one comes. A command
with the wrong number of values, unknown, missing or repeated joint names, a non-finite
value or a position outside the joint's range is rejected and counted; a JointTrajectory
also for a point anywhere in it out of range, non-finite (velocities and accelerations
too) or of the wrong length, times from start negative or not strictly increasing, and a
header stamp malformed, more than ``command_timeout_s`` ahead of sim time, or (when not 0,
which means now) ending more than ``command_timeout_s`` in the past: what
joint_trajectory_controller refuses, its source cited by
:func:`ibvs_common.conversions.read_command_trajectory`. When the machine
cannot keep ``real_time_factor`` (a step's work, rendering above all, takes longer than its
share of wall time) the node says so once a second (WARN log and /diagnostics
``real_time_factor_held``) and goes on at the pace it can hold: sim time is never skipped.
From the first position reference on (the servoing) it measures the factor over windows of
``SERVO_RTF_WINDOW_S`` (1 s) of wall time: /diagnostics ``real_time_factor_servo_min_1s``
(the smallest window's) and ``real_time_factor_servo_mean`` (over all complete windows).

By hand. Every few seconds of wall time the node logs its progress (sim time, the real-time
factor since the last line, frames); with ``duration_s`` it stops stepping once sim time
reaches it (the last batches and /clock published, the steps in [0, duration_s) done) and
stays up, silent, until stopped.

Bad input. A command with a malformed stamp (:func:`ibvs_common.conversions.read_stamp`) is
rejected; one with another stamp is rejected as stale (older) or early (newer) and ignored.
A command with the right stamp but a wrong length, unknown joint names, NaN or inf, or an
effort beyond :data:`EFFORT_BOUND_FACTOR` times its joint's rated torque (absurd: it would
only break the physics) is rejected too; the step then happens with the holding torque
(PyBullet inverse dynamics that stops the arm where it is: Simulator.hold_torque), so the run
goes on and the arm holds its position. Each rejection is logged and counted on /diagnostics.
"""

from dataclasses import dataclass
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from ibvs_common import contract
from ibvs_common.conversions import (camera_infos, duration_ns, image_msg, InputError,
                                     joint_path, joint_state, ns_stamp, path_msg,
                                     pose_stamped, read_command_trajectory, read_joints,
                                     read_stamp, stamp_ns)
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.kit import publisher, subscription, WaitReporter
from ibvs_common.node_main import run
from ibvs_common.params import declare, Param, ParameterError
from ibvs_common.shared_params import (check_command_interface, COMMAND_INTERFACE,
                                       COMMAND_RATE_HZ, FEEDBACK_LATENCY_S, JOINTS, LOCKSTEP,
                                       MAX_JOINT_SPEED_DEG_S, POSITION_COMMAND_TYPE,
                                       TARGET_FEATURES_SOURCE, target_from_parameters,
                                       TARGET_POSITION, TARGET_ROTATION)
from ibvs_common.timing import period_ns, seconds_to_ns
from ibvs_model import IRB4600
from ibvs_model.drive import EGM_BANDWIDTH_HZ, EGM_DELAY_S, SPEED_LIMITS
from ibvs_model.mass_model import joint_efforts
from nav_msgs.msg import Path
import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Float64MultiArray, Header
from trajectory_msgs.msg import JointTrajectory

from .config import SimConfig
from .position_servo import PositionServo, TrajectoryFollower
from .simulator import Simulator

PUBLISH_IMAGES = Param('publish_images', True, 'render and publish the stereo images and '
                       'CameraInfo (false: physics only, e.g. with a model-based feature '
                       'source)', '-')

CLOCK_RATE_HZ = Param(
    'clock_rate_hz', 10.0, "rate of /clock, the sim time of every node's clock (10 Hz, as "
    'gazebo_ros publishes it by default): published at the first physics step at or after '
    'each multiple of its period, at most once a step (a rate at or above physics_rate_hz: '
    'every step); the true tool poses and joint states go out in one /ibvs/tool_path and one '
    '/ibvs/joint_path just before each. The lockstep goes by message stamps, not by /clock, '
    'so the rate changes no result, only the cost: each /clock wakes every node',
    'Hz', low=0.0, high=10000.0, low_open=True)

MIN_JOINT_STATE_SUBSCRIBERS = Param(
    'min_joint_state_subscribers', 1, 'the start waits until /joint_states has this many '
    'subscribers (every node that must see step 0)', '-', low=1, high=1000)
MIN_CAMERA_INFO_SUBSCRIBERS = Param(
    'min_camera_info_subscribers', 0, 'with publish_images, the start waits until each '
    'camera_info topic has this many subscribers (every node that builds its camera model '
    'from the first frame: a CameraInfo published before its reader is matched is lost)',
    '-', low=0, high=1000)
MIN_FRAME_JOINT_STATE_SUBSCRIBERS = Param(
    'min_frame_joint_state_subscribers', 0, 'the start waits until /stereo/joint_states has '
    'this many subscribers (the nodes that take the joint state of each frame from it)', '-',
    low=0, high=1000)
MIN_TOOL_PATH_SUBSCRIBERS = Param(
    'min_tool_path_subscribers', 0, 'the start waits until /ibvs/tool_path has this many '
    'subscribers (a recorder whose metrics start at step 0)', '-', low=0, high=1000)
MIN_JOINT_PATH_SUBSCRIBERS = Param(
    'min_joint_path_subscribers', 0, 'the start waits until /ibvs/joint_path has this many '
    'subscribers (a recorder whose joint series start at step 0)', '-', low=0, high=1000)

REAL_TIME_FACTOR = Param(
    'real_time_factor', 0.05, 'free-running (lockstep false): sim seconds per wall second '
    "(Gazebo's real_time_factor); 0.05 leaves margin on a loaded 2-core machine, where one "
    'HD720 stereo pair takes about 80 ms to render (0.1 was held at 0.05-0.09 with three '
    'other test suites running); when it cannot be held the node says so',
    '-', low=0.0, high=10.0, low_open=True)
COMMAND_TIMEOUT_S = Param(
    'command_timeout_s', 0.1, 'free-running: a position reference older than this (sim '
    'time) is stale: the drive stops and holds the arm', 's', low=0.0, high=10.0, low_open=True)
DRIVE_BANDWIDTH_HZ = Param(
    'drive_bandwidth_hz', EGM_BANDWIDTH_HZ, "position drive model: bandwidth of the drive's "
    'position loop (ibvs_model.drive: EGM)', 'Hz', low=0.0, high=80.0, low_open=True)
DRIVE_DELAY_S = Param(
    'drive_delay_s', EGM_DELAY_S, 'position drive model: dead time from a reference to the '
    'motion (ibvs_model.drive: EGM, about 20 ms)', 's', low=0.0, high=0.5)
DURATION_S = Param(
    'duration_s', 0.0, 'sim time at which the simulator stops stepping, for nodes started '
    'by hand (0: never): it publishes the last batches and /clock, logs that it stopped and '
    'goes on spinning until stopped; ibvs run stops the graph itself (--duration) and does '
    'not pass it', 's', low=0.0, high=1e6)


@dataclass(frozen=True)
class NameList(Param):
    """A Param whose value is a list of strings, empty by default (YAML's [] reads as None)."""

    def _strings(self):
        return True

    def check(self, value: Any) -> Any:
        """Return ``value`` as a list of strings, else raise ParameterError naming it."""
        return super().check([] if value is None else value)


#: abb_ros2's controller manager: ``update_rate: 250`` (PickNikRobotics/abb_ros2, main,
#: abb_bringup/config/abb_controllers.yaml L3), at which joint_state_broadcaster publishes.
ABB_UPDATE_RATE_HZ = 250.0
JOINT_STATE_RATE_HZ = Param(
    'joint_state_rate_hz', ABB_UPDATE_RATE_HZ, 'free-running: rate of /joint_states, as '
    "ros2_controllers' joint_state_broadcaster publishes them at the controller manager's "
    "update rate (abb_ros2: 250 Hz), each stamped with its update's time: published at the "
    'first physics step at or after each joint_state_phase_s + m / rate, at most once a '
    'step; lockstep publishes every physics step (this is then ignored, with a warning when '
    'set)', 'Hz', low=0.0, high=10000.0, low_open=True)
JOINT_STATE_PHASE_S = Param(
    'joint_state_phase_s', 0.001, "free-running: sim time of the controller manager's first "
    "update (its cycle runs on its own, not aligned with the camera's frames, which start "
    'at 0): with 250 Hz, 30 Hz frames and 1 kHz physics, frame stamps fall 0, 2 or 3 ms past '
    'a multiple of 4 ms and the joint states 1 ms past, so every frame is paired by '
    'interpolation between two of them', 's', low=0.0, high=1.0)
EXTRA_JOINTS = NameList(
    'extra_joints', [], "names of joints that are not the arm's (a track, a positioner) "
    "added to every /joint_states with position 0 (velocity and effort 0 where the arm's "
    'are given), as a joint_state_broadcaster publishes every joint of the controller '
    "manager: every node must take the arm's six by name and ignore them; none of "
    'joint_1 ... joint_6, each once', '-')
CAMERA_OUTAGE_S = Param(
    'camera_outage_s', [0.0, 0.0], 'free-running test hook: [start, duration] in sim time '
    'of a span in which the camera publishes nothing (no images, no camera_info, no '
    '/stereo/frame_lost): the frames exposed in [start, start + duration) are not taken; '
    'duration 0: none (refused in lockstep, where the graph would wait for ever)', 's',
    low=0.0, high=1e6, length=2)

CAMERA_TOPICS = Param(
    'camera_topics', 'ibvs', "names and format of the stereo pair: 'ibvs' (/stereo/*/image_raw "
    "in rgb8, this project's contract) or 'zed_wrapper' (what zed-ros2-wrapper 5.4 publishes "
    'for a camera named zed: /zed/zed_node/{left,right}/color/rect/image in bgra8 with '
    'their camera_info and frame ids, QoS depth 10)', '-', choices=('ibvs', 'zed_wrapper'))

#: The simulator's own (:class:`.config.SimConfig`), then the node's.
PARAMS = SimConfig.params() + (
    PUBLISH_IMAGES, CLOCK_RATE_HZ,
    MIN_JOINT_STATE_SUBSCRIBERS, MIN_FRAME_JOINT_STATE_SUBSCRIBERS, MIN_TOOL_PATH_SUBSCRIBERS,
    MIN_JOINT_PATH_SUBSCRIBERS, MIN_CAMERA_INFO_SUBSCRIBERS,
    TARGET_FEATURES_SOURCE, TARGET_POSITION, TARGET_ROTATION,
    LOCKSTEP, COMMAND_INTERFACE, POSITION_COMMAND_TYPE, COMMAND_RATE_HZ, JOINTS,
    REAL_TIME_FACTOR, COMMAND_TIMEOUT_S, DRIVE_BANDWIDTH_HZ, DRIVE_DELAY_S, CAMERA_TOPICS,
    DURATION_S, FEEDBACK_LATENCY_S, JOINT_STATE_RATE_HZ, JOINT_STATE_PHASE_S, EXTRA_JOINTS,
    CAMERA_OUTAGE_S, MAX_JOINT_SPEED_DEG_S)
#: Rules between parameters, run at start and by ``ibvs run`` before any node starts.
RULES = (check_command_interface,)
#: The parameters that only free-running uses: lockstep warns when one is not its default.
FREE_RUNNING_ONLY = (REAL_TIME_FACTOR, COMMAND_TIMEOUT_S, DRIVE_BANDWIDTH_HZ, DRIVE_DELAY_S,
                     JOINT_STATE_RATE_HZ, JOINT_STATE_PHASE_S, MAX_JOINT_SPEED_DEG_S)

#: camera_topics -> (image topics, camera_info topics, frame ids, encoding, QoS).
CAMERA_OUTPUTS = {
    'ibvs': ((contract.LEFT_IMAGE, contract.RIGHT_IMAGE),
             (contract.LEFT_INFO, contract.RIGHT_INFO),
             (contract.LEFT_CAMERA_FRAME, contract.RIGHT_CAMERA_FRAME), 'rgb8',
             contract.IMAGES),
    'zed_wrapper': ((contract.ZED_LEFT_IMAGE, contract.ZED_RIGHT_IMAGE),
                    (contract.ZED_LEFT_INFO, contract.ZED_RIGHT_INFO),
                    (contract.ZED_LEFT_FRAME, contract.ZED_RIGHT_FRAME),
                    contract.ZED_ENCODING, contract.ZED_IMAGES),
}
#: Free-running: the longest the stepping timer waits (wall s), and the most physics steps
#: one of its calls takes before it lets the executor run other callbacks.
FREE_RUN_TICK_S = 0.005
MAX_STEPS_PER_TICK = 20
#: Free-running: the wall-clock window over which the real-time factor held is measured,
#: and the share of the set factor below which the node reports that it falls behind.
RTF_WINDOW_S = 2.0
RTF_TOLERANCE = 0.9
#: Free-running: the wall-clock window of the factor held while servoing (from the first
#: position reference): its minimum over these windows and its mean over all of them.
SERVO_RTF_WINDOW_S = 1.0

#: Largest |effort| of a command, in multiples of its joint's rated torque
#: (ibvs_model.mass_model.joint_efforts). Not the rating itself: the paper's ideal actuators
#: command thousands of times it while the feedforward starts (scenario 1: 4.6e7 N m on
#: joint 1, 6e3 times its rating, in the first steps), and the 'limited' actuators clip to it
#: in the controller. Beyond this bound a command is absurd and would only break the physics.
EFFORT_BOUND_FACTOR = 1e6

#: Steady-clock period of the readiness poll before the start.
START_POLL_S = 0.02


class SimNode(Node):
    """PyBullet IRB 4600 and ZED 2, in lockstep with the controllers (module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare and check the parameters, build the simulator and the interfaces."""
        super().__init__('sim_node', **kwargs)
        self.sim = None
        #: The (stamp ns, true q) and the /joint_states of the steps since the last batch.
        self._tool_poses, self._joint_states = [], []
        try:
            self._setup()
        except BaseException:
            # No half-built node for the garbage collector: main() cannot destroy it.
            self.destroy_node()
            raise

    def _setup(self):
        values = declare(self, PARAMS, RULES)
        self._lockstep = values['lockstep']
        self._position = values['command_interface'] == 'position'
        self._publish_images = values['publish_images']
        self._min_joint_subscribers = values['min_joint_state_subscribers']
        self._min_frame_joint_subscribers = values['min_frame_joint_state_subscribers']
        self._min_tool_subscribers = values['min_tool_path_subscribers']
        self._min_joint_path_subscribers = values['min_joint_path_subscribers']
        self._min_info_subscribers = values['min_camera_info_subscribers']
        self._duration_ns = int(round(values['duration_s'] * 1e9))
        self.finished = False
        self._check_mode(values)
        self._feedback_latency_ns = seconds_to_ns(values['feedback_latency_s'])
        self._joint_state_period_ns = period_ns(values['joint_state_rate_hz'])
        self._next_joint_state_ns = seconds_to_ns(values['joint_state_phase_s'])
        self._extra_joints = list(values['extra_joints'])
        start_s, span_s = values['camera_outage_s']
        self._outage = (seconds_to_ns(start_s), seconds_to_ns(start_s + span_s)) \
            if span_s > 0.0 else None
        #: Free-running: the frames rendered and not yet delivered, (due ns, stamp ns,
        #: images or None when lost), in order (feedback_latency_s after their exposure).
        self._deliveries = []
        self.frames_published = 0
        self.frames_outage = 0
        clock_rate_hz = values['clock_rate_hz']
        if not self._lockstep and clock_rate_hz < values['command_rate_hz']:
            # A sim-time timer fires only when /clock moves: the command timer needs it.
            clock_rate_hz = values['command_rate_hz']
        self._clock_period_ns = period_ns(clock_rate_hz)
        self._next_clock_ns = 0
        self.last_clock_ns = None
        teach = values['target_features_source'] == 'taught'
        if teach and not self._publish_images:
            raise ParameterError("parameter 'target_features_source' = 'taught' is invalid: "
                                 'it needs publish_images true; allowed: model')
        teach_pose = target_from_parameters(values) if teach else None
        config = SimConfig.from_values(values)
        # Physics only (publish_images false): no renderer to load.
        self.sim = Simulator(config, teach_pose=teach_pose, render=self._publish_images)
        log = self.get_logger()
        pos_err, rot_err = self.sim.start_residual
        log.info(f'scenario {self.sim.scenario}: true start angles '
                 f'{np.round(np.degrees(self.sim.q_start), 3).tolist()} deg (IK residual '
                 f'{pos_err:.2e} m, {rot_err:.2e} rad); d_q '
                 f'{np.round(np.degrees(self.sim.d_q), 3).tolist()} deg; renderer '
                 f'{self.sim.world.renderer or "off"}; '
                 f'{"exact" if self.sim.frames_exact else "nearest-step"} frame times')

        self.diagnostics = Diagnostics(self, 'simulator')
        self.diagnostics.update(step=0, sim_time_s=0.0, waiting_for_ns=-1, frames=0,
                                frames_lost=0, held_steps=0, start_residual_m=pos_err)
        device = self.sim.world.render_device
        if device is not None:  # what draws the images: reported in the run's metrics
            self.diagnostics.update(render_device=device.gl_renderer,
                                    render_hardware=device.hardware)
        self._pub_clock = publisher(self, ClockMsg, contract.CLOCK, contract.RELIABLE)
        self._pub_joints = publisher(self, JointState, contract.JOINT_STATES, contract.RELIABLE)
        self._pub_frame_joints = publisher(self, JointState, contract.FRAME_JOINT_STATES,
                                           contract.RELIABLE)
        self._pub_tool = publisher(self, Path, contract.TOOL_PATH, contract.RELIABLE)
        self._pub_joint_path = publisher(self, JointTrajectory, contract.JOINT_PATH,
                                         contract.RELIABLE)
        self._pub_images = self._pub_infos = ()
        image_topics, info_topics, self._camera_frames, self._encoding, qos = \
            CAMERA_OUTPUTS[values['camera_topics']]
        if self._publish_images:
            self._pub_images = tuple(publisher(self, Image, topic, qos) for topic in image_topics)
            self._pub_infos = tuple(publisher(self, CameraInfo, topic, qos)
                                    for topic in info_topics)
        self._pub_lost = publisher(self, Header, contract.FRAME_LOST, contract.RELIABLE)
        # The controllers get the calibrated camera; the images show the true one.
        pose_pub = publisher(self, PoseStamped, contract.STEREO_POSE, contract.LATCHED)
        pose_pub.publish(pose_stamped(self.sim.calibrated_camera.pose_C_O, 0))
        self._pose_pub = pose_pub
        self._teach_pubs = ()
        if self.sim.teach_images is not None:
            self._teach_pubs = tuple(
                publisher(self, Image, topic, contract.LATCHED)
                for topic in (contract.TEACH_LEFT_IMAGE, contract.TEACH_RIGHT_IMAGE))
            for pub, image, frame in zip(self._teach_pubs, self.sim.teach_images,
                                         (contract.LEFT_CAMERA_FRAME,
                                          contract.RIGHT_CAMERA_FRAME)):
                pub.publish(image_msg(image, 0, 'rgb8', frame))
        if self._position:
            self._setup_position(values)
        else:
            limit = EFFORT_BOUND_FACTOR * np.asarray(joint_efforts(self.sim.params),
                                                     dtype=float)
            self._effort_bound = (-limit, limit)
            self._sub = subscription(self, JointState, contract.EFFORT_COMMANDS,
                                     self._on_command, contract.RELIABLE)

        self.started = False
        self._frame_step = False
        self._published_at = None
        self.frames = 0
        self.held_steps = 0
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._start_timer = self.create_timer(START_POLL_S, self._try_start,
                                              clock=self._steady)
        self.waiting = WaitReporter(self, self._waiting)
        self._progress_mark = None
        self.diagnostics.log_progress(self._progress)

    def _check_mode(self, values):
        """Refuse what the time mode cannot do, warn about what it ignores (module docs)."""
        extra = values['extra_joints']
        bad = [n for n in extra if not n or n in contract.JOINT_NAMES]
        if bad or len(set(extra)) != len(extra):
            raise ParameterError(f"parameter 'extra_joints' = {extra!r} is invalid: each name "
                                 f'once, not empty and none of {list(contract.JOINT_NAMES)}')
        log = self.get_logger()
        if self._lockstep:
            if values['camera_outage_s'][1] > 0.0:
                raise ParameterError(
                    f"parameter 'camera_outage_s' = {values['camera_outage_s']!r} is invalid "
                    'in lockstep: the joint controller waits for every frame, so the run '
                    'would stop; allowed: a duration of 0 (or lockstep false)')
            for spec in FREE_RUNNING_ONLY:
                if values[spec.name] != spec.default:
                    log.warn(f"parameter '{spec.name}' = {values[spec.name]!r} is ignored in "
                             'lockstep (it applies to free-running, lockstep false)')
        elif values['min_frame_joint_state_subscribers'] > 0:
            log.warn("parameter 'min_frame_joint_state_subscribers' = "
                     f"{values['min_frame_joint_state_subscribers']} is ignored free-running: "
                     f'no {contract.FRAME_JOINT_STATES} (a real cell has none)')

    def _setup_position(self, values):
        """Create the position drive and its command subscription (module docstring)."""
        self._joints = list(values['joints'])
        if sorted(self._joints) != sorted(contract.JOINT_NAMES) or \
                len(set(self._joints)) != 6:
            raise ParameterError(f"parameter 'joints' = {self._joints!r} is invalid: it must "
                                 f'name each of {list(contract.JOINT_NAMES)} exactly once')
        # Command value i is joint self._joints[i]; _to_contract reorders to joint_1..6.
        self._to_contract = np.array([self._joints.index(n) for n in contract.JOINT_NAMES])
        try:
            # EGM's speed setting (the RAPID's \MaxSpeedDeviation) caps the drive as the
            # joint controller's shaper is capped: max_joint_speed_deg_s, both.
            self.servo = PositionServo(
                self.sim.dt_ns * 1e-9, self.sim.q_start,
                bandwidth_hz=values['drive_bandwidth_hz'], delay_s=values['drive_delay_s'],
                speed_limits=np.minimum(SPEED_LIMITS,
                                        np.radians(values['max_joint_speed_deg_s'])))
        except ValueError as exc:
            raise ParameterError(f"parameter 'drive_bandwidth_hz' = "
                                 f"{values['drive_bandwidth_hz']!r} is invalid: {exc}") from None
        self._command_timeout_ns = int(round(values['command_timeout_s'] * 1e9))
        self._rtf = values['real_time_factor']
        self._command_ns = None
        self._stale = False
        self._servo_start = self._servo_window = self._servo_min = None
        self._servo_windows = 0
        self.commands = 0
        # joint_trajectory: the trajectory controller, updated at command_rate_hz (abb_ros2's
        # controller manager: 250 Hz), samples each trajectory window for the drive.
        self._follower = None
        if values['position_command_type'] == 'joint_trajectory':
            self._follower = TrajectoryFollower(values['command_rate_hz'])
        if values['position_command_type'] == 'forward_command':
            self._sub = subscription(self, Float64MultiArray, contract.POSITION_COMMANDS,
                                     self._on_position_command, contract.RELIABLE)
        else:
            self._sub = subscription(self, JointTrajectory, contract.TRAJECTORY_COMMANDS,
                                     self._on_trajectory_command, contract.RELIABLE)
        self.diagnostics.update(command='none yet', commands=0, real_time_factor=self._rtf)
        self._run_timer = None

    def destroy_node(self) -> None:
        """Publish the last batches (the end of a run), release PyBullet with the node."""
        if self.context.ok():
            self._publish_tool_path()
            self._publish_joint_path()
        if self.sim is not None:
            self.sim.close()
        return super().destroy_node()

    def _missing(self):
        """Return what the start still waits for (empty when it can start)."""
        missing = []
        if self._sub.get_publisher_count() < 1:
            missing.append(f'a publisher on {self._sub.topic_name}')
        frame_joints = self._min_frame_joint_subscribers if self._lockstep else 0
        for pub, wanted in ((self._pub_joints, self._min_joint_subscribers),
                            (self._pub_frame_joints, frame_joints),
                            (self._pub_tool, self._min_tool_subscribers),
                            (self._pub_joint_path, self._min_joint_path_subscribers)):
            have = pub.get_subscription_count()
            if have < wanted:
                missing.append(f'{wanted - have} more subscriber(s) on {pub.topic_name}')
        for pub in self._pub_images:
            if pub.get_subscription_count() < 1:
                missing.append(f'a subscriber on {pub.topic_name}')
        for pub in self._pub_infos:
            have = pub.get_subscription_count()
            if have < self._min_info_subscribers:
                missing.append(f'{self._min_info_subscribers - have} more subscriber(s) on '
                               f'{pub.topic_name}')
        return missing

    def _try_start(self):
        if self.started or self._missing():
            return
        self.started = True
        self._start_timer.cancel()
        self.get_logger().info('starting at t = 0: publishing step 0')
        self._progress_mark = (time.monotonic(), self.sim.t_ns)
        self._publish_step()
        if not self._lockstep:
            outage = '' if self._outage is None else (
                f', camera out over [{self._outage[0]}, {self._outage[1]}) ns')
            self.get_logger().info(
                f'free-running at real_time_factor {self._rtf:g}, /clock every '
                f'{self._clock_period_ns} ns, commands stale after '
                f'{self._command_timeout_ns} ns, /joint_states every '
                f'{self._joint_state_period_ns} ns from {self._next_joint_state_ns} ns, frames '
                f'delivered {self._feedback_latency_ns} ns after exposure{outage}')
            self._anchor = (time.monotonic(), self.sim.t_ns)
            self._window = (time.monotonic(), self.sim.t_ns)
            self._run_timer = self.create_timer(
                min(FREE_RUN_TICK_S, self.sim.dt_ns * 1e-9 / self._rtf), self._run,
                clock=self._steady)

    def _progress(self):
        """Return the progress line: sim time, real-time factor since the last, frames."""
        if self._progress_mark is None:
            return None
        now, t_ns = time.monotonic(), self.sim.t_ns
        wall0, t0_ns = self._progress_mark
        self._progress_mark = (now, t_ns)
        rtf = (t_ns - t0_ns) * 1e-9 / max(now - wall0, 1e-9)
        end = f' of {self._duration_ns * 1e-9:g} s' if self._duration_ns else ''
        state = 'stopped at duration_s' if self.finished else f'real-time factor {rtf:.3f}'
        return (f't = {t_ns * 1e-9:.3f} s{end} (step {self.sim.k}), {state}, '
                f'{self.frames} frames ({self.sim.frames_lost} lost)')

    def _finish(self):
        """Stop stepping at duration_s: the last batches and /clock out, then say so."""
        self.finished = True
        if getattr(self, '_run_timer', None) is not None:  # free-running
            self._run_timer.cancel()
        t_ns = self.sim.t_ns
        self._publish_tool_path()
        self._publish_joint_path()
        self._pub_clock.publish(ClockMsg(clock=ns_stamp(t_ns)))
        self.last_clock_ns = t_ns
        self.diagnostics.update(step=self.sim.k, sim_time_s=t_ns * 1e-9, waiting_for_ns=-1,
                                finished=True)
        self.get_logger().info(
            f'stopped at t = {t_ns * 1e-9:.3f} s (duration_s {self._duration_ns * 1e-9:g}): '
            'no further step; the nodes stay up until stopped (SIGINT: Ctrl-C, or '
            'ibvs_nodes_stop of docs/running.md)')

    def _waiting(self):
        """Return the wait reporter's line: the start, a first reference or a stamp."""
        if self.finished:
            return None
        if not self.started:
            return 'waiting to start for ' + ', '.join(self._missing())
        if not self._lockstep:
            if self._command_ns is not None:
                return None
            return (f'no position reference yet on {self._sub.topic_name}: holding the arm at '
                    f'its start (t = {self.sim.t_ns * 1e-9:.3f} s)')
        return (f'waiting for {contract.EFFORT_COMMANDS} stamped {self.sim.t_ns} ns '
                f'(t = {self.sim.t_ns * 1e-9:.6f} s, step {self.sim.k})')

    def _publish_step(self):
        """Publish the outputs of the current step (module docstring, in this order)."""
        sim = self.sim
        t_ns = sim.t_ns
        timing = self.diagnostics.timing
        clock_due = t_ns >= self._next_clock_ns
        state = sim.true_state()
        with timing.section('tool_path'):
            if clock_due:
                self._publish_tool_path()
            self._tool_poses.append((t_ns, state[0]))  # T_E^O in a batch, at publication
        self._frame_step = sim.frame_due() is not None
        with timing.section('step_messages'):
            if clock_due:
                self._publish_joint_path()
                self._pub_clock.publish(ClockMsg(clock=ns_stamp(t_ns)))
                self.last_clock_ns = t_ns
                self._next_clock_ns = (t_ns // self._clock_period_ns + 1) * self._clock_period_ns
            q, qd = sim.encoders(state)
            joints = joint_state(t_ns, q, qd, sim.last_torque)
            if self._lockstep:
                self._pub_joints.publish(self._with_extra_joints(joints))
                self._published_at = time.perf_counter()
            elif t_ns >= self._next_joint_state_ns:
                # joint_state_broadcaster's cycle: joint_state_rate_hz from its own phase.
                self._pub_joints.publish(self._with_extra_joints(joints))
                self._next_joint_state_ns += self._joint_state_period_ns * (
                    (t_ns - self._next_joint_state_ns) // self._joint_state_period_ns + 1)
            self._joint_states.append(joints)
            if self._frame_step and self._lockstep:
                self._pub_frame_joints.publish(joints)
        if self._frame_step:
            if self._outage is not None and self._outage[0] <= t_ns < self._outage[1]:
                sim.skip_frame()  # camera_outage_s: the camera is gone, it says nothing
                self.frames_outage += 1
            else:
                with timing.section('render'):
                    stamp, images, lost = sim.take_frame(render=self._publish_images)
                self.frames += 1
                self._deliveries.append((stamp + (0 if self._lockstep
                                                  else self._feedback_latency_ns),
                                         stamp, None if lost else images, lost))
        while self._deliveries and self._deliveries[0][0] <= t_ns:
            self._deliver(*self._deliveries.pop(0)[1:])
        timing.reached(t_ns)
        self.diagnostics.update(step=sim.k, sim_time_s=t_ns * 1e-9, waiting_for_ns=t_ns,
                                frames=self.frames, frames_lost=sim.frames_lost,
                                held_steps=self.held_steps)

    def _with_extra_joints(self, joints):
        """Return ``joints`` with the extra_joints at 0 (a new message), or itself."""
        if not self._extra_joints:
            return joints
        msg = JointState(header=joints.header, name=list(joints.name) + self._extra_joints)
        zeros = [0.0] * len(self._extra_joints)
        msg.position = list(joints.position) + zeros
        msg.velocity = list(joints.velocity) + zeros if len(joints.velocity) else []
        msg.effort = list(joints.effort) + zeros if len(joints.effort) else []
        return msg

    def _deliver(self, stamp, images, lost):
        """Publish a frame stamped with its exposure: its images and CameraInfo, or lost."""
        if lost:
            self._pub_lost.publish(Header(stamp=ns_stamp(stamp),
                                          frame_id=contract.CAMERA_FRAME))
        elif images is not None:
            with self.diagnostics.timing.section('image_messages'):
                frames = self._camera_frames
                infos = camera_infos(self.sim.calibrated_camera.intrinsics, stamp, frames)
                for pub, info_pub, image, info, frame in zip(
                        self._pub_images, self._pub_infos, images, infos, frames):
                    pub.publish(image_msg(image, stamp, self._encoding, frame))
                    info_pub.publish(info)
            self.frames_published += 1
            self.diagnostics.update(frames_published=self.frames_published,
                                    frames_outage=self.frames_outage)

    def _publish_tool_path(self):
        """Publish the true tool poses of the steps since the last batch, if any."""
        if self._tool_poses:
            stamps, qs = zip(*self._tool_poses)
            self._pub_tool.publish(path_msg(list(zip(stamps, self.sim.tool_poses(qs)))))
            self._tool_poses = []

    def _publish_joint_path(self):
        """Publish the /joint_states of the steps since the last batch, if any."""
        if self._joint_states:
            self._pub_joint_path.publish(joint_path(self._joint_states))
            self._joint_states = []

    def _on_command(self, msg):
        """Apply the effort command stamped t_k: one physics step, then publish step k + 1."""
        source = contract.EFFORT_COMMANDS
        if not self.started:
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
        self.waiting.progress()
        if self._duration_ns and self.sim.t_ns >= self._duration_ns:
            self._finish()
            return
        self._publish_step()

    # -- free-running, position drive ----------------------------------------------------
    def _run(self):
        """Advance the physics to where real_time_factor puts sim time now (module docs)."""
        wall0, sim0 = self._anchor
        now = time.monotonic()
        due_ns = sim0 + int((now - wall0) * self._rtf * 1e9)
        steps = 0
        while self.sim.t_ns + self.sim.dt_ns <= due_ns and steps < MAX_STEPS_PER_TICK:
            self._free_step()
            steps += 1
            if self.finished:
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
                self.get_logger().warn(message)
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
            self.get_logger().warn(message)
            self.diagnostics.set_level(DiagnosticStatus.WARN, message)
            self.diagnostics.update(command='stale')
        if self._follower is not None and not self._stale and self._follower.due(sim.t_ns):
            reference = self._follower.update(sim.t_ns, self.servo.q - sim.d_q)
            if reference is not None:
                self.servo.command(reference + sim.d_q)
        with self.diagnostics.timing.section('physics'):
            q, qd = self.servo.step()
            sim.move_to(q, qd)
        if self._duration_ns and sim.t_ns >= self._duration_ns:
            self._finish()
            return
        self._publish_step()

    def _beyond_range(self, q_encoder):
        """Return, per row of encoder angles, whether a true angle (+ d_q) leaves its range."""
        q_true = np.atleast_2d(q_encoder) + self.sim.d_q
        return np.any((q_true < np.asarray(IRB4600.q_min))
                      | (q_true > np.asarray(IRB4600.q_max)), axis=1)

    def _take_reference(self, q_encoder, source, checked=False, trajectory=None):
        """
        Take a reference in encoder angles (contract order): range check, then the drive.

        ``trajectory`` (stamp ns, times ns, positions): a checked joint_trajectory command,
        for the trajectory controller (:class:`.position_servo.TrajectoryFollower`).
        """
        if not checked and self._beyond_range(q_encoder)[0]:
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
            self.get_logger().info('position references again: tracking')
            self.diagnostics.set_level(DiagnosticStatus.OK, 'ok')
        self.diagnostics.update(command='tracking', commands=self.commands)

    def _on_position_command(self, msg):
        """Take a forward_command_controller command: values in the order of ``joints``."""
        source = self._sub.topic_name
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
        (:func:`ibvs_common.conversions.read_command_trajectory`, which cites its source:
        names, empty, times not strictly increasing or negative, a non-zero stamp whose end
        is more than ``command_timeout_s`` in the past, a stamp more than that ahead, wrong
        lengths, non-finite values), and for a point anywhere outside a joint's range.
        """
        source = self._sub.topic_name
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
        self._take_reference(positions[-1], source, checked=True, trajectory=(
            stamp_ns(msg.header.stamp), [duration_ns(p.time_from_start) for p in msg.points],
            positions))


def main(args: list[str] | None = None) -> None:
    """Run the simulator node (``ros2 run ibvs_sim sim_node``)."""
    run(SimNode, args=args, name='sim_node')


if __name__ == '__main__':
    main()
