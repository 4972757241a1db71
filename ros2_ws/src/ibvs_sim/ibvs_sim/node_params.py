"""
ibvs_sim's parameters and typed configurations, no ROS.

:class:`SimConfig` is what :class:`.simulator.Simulator` simulates: each field a sim_node
parameter of the same name (:class:`ibvs_common.params.Param`: default, units, allowed
values), the timing and the plant as the shared groups (:class:`ibvs_common.shared_params.
Timing`, :class:`~ibvs_common.shared_params.Plant`); the replay builds one from recorded
values (:meth:`SimConfig.from_values`), a test directly (:meth:`SimConfig.make`).
:class:`SimNodeConfig` extends it with the node's own parameters and the target
(:class:`~ibvs_common.shared_params.Target`): each value checked against its Param at
construction, then the rules across them (a taught target against publish_images, a camera
outage against lockstep, the extra joints' names, a start at the target against
start_joints), so that a bad combination is refused before the node opens a topic.
:class:`RobotStateConfig` is robot_state_node's.
"""

from dataclasses import dataclass
from typing import Any

from ibvs_common import shared_params as shared
from ibvs_common.params import group_field, Param, param_field, ParamConfig, ParameterError
from ibvs_common.shared_params import SCENARIO, START_JOINTS
from ibvs_common.teach import TEACH_FRAMES
from ibvs_model import paper
from ibvs_model.drive import EGM_BANDWIDTH_HZ, EGM_DELAY_S

from .camera_effects import MAX_DROP_PROBABILITY, MAX_NOISE_STDDEV
from .rendering import (DEFAULT_FOCUS_SUPERSAMPLING, DEFAULT_SUPERSAMPLING,
                        MAX_FOCUS_SUPERSAMPLING, MAX_SUPERSAMPLING)

#: The robot stands on a riser (:class:`.world.World`) whose top is the base plane. The
#: paper's model has no floor; its sweep (Figure 13) needs room below the base: with L2 at
#: 50 % the tool ends 0.11 m (its lower marker 0.17 m) under z = 0.
DEFAULT_MOUNT_HEIGHT_M = 0.5
MAX_MOUNT_HEIGHT_M = 5.0

RESOLUTION = Param('resolution', 'HD720', 'stereo image size: ZED 2 HD720 (1280 x 720) or '
                   'VGA (672 x 376)', '-', choices=('HD720', 'VGA'))
PUB_DOWNSCALE_FACTOR = Param(
    'pub_downscale_factor', 1.0, 'the images and camera_info published at the resolution '
    "divided by this, as zed-ros2-wrapper's general.pub_downscale_factor does with "
    "general.pub_resolution 'CUSTOM' (the wrapper's defaults up to v5.2.2: 'CUSTOM' and 2.0, "
    'HD720 published as 640 x 360); 1: NATIVE', '-', low=1.0, high=8.0)
CAMERA_EYE = Param('camera_eye', [float(v) for v in paper.CAMERA_EYE],
                   'camera frame {C} origin (midway between the lenses) in {O}', 'm',
                   low=-20.0, high=20.0, length=3)
CAMERA_LOOK_AT = Param('camera_look_at', [float(v) for v in paper.CAMERA_LOOK_AT],
                       'point of {O} on the optical axis (image up = +z of {O})', 'm',
                       low=-20.0, high=20.0, length=3)
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


@dataclass(frozen=True)
class SimConfig(ParamConfig):
    """
    What :class:`.simulator.Simulator` simulates: the sim_node parameters of these names.

    Each value is checked against its Param at construction (ParameterError naming it),
    the camera rate against the physics rate by the timing group; what depends on the robot
    (a reachable start pose, a camera that sees the scene) the Simulator checks.
    """

    scenario: int = param_field(SCENARIO)
    start_joints: tuple[float, ...] = param_field(START_JOINTS)
    plant: shared.Plant = group_field(shared.Plant)
    timing: shared.Timing = group_field(shared.Timing)
    resolution: str = param_field(RESOLUTION)
    pub_downscale_factor: float = param_field(PUB_DOWNSCALE_FACTOR)
    camera_eye: tuple[float, float, float] = param_field(CAMERA_EYE)
    camera_look_at: tuple[float, float, float] = param_field(CAMERA_LOOK_AT)
    render_supersampling: int = param_field(RENDER_SUPERSAMPLING)
    render_marker_supersampling: int = param_field(RENDER_MARKER_SUPERSAMPLING)
    mount_height_m: float = param_field(MOUNT_HEIGHT_M)
    image_noise_stddev: float = param_field(IMAGE_NOISE_STDDEV)
    frame_drop_probability: float = param_field(FRAME_DROP_PROBABILITY)
    camera_seed: int = param_field(CAMERA_SEED)
    teach_frames: int = param_field(TEACH_FRAMES)
    camera_pose_error_xyz_m: tuple[float, float, float] = param_field(CAMERA_POSE_ERROR_XYZ_M)
    camera_pose_error_rpy_deg: tuple[float, float, float] = \
        param_field(CAMERA_POSE_ERROR_RPY_DEG)
    focal_length_error: float = param_field(FOCAL_LENGTH_ERROR)


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
    'Hz', low=shared.MIN_RATE_HZ, high=10000.0)

