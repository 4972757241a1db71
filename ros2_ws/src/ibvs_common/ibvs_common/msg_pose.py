"""
geometry_msgs Pose and PoseStamped, tf2_msgs/TFMessage, nav_msgs/Path <-> 4x4 transforms.

And /stereo/pose read as the camera's pose T_C^O (:func:`read_camera_pose`). Readers raise
:class:`.input_error.InputError`.
"""

from collections.abc import Sequence

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Pose, PoseStamped, TransformStamped
from nav_msgs.msg import Path
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation
from std_msgs.msg import Header
from tf2_msgs.msg import TFMessage

from . import contract
from .input_error import InputError
from .msg_time import ns_stamp


def pose_matrix(pose: Pose) -> NDArray[np.float64]:
    """Return a geometry_msgs/Pose as a 4x4 homogeneous transform."""
    q = pose.orientation
    quat = np.array([q.x, q.y, q.z, q.w], dtype=float)
    pos = np.array([pose.position.x, pose.position.y, pose.position.z], dtype=float)
    if not (np.all(np.isfinite(quat)) and np.all(np.isfinite(pos))):
        raise InputError('non-finite pose')
    norm = np.linalg.norm(quat)
    if abs(norm - 1.0) > 1e-3:
        raise InputError('quaternion not normalised', f'|q| = {norm:.6f}')
    tf = np.eye(4)
    tf[:3, :3] = Rotation.from_quat(quat / norm).as_matrix()
    tf[:3, 3] = pos
    return tf


def matrix_poses(tfs: ArrayLike) -> list[Pose]:
    """Return 4x4 homogeneous transforms (N, 4, 4) as geometry_msgs/Pose, one quaternion call."""
    tfs = np.asarray(tfs, dtype=float).reshape(-1, 4, 4)
    quats = Rotation.from_matrix(tfs[:, :3, :3]).as_quat()
    poses = []
    for tf, (x, y, z, w) in zip(tfs, quats):
        pose = Pose()
        pose.position.x, pose.position.y, pose.position.z = (float(v) for v in tf[:3, 3])
        pose.orientation.x, pose.orientation.y = float(x), float(y)
        pose.orientation.z, pose.orientation.w = float(z), float(w)
        poses.append(pose)
    return poses


def transforms_msg(triples: Sequence[tuple[str, str, ArrayLike]], stamp: Time) -> TFMessage:
    """
    Return (parent, child, 4x4 T_child^parent) triples as one tf2_msgs/TFMessage.

    Every transform stamped ``stamp``, as tf2_ros's TransformBroadcaster sends a batch
    (robot_state_node's links, viz_node's frames).
    """
    msg = TFMessage()
    for (parent, child, _), pose in zip(triples, matrix_poses([tf for *_, tf in triples])):
        t = TransformStamped()
        t.header.stamp = stamp
        t.header.frame_id = parent
        t.child_frame_id = child
        t.transform.translation.x = pose.position.x
        t.transform.translation.y = pose.position.y
        t.transform.translation.z = pose.position.z
        t.transform.rotation = pose.orientation
        msg.transforms.append(t)
    return msg


def matrix_pose(tf: ArrayLike) -> Pose:
    """Return a 4x4 homogeneous transform as a geometry_msgs/Pose."""
    return matrix_poses(tf)[0]


def pose_stamped(tf: ArrayLike, stamp: int | Time,
                 frame_id: str = contract.BASE_FRAME) -> PoseStamped:
    """Return a 4x4 transform as PoseStamped in ``frame_id``."""
    msg = PoseStamped()
    msg.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
    msg.header.frame_id = frame_id
    msg.pose = matrix_pose(tf)
    return msg


def path_msg(stamped_poses: Sequence[tuple[int, ArrayLike]],
             frame_id: str = contract.BASE_FRAME) -> Path:
    """Return (stamp ns, 4x4 transform) pairs as a nav_msgs/Path stamped with the last one."""
    msg = Path()
    msg.header.frame_id = frame_id
    stamps = [t_ns for t_ns, _ in stamped_poses]
    poses = matrix_poses([tf for _, tf in stamped_poses]) if stamps else []
    msg.poses = [PoseStamped(header=Header(stamp=ns_stamp(t_ns), frame_id=frame_id), pose=pose)
                 for t_ns, pose in zip(stamps, poses)]
    if msg.poses:
        msg.header.stamp = msg.poses[-1].header.stamp
    return msg


#: Farthest a camera may be from the robot base (m) and still see its markers (the
#: simulator's camera_eye lies within 20 m of it in each axis).
MAX_CAMERA_DISTANCE_M = 100.0


def read_camera_pose(pose_msg: PoseStamped | Pose) -> NDArray[np.float64]:
    """
    Return /stereo/pose (PoseStamped or Pose) as T_C^O; :class:`InputError` if unusable.

    Besides :func:`pose_matrix`'s checks, the camera must be within
    :data:`MAX_CAMERA_DISTANCE_M` of the robot base and look towards the robot: the base
    origin of {O} in front of it (positive depth). A pose looking away is a wrong
    calibration; nothing could be servoed on.
    """
    pose = pose_msg.pose if hasattr(pose_msg, 'pose') else pose_msg
    tf = pose_matrix(pose)
    x, y, z = tf[:3, 3]
    distance = float(np.hypot(np.hypot(x, y), z))  # no overflow warning for 1e308
    if distance > MAX_CAMERA_DISTANCE_M:
        raise InputError('camera too far from the robot',
                         f'{distance:.3g} m from the base, at most {MAX_CAMERA_DISTANCE_M:g}')
    depth = float(tf[:3, 2] @ -tf[:3, 3])  # z_C of the point O = 0
    if depth <= 0.0:
        raise InputError('camera looks away from the robot',
                         f'the robot base is {depth:.3f} m deep in the camera frame')
    return tf
