"""
The cell as a viewer sees it: URDF, frame tree and field-of-view geometry (pure numpy).

What ``robot_state_publisher`` does for a URDF, from our own kinematics (it is not on PyPI):
each revolute joint ``joint_i`` gives the transform of ``link_i`` in its parent,
``origin_i Rot_z(q_i)`` (:func:`ibvs_model.urdf.joint_origins`: the paper's DH frames,
eq. 4-7, split at the joints), and each fixed joint a constant transform. Chained from
``base_link`` ({O}) they give ``tool0`` = {E} = T_E^O(q) of eq. (7) exactly.

The camera is part of the cell's URDF (:func:`cell_urdf`): a ZED 2 body on the frame {C}
``stereo_center_optical_frame`` (T_C^O, eq. 12, as /stereo/pose gives it), and the two
lenses' optical frames half a baseline to each side of it, left at X^C = -b/2 and right at
+b/2 (the projection of eq. 19-22). ROS optical frames: x right, y down, z forward.
"""

from ibvs_common import contract
from ibvs_model import StereoIntrinsics
from ibvs_model.mass_model import matrix_rpy
from ibvs_model.robot import IRB4600, RobotParams
from ibvs_model.urdf import joint_origins, LINK_NAMES, robot_urdf
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: The ZED 2's body (175 x 30 x 33 mm, Stereolabs' datasheet) in the optical frame {C}:
#: x along the baseline, y down, z along the optical axis.
ZED2_BODY_SIZE_M = (0.175, 0.033, 0.030)
#: The fixed joint from base_link to the camera, and the camera's frames (contract names).
CAMERA_JOINT = 'stereo_camera_joint'
LENS_FRAMES = (contract.LEFT_CAMERA_FRAME, contract.RIGHT_CAMERA_FRAME)
#: The frame of the target flange pose (the target of eq. 43), published on /tf_static.
TARGET_FRAME = 'ibvs_target'
TOOL_FRAME = 'tool0'
#: (parent, child, T_child^parent) of each joint, as /tf and /tf_static carry them.
Transforms = list[tuple[str, str, NDArray[np.float64]]]


def rot_z(angle: float) -> NDArray[np.float64]:
    """
    Return the rotation about z: a revolute joint's motion.

    Parameters
    ----------
    angle : float
        The angle (rad).

    Returns
    -------
    ndarray, shape (4, 4)

    """
    c, s = np.cos(angle), np.sin(angle)
    tf = np.eye(4)
    tf[:2, :2] = [[c, -s], [s, c]]
    return tf


def translation(xyz: ArrayLike) -> NDArray[np.float64]:
    """
    Return the translation by ``xyz``.

    Parameters
    ----------
    xyz : array_like, shape (3,)
        The offset (m).

    Returns
    -------
    ndarray, shape (4, 4)

    """
    tf = np.eye(4)
    tf[:3, 3] = xyz
    return tf


def joint_transforms(q: ArrayLike, params: RobotParams = IRB4600) -> Transforms:
    """
    Return (parent, child, T_child^parent) of the six revolute joints at angles ``q``.

    What robot_state_publisher publishes on /tf for each moving joint: the joint's origin
    in its parent link times its rotation ``Rot_z(q_i)`` about the joint axis z.

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    list of (str, str, ndarray, shape (4, 4))

    """
    q = np.asarray(q, dtype=float)
    origins = joint_origins(params)
    return [(LINK_NAMES[i], LINK_NAMES[i + 1], origins[i] @ rot_z(q[i])) for i in range(6)]


def robot_fixed_transforms(params: RobotParams = IRB4600) -> Transforms:
    """
    Return (parent, child, T) of the fixed joints of the arm and tool (tool0, markers).

    Parameters
    ----------
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    list of (str, str, ndarray, shape (4, 4))

    """
    out = [('link_6', TOOL_FRAME, joint_origins(params)[6]),
           (TOOL_FRAME, 'screwdriver', np.eye(4))]
    out += [(TOOL_FRAME, f'marker_{k}', translation(xyz))
            for k, xyz in enumerate(params.fiducials_E, start=1)]
    return out