MIN_COMMAND_PUBLISHERS = Param(
    'min_command_publishers', 1, 'the start waits until the command topic has this many '
    'publishers (the joint controller); 0: it starts without one, the arm held where it '
    'starts (a cell with nobody commanding: ibvs teach, ibvs cell --dry-run)', '-', low=0,
    high=1000)
START_AT_TARGET = Param(
    'start_at_target', False, 'the arm starts at the target pose (target_position, '
    "target_rotation; the simulated robot's IK, as its teach pair) instead of the "
    "scenario's start: the tool held at the target, to teach it (ibvs teach)", '-')
MIN_JOINT_STATE_SUBSCRIBERS = Param(
    'min_joint_state_subscribers', 1, 'the start waits until /joint_states has this many '
    'subscribers (every node that must see step 0); 0: it starts without one, as a real '
    "cell's joint_state_broadcaster publishes to nobody", '-', low=0, high=1000)
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
    'real_time_factor', 0.05, "free-running (command_interface 'position'): sim seconds per "
    "wall second (Gazebo's real_time_factor); 0.05 leaves margin for any graph on a loaded 2-core "
    'machine (0.1 was held at 0.05-0.09 with three other test suites running); real_cell.yaml '
    'sets 0.6, what the idle machine holds at HD720 (docs/speed.md); when it cannot be held '
    'the node says so',
    '-', low=0.0, high=10.0, low_open=True)
COMMAND_TIMEOUT_S = Param(
    'command_timeout_s', 0.1, 'free-running: a position reference older than this (sim '
    'time) is stale: the drive stops and holds the arm', 's', low=0.0, high=10.0, low_open=True)
DRIVE_BANDWIDTH_HZ = Param(
    'drive_bandwidth_hz', EGM_BANDWIDTH_HZ, "position drive model: bandwidth of the drive's "
    'position loop (ibvs_model.drive: EGM)', 'Hz', low=0.0, high=80.0, low_open=True)
DRIVE_DELAY_S = Param(
    'drive_delay_s', EGM_DELAY_S, 'position drive model: dead time from a reference to the '
    'motion (ibvs_model.drive: EGM as its users measure it)', 's', low=0.0, high=0.5)
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
    'set)', 'Hz', low=shared.MIN_RATE_HZ, high=10000.0)
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

IMAGE_STAMP_OFFSET_S = Param(
    'image_stamp_offset_s', 0.0, 'free-running: every image, camera_info and '
    '/stereo/frame_lost is stamped this long after its exposure (a camera driver that stamps '
    'on receipt, as the ZED wrapper does; negative: before it); at most feedback_latency_s '
    '(no stamp after its delivery); 0 in lockstep, where stamps pair frames with their joint '
    'states', 's', low=-0.2, high=0.2)

CAMERA_TOPICS = Param(
    'camera_topics', 'ibvs', "names and format of the stereo pair: 'ibvs' (/stereo/*/image_raw "
    "in rgb8, this project's contract) or 'zed_wrapper' (what zed-ros2-wrapper 5.4 publishes "
    'for a camera named zed: /zed/zed_node/{left,right}/color/rect/image in bgra8 with '
    'their camera_info and frame ids, QoS depth 10)', '-', choices=('ibvs', 'zed_wrapper'))


