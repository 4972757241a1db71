"""
The typed configurations of ibvs_sim's nodes (:class:`SimNodeConfig`, :class:`RobotStateConfig`).

:class:`SimNodeConfig` is :class:`.config.SimConfig` (what the simulator simulates) and the
node's own parameters below: each value checked against its Param at construction, then
the rules across them (a taught target against publish_images, a camera outage against
lockstep, the extra joints' names, a start at the target against start_joints), so that a
bad combination is refused before the node opens a topic.
"""

from dataclasses import dataclass
from typing import Any

from ibvs_common import contract
from ibvs_common import shared_params as shared
from ibvs_common.params import Param, param_field, ParamConfig, ParameterError
from ibvs_model.drive import EGM_BANDWIDTH_HZ, EGM_DELAY_S

from .config import SimConfig

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
    """The parameters of sim_node: the simulator's (:class:`.config.SimConfig`), then its own."""

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
    target_features_source: str = param_field(shared.TARGET_FEATURES_SOURCE)
    target_position: tuple[float, ...] = param_field(shared.TARGET_POSITION)
    target_rotation: tuple[float, ...] = param_field(shared.TARGET_ROTATION)
    command_interface: str = param_field(shared.COMMAND_INTERFACE)
    position_command_type: str = param_field(shared.POSITION_COMMAND_TYPE)
    command_rate_hz: float = param_field(shared.COMMAND_RATE_HZ)
    joints: tuple[str, ...] = param_field(shared.JOINTS)
    real_time_factor: float = param_field(REAL_TIME_FACTOR)
    command_timeout_s: float = param_field(COMMAND_TIMEOUT_S)
    drive_bandwidth_hz: float = param_field(DRIVE_BANDWIDTH_HZ)
    drive_delay_s: float = param_field(DRIVE_DELAY_S)
    camera_topics: str = param_field(CAMERA_TOPICS)
    duration_s: float = param_field(DURATION_S)
    feedback_latency_s: float = param_field(shared.FEEDBACK_LATENCY_S)
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
        if not self.lockstep:  # the free-running drive's joint order
            shared.joint_order(self.joints)
        if self.target_features_source == 'taught' and not self.publish_images:
            raise ParameterError("parameter 'target_features_source' = 'taught' is invalid: "
                                 'it needs publish_images true; allowed: model')
        extra = list(self.extra_joints)
        if any(not n or n in contract.JOINT_NAMES for n in extra) or \
                len(set(extra)) != len(extra):
            raise ParameterError(f"parameter 'extra_joints' = {extra!r} is invalid: each name "
                                 f'once, not empty and none of {list(contract.JOINT_NAMES)}')
        if self.lockstep and self.camera_outage_s[1] > 0.0:
            raise ParameterError(
                f"parameter 'camera_outage_s' = {list(self.camera_outage_s)!r} is invalid in "
                'lockstep: the joint controller waits for every frame, so the run would stop; '
                "allowed: a duration of 0 (or command_interface 'position')")
        if self.image_stamp_offset_s != 0.0 and self.lockstep:
            raise ParameterError(
                f"parameter 'image_stamp_offset_s' = {self.image_stamp_offset_s!r} is invalid "
                "in lockstep: a frame's stamp names its joint state there; allowed: 0 (or "
                "command_interface 'position')")
        if self.image_stamp_offset_s > self.feedback_latency_s:
            raise ParameterError(
                f"parameter 'image_stamp_offset_s' = {self.image_stamp_offset_s!r} is invalid "
                f'with feedback_latency_s = {self.feedback_latency_s!r}: a frame cannot be '
                'stamped after it is delivered; allowed: at most feedback_latency_s')

    @property
    def lockstep(self) -> bool:
        """Return whether it runs in lockstep, by :func:`ibvs_common.shared_params.lockstep`."""
        return shared.lockstep(vars(self))


@dataclass(frozen=True)
class RobotStateConfig(ParamConfig):
    """The parameters of robot_state_node: the simulated arm drawn and the stamp rule's."""

    disturbance_deg: tuple[float, ...] = param_field(shared.DISTURBANCE_DEG)
    l2_scale: float = param_field(shared.L2_SCALE)
    l4_scale: float = param_field(shared.L4_SCALE)
    camera_rate_hz: float = param_field(shared.CAMERA_RATE_HZ)
    stale_timeout_s: float = param_field(shared.STALE_TIMEOUT_S)
