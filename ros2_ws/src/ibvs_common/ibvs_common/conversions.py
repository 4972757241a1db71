"""
Messages <-> numpy arrays and :mod:`ibvs_model` objects: every name of the message modules.

Readers raise :class:`InputError` with a short reason (used as the rejection reason on
/diagnostics) and never return NaN.

A façade: each message family has a module of its own, and this one re-exports their
names, so that a node imports them all from ``ibvs_common.conversions``:

- :mod:`.input_error`: :class:`InputError`.
- :mod:`.msg_time`: builtin_interfaces Time and Duration <-> integer nanoseconds and the
  one stamp rule: :func:`stamp_ns`, :func:`ns_stamp`, :func:`duration_ns`,
  :func:`read_stamp`, :class:`StampOrder`; and from :mod:`.timing`, how far a stamp may
  lead: :data:`STAMP_LEAD_MARGIN_NS`, :func:`stamp_lead_ns` (which a node takes from its
  :class:`.shared_params.Timing`).
- :mod:`.msg_joints`: sensor_msgs/JointState and the range a joint value is read in:
  :func:`joint_state`, :func:`joint_order` (:data:`JOINT_ORDER_CACHE`),
  :func:`ignored_joints`, :data:`JOINT_FIELDS`, :func:`read_joints`, :func:`check_finite`,
  :func:`travel_bounds`, :func:`position_bounds`, :func:`velocity_bounds`,
  :data:`POSITION_MARGIN_RAD`, :data:`POSITION_BOUND_RAD`, :data:`SPEED_BOUND_RAD_S`.
- :mod:`.msg_trajectory`: trajectory_msgs/JointTrajectory: :func:`joint_trajectory`,
  :func:`trajectory_arrays`, :func:`read_trajectory`, :func:`read_command_trajectory`,
  :func:`joint_path`, :func:`read_joint_path`.
- :mod:`.msg_pose`: Pose, PoseStamped, TFMessage and Path <-> 4x4 transforms:
  :func:`pose_matrix`, :func:`matrix_poses`, :func:`matrix_pose`, :func:`transforms_msg`,
  :func:`pose_stamped`, :func:`path_msg`, :func:`read_camera_pose`
  (:data:`MAX_CAMERA_DISTANCE_M`).
- :mod:`.msg_camera`: Image and CameraInfo: :func:`image_msg`, :func:`camera_infos`,
  :func:`focal_range_px`, :func:`check_camera_info`, :func:`intrinsics_from_infos`,
  :func:`camera_from_msgs`, :data:`MAX_IMAGE_SIDE_PX`, :data:`FOV_RANGE_DEG`,
  :data:`BASELINE_RANGE_M`, :data:`ROW_TOLERANCE_PX`, :data:`PINHOLE_TOLERANCE`,
  :data:`CU_TOLERANCE`.
- :mod:`.msg_features`: /ibvs/features and /ibvs/feature_status: :func:`features_msg`,
  :func:`read_features`, :func:`check_features_in_image` (:data:`IMAGE_MARGIN_PX`),
  :class:`FeatureStatus`, :func:`feature_status_msg`, :func:`read_feature_status`.

Each name here is the object of its module (the same function, class, constant or cache).
"""

from . import msg_joints
from .input_error import InputError
from .msg_camera import (BASELINE_RANGE_M, camera_from_msgs, camera_infos, check_camera_info,
                         CU_TOLERANCE, focal_range_px, FOV_RANGE_DEG, image_msg,
                         intrinsics_from_infos, MAX_IMAGE_SIDE_PX, PINHOLE_TOLERANCE,
                         ROW_TOLERANCE_PX)
from .msg_features import (check_features_in_image, feature_status_msg, features_msg,
                           FeatureStatus, IMAGE_MARGIN_PX, read_feature_status, read_features)
from .msg_joints import (check_finite, ignored_joints, JOINT_FIELDS, joint_order,
                         JOINT_ORDER_CACHE, joint_state, POSITION_BOUND_RAD, position_bounds,
                         POSITION_MARGIN_RAD, read_joints, SPEED_BOUND_RAD_S, travel_bounds,
                         velocity_bounds)
from .msg_pose import (matrix_pose, matrix_poses, MAX_CAMERA_DISTANCE_M, path_msg, pose_matrix,
                       pose_stamped, read_camera_pose, transforms_msg)
from .msg_time import duration_ns, ns_stamp, read_stamp, stamp_ns, StampOrder
from .msg_trajectory import (joint_path, joint_trajectory, read_command_trajectory,
                             read_joint_path, read_trajectory, trajectory_arrays)
from .timing import STAMP_LEAD_MARGIN_NS, stamp_lead_ns

# The private names callers reach through this module, the objects themselves (not copies):
# the cache read or cleared here is the one joint_order keeps.
_JOINT_ORDERS = msg_joints._JOINT_ORDERS
_symmetric_bounds = msg_joints._symmetric_bounds
_POSITION_BOUNDS = msg_joints._POSITION_BOUNDS
_VELOCITY_BOUNDS = msg_joints._VELOCITY_BOUNDS

__all__ = [
    'InputError',
    # msg_time
    'duration_ns', 'ns_stamp', 'read_stamp', 'STAMP_LEAD_MARGIN_NS', 'stamp_lead_ns',
    'stamp_ns', 'StampOrder',
    # msg_joints
    'check_finite', 'ignored_joints', 'JOINT_FIELDS', 'JOINT_ORDER_CACHE', 'joint_order',
    'joint_state', 'POSITION_BOUND_RAD', 'position_bounds', 'POSITION_MARGIN_RAD',
    'read_joints', 'SPEED_BOUND_RAD_S', 'travel_bounds', 'velocity_bounds',
    # msg_trajectory
    'joint_path', 'joint_trajectory', 'read_command_trajectory', 'read_joint_path',
    'read_trajectory', 'trajectory_arrays',
    # msg_pose
    'matrix_pose', 'matrix_poses', 'MAX_CAMERA_DISTANCE_M', 'path_msg', 'pose_matrix',
    'pose_stamped', 'read_camera_pose', 'transforms_msg',
    # msg_camera
    'BASELINE_RANGE_M', 'camera_from_msgs', 'camera_infos', 'check_camera_info',
    'CU_TOLERANCE', 'focal_range_px', 'FOV_RANGE_DEG', 'image_msg', 'intrinsics_from_infos',
    'MAX_IMAGE_SIDE_PX', 'PINHOLE_TOLERANCE', 'ROW_TOLERANCE_PX',
    # msg_features
    'check_features_in_image', 'feature_status_msg', 'features_msg', 'FeatureStatus',
    'IMAGE_MARGIN_PX', 'read_feature_status', 'read_features',
]
