"""
The interface contract of the node graph (docs/design.md §3) and its timing rule (§4).

Every name a node publishes or subscribes comes from here, so a rename is one edit.
"""

from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy)

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
FEATURES = '/ibvs/features'
#: The feedforward's joint reference, one trajectory_msgs/JointTrajectory for the whole run,
#: sampled at the physics rate; latched, so a node that joins late still gets it.
FEEDFORWARD_TRAJECTORY = '/ibvs/feedforward_trajectory'
Q_FEEDBACK = '/ibvs/q_feedback'
EFFORT_COMMANDS = '/joint_effort_commands'
#: Evaluation only (nav_msgs/Path in base_link): the true flange pose of every physics step,
#: published in batches just before each /clock, so that when /clock says T every pose
#: stamped before T is out. One pose message per step cost the lockstep 0.3 ms a step.
TOOL_PATH = '/ibvs/tool_path'
#: Per stereo frame, stamped with the image stamp: one DiagnosticStatus whose values say
#: mode (measured / estimated / blending), the reason and the blend weight.
FEATURE_STATUS = '/ibvs/feature_status'
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
#: Facts that do not change (camera pose): the last value reaches late joiners.
LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
