"""
sim_node: the simulated plant (paper Figure 3) on the contract of docs/design.md §3 and §4.

Lockstep. At step k (sim time t_k, from 0) the node publishes, in this order: when /clock is
due (``clock_rate_hz``, 10 Hz: the first step at or after each multiple of its period; sim
time for the nodes' clocks, at gazebo_ros's default rate; no result depends on it), first
/ibvs/tool_path with the true flange poses of the steps since the last one, then /clock,
so that when /clock says T every tool pose stamped before T is out; /joint_states (encoder
angles q - d_q, velocities, the torque of the previous step); on a camera frame's
step, the same joint state on /stereo/joint_states, then the frame (both images and
CameraInfo, stamped t_k), which it renders while the joint controller works on step k.
Every consumer matches its inputs by stamp, so the order changes no result.
It then waits for /joint_effort_commands stamped t_k; that message (and only that one)
applies its torques for one step and moves to k + 1, inside the subscription callback:
nothing spins or sleeps, so any number of nodes can share one executor. While it waits, a
steady-clock timer logs once a second what it waits for.

Start. Step 0 is published once somebody will answer and listen: /joint_effort_commands
has a publisher, /joint_states a subscriber (and /stereo/joint_states and /ibvs/tool_path
as many as the runner says) and, with publish_images, both image topics a
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

Bad input. A command with a malformed stamp (:func:`ibvs_common.conversions.read_stamp`) is
rejected; one with another stamp is rejected as stale (older) or early (newer) and ignored.
A command with the right stamp but a wrong length, unknown joint names, NaN or inf, or an
effort beyond :data:`EFFORT_BOUND_FACTOR` times its joint's rated torque (absurd: it would
only break the physics) is rejected too; the step then happens with the holding torque
(PyBullet inverse dynamics that stops the arm where it is: Simulator.hold_torque), so the run
goes on and the arm holds its position. Each rejection is logged and counted on /diagnostics.
"""

import time

from geometry_msgs.msg import PoseStamped
from ibvs_common import contract
from ibvs_common.conversions import (camera_infos, image_msg, InputError, joint_state,
                                     ns_stamp, path_msg, pose_stamped, read_joints, read_stamp,
                                     stamp_ns)
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.node_main import run
from ibvs_common.params import declare, Param, ParameterError
from ibvs_common.shared_params import (CAMERA_RATE_HZ, DISTURBANCE_DEG, L2_SCALE, L4_SCALE,
                                       PHYSICS_RATE_HZ, SCENARIO, TARGET_FEATURES_SOURCE,
                                       target_from_parameters, TARGET_POSITION,
                                       TARGET_ROTATION)
from ibvs_common.timing import period_ns
from ibvs_model import paper
from ibvs_model.mass_model import joint_efforts
from nav_msgs.msg import Path
import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header

from .camera_effects import MAX_DROP_PROBABILITY, MAX_NOISE_STDDEV
from .simulator import ConfigError, Simulator
from .world import (DEFAULT_FOCUS_SUPERSAMPLING, DEFAULT_MOUNT_HEIGHT_M, DEFAULT_SUPERSAMPLING,
                    MAX_FOCUS_SUPERSAMPLING, MAX_MOUNT_HEIGHT_M, MAX_SUPERSAMPLING, RENDERERS)

RESOLUTION = Param('resolution', 'HD720', 'stereo image size: ZED 2 HD720 (1280 x 720) or '
                   'VGA (672 x 376)', '-', choices=('HD720', 'VGA'))
CAMERA_EYE = Param('camera_eye', [float(v) for v in paper.CAMERA_EYE],
                   'camera frame {C} origin (midway between the lenses) in {O}', 'm',
                   low=-20.0, high=20.0, length=3)
CAMERA_LOOK_AT = Param('camera_look_at', [float(v) for v in paper.CAMERA_LOOK_AT],
                       'point of {O} on the optical axis (image up = +z of {O})', 'm',
                       low=-20.0, high=20.0, length=3)
RENDERER = Param('renderer', 'auto', "PyBullet renderer: 'egl' (OpenGL without display), "
                 "'tiny' (TinyRenderer, CPU) or 'auto' (EGL where it loads)", '-',
                 choices=RENDERERS)
RENDER_SUPERSAMPLING = Param(
    'render_supersampling', DEFAULT_SUPERSAMPLING, 'samples per pixel along each axis, '
    'averaged as a camera pixel integrates light (1: one sample per pixel, cheapest; the '
    'cost grows with its square)', '-', low=1, high=MAX_SUPERSAMPLING)
