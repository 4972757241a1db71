"""
The interface contract of the node graph (docs/design.md §3) and its timing rule (§4).

Every name a node publishes or subscribes comes from here, so a rename is one edit; so do
the codes of /ibvs/servo_status (:class:`ServoStatus`), the meaning of that topic.
"""

from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy)

# The codes of /ibvs/servo_status are part of the contract (without rclpy: servo_codes).
from .servo_codes import ServoStatus  # noqa: F401
# The timing rule is part of the contract.
from .timing import feedback_frame_ns, frame_stamp_ns  # noqa: F401

JOINT_NAMES = tuple(f'joint_{i}' for i in range(1, 7))

CLOCK = '/clock'
JOINT_STATES = '/joint_states'
#: The /joint_states message of each camera frame's step, stamped with the frame's stamp: the
#: joint state the frame's consumers need (the encoder angles the image was taken at), one
#: per frame instead of one per physics step. The runner remaps the feature and feedback
#: nodes' /joint_states to it; on a real cell, where nobody publishes it, they take
#: /joint_states and pick the state of each frame's stamp themselves.
FRAME_JOINT_STATES = '/stereo/joint_states'
LEFT_IMAGE = '/stereo/left/image_raw'
RIGHT_IMAGE = '/stereo/right/image_raw'
LEFT_INFO = '/stereo/left/camera_info'
RIGHT_INFO = '/stereo/right/camera_info'
STEREO_POSE = '/stereo/pose'
#: One std_msgs/Header per stereo frame the camera lost (sim_node frame_drop_probability),
#: stamped with the frame's stamp and published in place of its images: in lockstep it
#: tells the joint controller that no q_feedback will come for that frame.
FRAME_LOST = '/stereo/frame_lost'
#: The stereo pair of the tool at the target pose, rendered once before the run (sim_node,
#: target_features_source 'taught'); latched.
TEACH_LEFT_IMAGE = '/stereo/teach/left/image_raw'
TEACH_RIGHT_IMAGE = '/stereo/teach/right/image_raw'
#: The target features p_bar the feature node measured on the teach pair (PolygonStamped,
#: as /ibvs/features); latched.
TARGET_FEATURES = '/ibvs/target_features'
#: The feature node's /diagnostics value when it could not measure p_bar on the teach pair
#: (why, in words): no target features will come, and no frame is answered without them.
#: ``ibvs run`` ends the run on it (ibvs_experiments.runner.TeachFailed).
TEACH_FAILED = 'teach_failed'
FEATURES = '/ibvs/features'
#: The feedforward's joint reference, one trajectory_msgs/JointTrajectory for the whole run,
#: sampled at the physics rate; latched, so a node that joins late still gets it.
FEEDFORWARD_TRAJECTORY = '/ibvs/feedforward_trajectory'
Q_FEEDBACK = '/ibvs/q_feedback'
EFFORT_COMMANDS = '/joint_effort_commands'
#: command_interface 'position' (docs/design.md §4, free-running): ros2_controllers'
#: forward_command_controller (std_msgs/Float64MultiArray, the values in the order of the
#: controller's ``joints`` parameter) under the name of the usual position_controllers
#: configuration, or a joint_trajectory_controller (trajectory_msgs/JointTrajectory, by
#: joint name). Remappable, as every name here.
POSITION_COMMANDS = '/forward_position_controller/commands'
TRAJECTORY_COMMANDS = '/joint_trajectory_controller/joint_trajectory'
#: A dry run's references (the joint controller's ``dry_run``): what it would send on
#: POSITION_COMMANDS or TRAJECTORY_COMMANDS, the same type, on a topic no arm reads.
DRY_RUN_COMMANDS = '/ibvs/dry_run/commands'
DRY_RUN_TRAJECTORY = '/ibvs/dry_run/joint_trajectory'
#: sensor_msgs/TimeReference, one per camera frame, from the joint controller in position
#: mode: header.stamp = the time of the first command that uses the frame's q_feedback,
#: time_ref = the frame's stamp (its exposure); the run's latency metric.
FRAME_LATENCY = '/ibvs/frame_latency'
#: std_msgs/Int8, latched: the joint controller's status, one code of
#: :class:`ServoStatus` (MoveIt Servo's codes, and ours from 10: waiting,
#: holding on a stale input and which, a local minimum the feedback node reports); in
#: position mode on each change and once a second, with the effort interface (which never
#: holds) from its first command on, on each change.
SERVO_STATUS = '/ibvs/servo_status'
#: std_msgs/Int8, latched: the feedback node's status, NO_WARNING or LOCAL_MINIMUM of
#: :class:`ServoStatus` (ibvs_control.minimum_watch), from its first
#: answered frame on, on each change; the joint controller relays it on SERVO_STATUS.
FEEDBACK_STATUS = '/ibvs/feedback_status'
#: Evaluation only (nav_msgs/Path in base_link): the true flange pose of every physics step,
#: published in batches just before each /clock, so that when /clock says T every pose
#: stamped before T is out (batched: a message per step would slow every lockstep step).
TOOL_PATH = '/ibvs/tool_path'
#: Evaluation only (trajectory_msgs/JointTrajectory in base_link): the /joint_states of every
#: physics step, the same values, in batches published with /ibvs/tool_path: one point per
#: step (positions, velocities, effort = the torque of the step before; time_from_start from
#: header.stamp, the first step's stamp). The recorder takes these instead of the 1000
#: /joint_states and /joint_effort_commands a second, so that no per-step message leaves the
#: lockstep's process unless somebody subscribes to it.
JOINT_PATH = '/ibvs/joint_path'
#: Per stereo frame, stamped with the image stamp: one DiagnosticStatus whose values
#: (:data:`FEATURE_STATUS_KEYS`) say what the feature node published for the frame. Written by
#: :func:`ibvs_common.conversions.feature_status_msg` and read by
#: :func:`ibvs_common.conversions.read_feature_status`, never key by key.
FEATURE_STATUS = '/ibvs/feature_status'
#: The keys of a /ibvs/feature_status: 'mode' (:data:`FEATURE_MODES`: what was published),
#: 'source' (:data:`FEATURE_MEASURED` or :data:`FEATURE_ESTIMATED`: what the output follows),
#: 'reason' (:data:`FEATURE_MEASURED` when the detector found both markers in both images,
#: else why not), 'blend_weight' (the share of the switch offset still blended, 0 to 1) and
#: 'search' (how the detector searched: 'roi' or 'full').
FEATURE_STATUS_KEYS = ('mode', 'source', 'reason', 'blend_weight', 'search')
#: The modes of a frame's features: measured (eq. 2-3), estimated (eq. 46), or blending
#: from one to the other after a switch (section 2.3).
FEATURE_MEASURED = 'measured'
FEATURE_ESTIMATED = 'estimated'
FEATURE_BLENDING = 'blending'
FEATURE_MODES = (FEATURE_MEASURED, FEATURE_ESTIMATED, FEATURE_BLENDING)
DIAGNOSTICS = '/diagnostics'
#: For viewers (RViz, Foxglove; ibvs_viz.viz_node): the cell's URDF (std_msgs/String,
#: latched), the frame tree (tf2_msgs/TFMessage; /tf_static latched) and the markers
#: (visualization_msgs/MarkerArray): fields of view, target, tool path, fiducials.
ROBOT_DESCRIPTION = '/robot_description'
TF = '/tf'
TF_STATIC = '/tf_static'
MARKERS = '/ibvs/markers'
#: The feature node's overlays (sensor_msgs/Image, rgb8), drawn only when someone listens.
DEBUG_LEFT_IMAGE = '/ibvs/debug/left/image'
DEBUG_RIGHT_IMAGE = '/ibvs/debug/right/image'