@dataclass(frozen=True)
class SimNodeConfig(SimConfig):
    """The parameters of sim_node: the simulator's (:class:`SimConfig`), then its own."""

    #: Rules between parameters, run at start and by ``ibvs run`` before any node starts:
    #: none (its checks across values are its construction's, :meth:`__post_init__`).
    RULES = ()

    publish_images: bool = param_field(PUBLISH_IMAGES)
    clock_rate_hz: float = param_field(CLOCK_RATE_HZ)
    min_joint_state_subscribers: int = param_field(MIN_JOINT_STATE_SUBSCRIBERS)
    min_frame_joint_state_subscribers: int = param_field(MIN_FRAME_JOINT_STATE_SUBSCRIBERS)
    min_tool_path_subscribers: int = param_field(MIN_TOOL_PATH_SUBSCRIBERS)
    min_joint_path_subscribers: int = param_field(MIN_JOINT_PATH_SUBSCRIBERS)
    min_camera_info_subscribers: int = param_field(MIN_CAMERA_INFO_SUBSCRIBERS)
    min_command_publishers: int = param_field(MIN_COMMAND_PUBLISHERS)
    start_at_target: bool = param_field(START_AT_TARGET)
    target: shared.Target = group_field(shared.Target)
    interface: shared.Interface = group_field(shared.Interface)
    real_time_factor: float = param_field(REAL_TIME_FACTOR)
    command_timeout_s: float = param_field(COMMAND_TIMEOUT_S)
    drive_bandwidth_hz: float = param_field(DRIVE_BANDWIDTH_HZ)
    drive_delay_s: float = param_field(DRIVE_DELAY_S)
    camera_topics: str = param_field(CAMERA_TOPICS)
    duration_s: float = param_field(DURATION_S)
    joint_state_rate_hz: float = param_field(JOINT_STATE_RATE_HZ)
    joint_state_phase_s: float = param_field(JOINT_STATE_PHASE_S)
    extra_joints: tuple[str, ...] = param_field(EXTRA_JOINTS)
    camera_outage_s: tuple[float, float] = param_field(CAMERA_OUTAGE_S)
    image_stamp_offset_s: float = param_field(IMAGE_STAMP_OFFSET_S)
    max_joint_speed_deg_s: float = param_field(shared.MAX_JOINT_SPEED_DEG_S)

    def __post_init__(self):
        """Check each value, then the rules across them (module docstring)."""
        super().__post_init__()
        shared.start_joints(self.start_joints)  # 6 angles within the joints' ranges, or none
        if self.start_at_target and self.start_joints:
            raise ParameterError("parameter 'start_at_target' = True is invalid with "
                                 'start_joints set: the arm starts at one of them; allowed: '
                                 'false (or start_joints empty)')
        if self.target.taught and not self.publish_images:
            raise ParameterError("parameter 'target_features_source' = 'taught' is invalid: "
                                 'it needs publish_images true; allowed: model')
        extra = list(self.extra_joints)
        from ibvs_common import contract  # here: it imports rclpy, which the core does without
        if any(not n or n in contract.JOINT_NAMES for n in extra) or \
                len(set(extra)) != len(extra):
            raise ParameterError(f"parameter 'extra_joints' = {extra!r} is invalid: each name "
                                 f'once, not empty and none of {list(contract.JOINT_NAMES)}')
        if self.interface.lockstep and self.camera_outage_s[1] > 0.0:
            raise ParameterError(
                f"parameter 'camera_outage_s' = {list(self.camera_outage_s)!r} is invalid in "
                'lockstep: the joint controller waits for every frame, so the run would stop; '
                "allowed: a duration of 0 (or command_interface 'position')")
        if self.image_stamp_offset_s != 0.0 and self.interface.lockstep:
            raise ParameterError(
                f"parameter 'image_stamp_offset_s' = {self.image_stamp_offset_s!r} is invalid "
                "in lockstep: a frame's stamp names its joint state there; allowed: 0 (or "
                "command_interface 'position')")
        if self.image_stamp_offset_s > self.timing.feedback_latency_s:
            raise ParameterError(
                f"parameter 'image_stamp_offset_s' = {self.image_stamp_offset_s!r} is invalid "
                f'with feedback_latency_s = {self.timing.feedback_latency_s!r}: a frame cannot '
                'be stamped after it is delivered; allowed: at most feedback_latency_s')


@dataclass(frozen=True)
class RobotStateConfig(ParamConfig):
    """The parameters of robot_state_node: the simulated arm drawn and the stamp rule's."""

    plant: shared.Plant = group_field(shared.Plant)
    timing: shared.Timing = group_field(shared.Timing)