RENDER_MARKER_SUPERSAMPLING = Param(
    'render_marker_supersampling', DEFAULT_FOCUS_SUPERSAMPLING, 'samples per pixel along '
    'each axis in small windows around the two markers, rendered again and pasted over the '
    'image (their centres then move with the sub-pixel position by 0.005 px rms instead of '
    '0.02-0.04 px; 1: off)', '-', low=1, high=MAX_FOCUS_SUPERSAMPLING)
MOUNT_HEIGHT_M = Param(
    'mount_height_m', DEFAULT_MOUNT_HEIGHT_M, 'height of the robot base above the floor (a '
    'riser fills it; drawn only, nothing collides): a tool below the floor is hidden from the '
    'camera; 0: robot on the floor', 'm', low=0.0, high=MAX_MOUNT_HEIGHT_M)
RENDER_PARALLEL_LENSES = Param(
    'render_parallel_lenses', True, 'render the right lens in a second process while this one '
    'renders the left (ibvs_sim.lens_worker): the same images in about half the wall time on '
    'two cores; false: both lenses in this process', '-')
PUBLISH_IMAGES = Param('publish_images', True, 'render and publish the stereo images and '
                       'CameraInfo (false: physics only, e.g. with a model-based feature '
                       'source)', '-')

CLOCK_RATE_HZ = Param(
    'clock_rate_hz', 10.0, "rate of /clock, the sim time of every node's clock (10 Hz, as "
    'gazebo_ros publishes it by default): published at the first physics step at or after '
    'each multiple of its period, at most once a step (a rate at or above physics_rate_hz: '
    'every step); the true tool poses go out in one /ibvs/tool_path just before each. The '
    'lockstep goes by message stamps, not by /clock, so the rate changes no result, only the '
    'cost: each /clock wakes every node',
    'Hz', low=0.0, high=10000.0, low_open=True)

MIN_JOINT_STATE_SUBSCRIBERS = Param(
    'min_joint_state_subscribers', 1, 'the start waits until /joint_states has this many '
    'subscribers (a recorder that must see step 0 counts too)', '-', low=1, high=1000)
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

IMAGE_NOISE_STDDEV = Param(
    'image_noise_stddev', 0.0, 'standard deviation of the Gaussian noise added to each pixel '
    'and channel of the rendered images, intensity in [0, 1] (Gazebo camera noise); the sum '
    'is clipped and rounded to 8 bits; 0: off', '-', low=0.0, high=MAX_NOISE_STDDEV)
FRAME_DROP_PROBABILITY = Param(
    'frame_drop_probability', 0.0, 'probability that a stereo frame is lost (both images), '
    'each frame drawn on its own; 0: off', '-', low=0.0, high=MAX_DROP_PROBABILITY)
CAMERA_SEED = Param('camera_seed', 0, 'seed of the Generator that draws image noise and '
                    'frame drops', '-', low=0, high=2 ** 31 - 1)
CAMERA_POSE_ERROR_XYZ_M = Param(
    'camera_pose_error_xyz_m', [0.0, 0.0, 0.0], 'calibration error of the camera position: '
    'the published /stereo/pose is the true one moved by this along the true camera axes '
    '(x right, y down, z forward)', 'm', low=-0.5, high=0.5, length=3)
CAMERA_POSE_ERROR_RPY_DEG = Param(
    'camera_pose_error_rpy_deg', [0.0, 0.0, 0.0], 'calibration error of the camera '
    'orientation: the published /stereo/pose is the true one turned by roll, pitch, yaw '
    'about the true camera axes x, y, z (R = Rz Ry Rx)', 'deg', low=-10.0, high=10.0,
    length=3)
FOCAL_LENGTH_ERROR = Param(
    'focal_length_error', 1.0, 'factor on f_u and f_v of the published camera_info (the '
    'images are rendered with the true ones); 1: exact', '-', low=0.5, high=2.0)

#: The parameters that go to :class:`.simulator.Simulator` as they are, under their names.
SIMULATOR_PARAMS = (SCENARIO, DISTURBANCE_DEG, PHYSICS_RATE_HZ, CAMERA_RATE_HZ, RESOLUTION,
                    CAMERA_EYE, CAMERA_LOOK_AT, L2_SCALE, L4_SCALE, RENDER_SUPERSAMPLING,
                    RENDER_MARKER_SUPERSAMPLING, MOUNT_HEIGHT_M, IMAGE_NOISE_STDDEV,
                    FRAME_DROP_PROBABILITY, CAMERA_SEED, CAMERA_POSE_ERROR_XYZ_M,
                    CAMERA_POSE_ERROR_RPY_DEG, FOCAL_LENGTH_ERROR)
PARAMS = SIMULATOR_PARAMS + (
    RENDERER, RENDER_PARALLEL_LENSES, PUBLISH_IMAGES, CLOCK_RATE_HZ,
    MIN_JOINT_STATE_SUBSCRIBERS, MIN_FRAME_JOINT_STATE_SUBSCRIBERS, MIN_TOOL_PATH_SUBSCRIBERS,
    MIN_CAMERA_INFO_SUBSCRIBERS,
    TARGET_FEATURES_SOURCE, TARGET_POSITION, TARGET_ROTATION)