#: What zed-ros2-wrapper 5.4 (master, zed_components zed_camera_component_video_depth.cpp)
#: publishes for the rectified colour pair of a camera named 'zed' (launch defaults:
#: namespace = camera_name 'zed', node 'zed_node'; topic root '~/'): images in bgra8,
#: CameraInfo at image_transport's getCameraInfoTopic of the image topic, frame ids
#: '<camera>_{left,right}_camera_frame_optical', QoS rclcpp::QoS(10) (keep last 10,
#: reliable, volatile); right P[3] = -f_x * baseline (m). sim_node camera_topics
#: 'zed_wrapper' publishes these; the other nodes take them by remapping.
ZED_LEFT_IMAGE = '/zed/zed_node/left/color/rect/image'
ZED_RIGHT_IMAGE = '/zed/zed_node/right/color/rect/image'
ZED_LEFT_INFO = '/zed/zed_node/left/color/rect/camera_info'
ZED_RIGHT_INFO = '/zed/zed_node/right/color/rect/camera_info'
ZED_LEFT_FRAME = 'zed_left_camera_frame_optical'
ZED_RIGHT_FRAME = 'zed_right_camera_frame_optical'
ZED_ENCODING = 'bgra8'

#: Base frame {O} and the camera frames (ROS optical frames, x right, y down, z forward).
BASE_FRAME = 'base_link'
CAMERA_FRAME = 'stereo_center_optical_frame'
LEFT_CAMERA_FRAME = 'stereo_left_optical_frame'
RIGHT_CAMERA_FRAME = 'stereo_right_optical_frame'

#: Lockstep data must never be dropped: reliable, and deep enough for a burst.
RELIABLE = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)
#: Images are large: reliable, a few frames deep.
IMAGES = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=5,
                    reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)
#: The ZED wrapper's image and camera_info QoS (rclcpp::QoS(10)).
ZED_IMAGES = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)
#: CameraInfo, read by every node that builds the camera (:class:`.kit.StereoCameraInput`):
#: one profile for the topic, the images' (it goes with them, one per frame).
CAMERA_INFO = IMAGES
#: Facts that do not change (camera pose): the last value reaches late joiners.
LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