def camera_transforms(pose_C_O: ArrayLike, baseline: float) -> Transforms:
    """
    Return (parent, child, T) of the camera's frames: {C} in base_link, the lenses in {C}.

    Parameters
    ----------
    pose_C_O : array_like, shape (4, 4)
        T_C^O (eq. 12).
    baseline : float
        b (m): the lenses sit at X^C = -b/2 and +b/2.

    Returns
    -------
    list of (str, str, ndarray, shape (4, 4))

    """
    half = baseline / 2.0
    return [(contract.BASE_FRAME, contract.CAMERA_FRAME, np.asarray(pose_C_O, dtype=float)),
            (contract.CAMERA_FRAME, contract.LEFT_CAMERA_FRAME, translation((-half, 0, 0))),
            (contract.CAMERA_FRAME, contract.RIGHT_CAMERA_FRAME, translation((half, 0, 0)))]


def link_poses(q: ArrayLike, params: RobotParams = IRB4600) -> dict[str, NDArray[np.float64]]:
    """
    Return {frame: T_frame^O} of every link, tool0, screwdriver and markers at ``q``.

    The chain :func:`joint_transforms` then :func:`robot_fixed_transforms`, as a tf
    listener would compose /tf and /tf_static.

    Parameters
    ----------
    q : array_like, shape (6,)
        Joint angles (rad).
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    dict of str to ndarray, shape (4, 4)

    """
    poses = {contract.BASE_FRAME: np.eye(4)}
    for parent, child, tf in joint_transforms(q, params) + robot_fixed_transforms(params):
        poses[child] = poses[parent] @ tf
    return poses


def _fixed_joint_xml(name, parent, child, tf):
    xyz = ' '.join(repr(float(v)) for v in tf[:3, 3])
    rpy = ' '.join(repr(float(v)) for v in matrix_rpy(tf[:3, :3]))
    return [f'  <joint name="{name}" type="fixed">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{child}"/>',
            f'    <origin xyz="{xyz}" rpy="{rpy}"/>',
            '  </joint>']


def cell_urdf(params: RobotParams, pose_C_O: ArrayLike, baseline: float) -> str:
    """
    Return the URDF a viewer loads as /robot_description: arm, tool, markers and camera.

    The robot of :func:`ibvs_model.urdf.robot_urdf` with its markers as URDF spheres (no
    file a viewer would have to find), and the ZED 2: a box on ``stereo_center_optical_frame``
    fixed in base_link at ``pose_C_O`` (T_C^O), and the two lenses' optical frames.

    Parameters
    ----------
    params : RobotParams
        The robot's geometry.
    pose_C_O : array_like, shape (4, 4)
        T_C^O (eq. 12).
    baseline : float
        b (m).

    Returns
    -------
    str
        The URDF.

    """
    robot = robot_urdf(params, with_tool=True, marker_mesh=False)
    size = ' '.join(repr(float(v)) for v in ZED2_BODY_SIZE_M)
    camera = ['  <material name="camera_black"><color rgba="0.1 0.1 0.1 1.0"/></material>',
              f'  <link name="{contract.CAMERA_FRAME}">',
              '    <visual>',
              f'      <geometry><box size="{size}"/></geometry>',
              '      <material name="camera_black"/>',
              '    </visual>',
              '  </link>']
    for frame in LENS_FRAMES:
        camera.append(f'  <link name="{frame}"/>')
    for parent, child, tf in camera_transforms(pose_C_O, baseline):
        name = CAMERA_JOINT if parent == contract.BASE_FRAME else f'{child}_joint'
        camera += _fixed_joint_xml(name, parent, child, tf)
    return robot.replace('</robot>\n', '\n'.join(camera + ['</robot>']) + '\n')


def frustum_lines(intrinsics: StereoIntrinsics, depth_m: float) -> NDArray[np.float64]:
    """
    Return the edges of a lens's field of view as line-list points in its frame.

    A pyramid from the optical centre to the image corners at distance ``depth_m`` along
    the optical axis: four edges from the apex, four around the far rectangle.

    Parameters
    ----------
    intrinsics : StereoIntrinsics
        The lens's image size and intrinsics.
    depth_m : float
        The pyramid's depth (m).

    Returns
    -------
    ndarray, shape (16, 3)
        Pairs of points, one per edge (m).

    """
    k = intrinsics
    corners = []
    for u, v in ((-0.5, -0.5), (k.width - 0.5, -0.5), (k.width - 0.5, k.height - 0.5),
                 (-0.5, k.height - 0.5)):
        corners.append([(u - k.cu) / k.fu * depth_m, (v - k.cv) / k.fv * depth_m, depth_m])
    corners = np.array(corners)
    points = []
    for i in range(4):
        points += [np.zeros(3), corners[i], corners[i], corners[(i + 1) % 4]]
    return np.array(points)