#: Largest |effort| of a command, in multiples of its joint's rated torque
#: (ibvs_model.mass_model.joint_efforts). Not the rating itself: the paper's ideal actuators
#: command thousands of times it while the feedforward starts (scenario 1: 4.6e7 N m on
#: joint 1, 6e3 times its rating, in the first steps), and the 'limited' actuators clip to it
#: in the controller. Beyond this bound a command is absurd and would only break the physics.
EFFORT_BOUND_FACTOR = 1e6

#: Steady-clock periods: readiness poll before the start, and the waiting log.
START_POLL_S = 0.02
WAIT_LOG_S = 1.0


class SimNode(Node):
    """PyBullet IRB 4600 and ZED 2, in lockstep with the controllers (module docstring)."""

    def __init__(self, **kwargs):
        """Declare and check the parameters, build the simulator and the interfaces."""
        super().__init__('sim_node', **kwargs)
        self.sim = None
        try:
            self._setup()
        except BaseException:
            # No half-built node for the garbage collector: main() cannot destroy it.
            self.destroy_node()
            raise

    def _setup(self):
        values = declare(self, PARAMS)
        self._publish_images = values['publish_images']
        self._min_joint_subscribers = values['min_joint_state_subscribers']
        self._min_frame_joint_subscribers = values['min_frame_joint_state_subscribers']
        self._min_tool_subscribers = values['min_tool_path_subscribers']
        self._min_info_subscribers = values['min_camera_info_subscribers']
        self._clock_period_ns = period_ns(values['clock_rate_hz'])
        self._next_clock_ns = 0
        self.last_clock_ns = None
        teach = values['target_features_source'] == 'taught'
        if teach and not self._publish_images:
            raise ParameterError("parameter 'target_features_source' = 'taught' is invalid: "
                                 'it needs publish_images true; allowed: model')
        teach_pose = target_from_parameters(values) if teach else None
        try:
            self.sim = Simulator(
                renderer=values['renderer'] if self._publish_images else 'tiny',
                render_parallel_lenses=values['render_parallel_lenses'] and self._publish_images,
                teach_pose=teach_pose,
                **{spec.name: values[spec.name] for spec in SIMULATOR_PARAMS})
        except ConfigError as exc:
            raise ParameterError(str(exc)) from None
        log = self.get_logger()
        pos_err, rot_err = self.sim.start_residual
        log.info(f'scenario {self.sim.scenario}: true start angles '
                 f'{np.round(np.degrees(self.sim.q_start), 3).tolist()} deg (IK residual '
                 f'{pos_err:.2e} m, {rot_err:.2e} rad); d_q '
                 f'{np.round(np.degrees(self.sim.d_q), 3).tolist()} deg; renderer '
                 f'{self.sim.world.renderer if self._publish_images else "off"}; '
                 f'{"exact" if self.sim.frames_exact else "nearest-step"} frame times')

        self.diagnostics = Diagnostics(self, 'simulator')
        self.diagnostics.update(step=0, sim_time_s=0.0, waiting_for_ns=-1, frames=0,
                                frames_lost=0, held_steps=0, renderer=self.sim.world.renderer,
                                start_residual_m=pos_err)
        self._pub_clock = self.create_publisher(ClockMsg, contract.CLOCK, contract.RELIABLE)
        self._pub_joints = self.create_publisher(JointState, contract.JOINT_STATES,
                                                 contract.RELIABLE)
        self._pub_frame_joints = self.create_publisher(JointState, contract.FRAME_JOINT_STATES,
                                                       contract.RELIABLE)
        self._pub_tool = self.create_publisher(Path, contract.TOOL_PATH, contract.RELIABLE)
        #: The (stamp ns, T_E^O) of the steps since the last /ibvs/tool_path.
        self._tool_poses = []
        self._pub_images = self._pub_infos = ()
        if self._publish_images:
            self._pub_images = tuple(self.create_publisher(Image, topic, contract.IMAGES)
                                     for topic in (contract.LEFT_IMAGE, contract.RIGHT_IMAGE))
            self._pub_infos = tuple(self.create_publisher(CameraInfo, topic, contract.IMAGES)
                                    for topic in (contract.LEFT_INFO, contract.RIGHT_INFO))
        self._pub_lost = self.create_publisher(Header, contract.FRAME_LOST, contract.RELIABLE)
        # The controllers get the calibrated camera; the images show the true one.
        pose_pub = self.create_publisher(PoseStamped, contract.STEREO_POSE, contract.LATCHED)
        pose_pub.publish(pose_stamped(self.sim.calibrated_camera.pose_C_O, 0))
        self._pose_pub = pose_pub
        self._teach_pubs = ()
        if self.sim.teach_images is not None:
            self._teach_pubs = tuple(
                self.create_publisher(Image, topic, contract.LATCHED)
                for topic in (contract.TEACH_LEFT_IMAGE, contract.TEACH_RIGHT_IMAGE))
            for pub, image, frame in zip(self._teach_pubs, self.sim.teach_images,
                                         (contract.LEFT_CAMERA_FRAME,
                                          contract.RIGHT_CAMERA_FRAME)):
                pub.publish(image_msg(image, 0, 'rgb8', frame))
        limit = EFFORT_BOUND_FACTOR * np.asarray(joint_efforts(self.sim.params), dtype=float)
        self._effort_bound = (-limit, limit)
        self._sub = self.create_subscription(JointState, contract.EFFORT_COMMANDS,
                                             self._on_command, contract.RELIABLE)

        self.started = False
        self._frame_step = False
        self._published_at = None
        self.frames = 0
        self.held_steps = 0
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._progress_since_log = True
        self._start_timer = self.create_timer(START_POLL_S, self._try_start,
                                              clock=self._steady)
        self._wait_timer = self.create_timer(WAIT_LOG_S, self._log_waiting, clock=self._steady)

    def destroy_node(self):
        """Release PyBullet with the node."""
        if self.sim is not None:
            self.sim.close()
        return super().destroy_node()

    def _missing(self):
        """Return what the start still waits for (empty when it can start)."""
        missing = []
        if self._sub.get_publisher_count() < 1:
            missing.append(f'a publisher on {contract.EFFORT_COMMANDS}')
        for pub, wanted in ((self._pub_joints, self._min_joint_subscribers),
                            (self._pub_frame_joints, self._min_frame_joint_subscribers),
                            (self._pub_tool, self._min_tool_subscribers)):
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
        self._publish_step()

    def _log_waiting(self):
        if not self.started:
            self.get_logger().info('waiting to start for ' + ', '.join(self._missing()))
        elif not self._progress_since_log:
            self.get_logger().info(
                f'waiting for {contract.EFFORT_COMMANDS} stamped {self.sim.t_ns} ns '
                f'(t = {self.sim.t_ns * 1e-9:.6f} s, step {self.sim.k})')
        self._progress_since_log = False

    def _publish_step(self):
        """Publish the outputs of the current step (module docstring, in this order)."""
        sim = self.sim
        t_ns = sim.t_ns
        timing = self.diagnostics.timing
        clock_due = t_ns >= self._next_clock_ns
        with timing.section('tool_path'):
            if clock_due and self._tool_poses:
                self._pub_tool.publish(path_msg(self._tool_poses))
                self._tool_poses = []
            self._tool_poses.append((t_ns, sim.tool_pose()))
        self._frame_step = sim.frame_due() is not None
        with timing.section('step_messages'):
            if clock_due:
                self._pub_clock.publish(ClockMsg(clock=ns_stamp(t_ns)))
                self.last_clock_ns = t_ns
                self._next_clock_ns = (t_ns // self._clock_period_ns + 1) * self._clock_period_ns
            q, qd = sim.encoders()
            joints = joint_state(t_ns, q, qd, sim.last_torque)
            self._pub_joints.publish(joints)
            self._published_at = time.perf_counter()
            if self._frame_step:
                self._pub_frame_joints.publish(joints)
        if self._frame_step:
            with timing.section('render'):
                stamp, images, lost = sim.take_frame(render=self._publish_images)
            self.frames += 1
            if lost:
                self._pub_lost.publish(Header(stamp=ns_stamp(stamp),
                                              frame_id=contract.CAMERA_FRAME))
            elif images is not None:
                with timing.section('image_messages'):
                    frames = (contract.LEFT_CAMERA_FRAME, contract.RIGHT_CAMERA_FRAME)
                    infos = camera_infos(sim.calibrated_camera.intrinsics, stamp)
                    for pub, info_pub, image, info, frame in zip(
                            self._pub_images, self._pub_infos, images, infos, frames):
                        pub.publish(image_msg(image, stamp, 'rgb8', frame))
                        info_pub.publish(info)
        timing.reached(t_ns)
        self.diagnostics.update(step=sim.k, sim_time_s=t_ns * 1e-9, waiting_for_ns=t_ns,
                                frames=self.frames, frames_lost=sim.frames_lost,
                                held_steps=self.held_steps)

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
        self._progress_since_log = True
        self._publish_step()


def main(args=None):
    """Run the simulator node (``ros2 run ibvs_sim sim_node``)."""
    run(SimNode, args=args, name='sim_node')


if __name__ == '__main__':
    main()
