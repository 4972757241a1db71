"""
What a viewer needs that a cell's URDF lacks: tool, camera and field-of-view frames (numpy).

The arm's frames are not here: on a cell abb_ros2's robot_state_publisher publishes them
from ABB's URDF, in simulation ibvs_sim's robot_state_node does the same
(:mod:`ibvs_model.abb_urdf`); ABB's ``tool0`` is the paper's flange {E} (eq. 7) exactly.
The viewers' node adds, on /tf_static:

- the tool, fixed to ``tool0`` (:func:`tool_transforms`): ``screwdriver`` at tool0 and the
  fiducials ``marker_1`` at P1 = [0, 0, 0]{E} and ``marker_2`` at P2 = [0, 0, L_tool / 2]{E}
  (eq. 8-9), which no cell's URDF has;
- the camera (:func:`camera_transforms`): {C} ``stereo_center_optical_frame`` in base_link
  at T_C^O (eq. 12, as /stereo/pose or the hand-eye ``camera_pose`` gives it), and the two
  lenses' optical frames half a baseline to each side of it, left at X^C = -b/2 and right
  at +b/2 (the projection of eq. 19-22). ROS optical frames: x right, y down, z forward.

Their shapes (screwdriver, fiducial spheres, the ZED 2's body) are drawn as markers
(:func:`tool_solids`, :data:`ZED2_BODY_SIZE_M`), not in a URDF.
"""

from ibvs_common import contract
from ibvs_model import StereoIntrinsics
from ibvs_model.abb_urdf import TOOL_FRAME
from ibvs_model.mass_model import Solid, tool_shapes
from ibvs_model.robot import IRB4600, RobotParams
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: The ZED 2's body (175 x 30 x 33 mm, Stereolabs' datasheet) in the optical frame {C}:
#: x along the baseline, y down, z along the optical axis.
ZED2_BODY_SIZE_M = (0.175, 0.033, 0.030)
#: The camera's frames (contract names).
LENS_FRAMES = (contract.LEFT_CAMERA_FRAME, contract.RIGHT_CAMERA_FRAME)
#: The frame of the target flange pose (the target of eq. 43), published on /tf_static.
TARGET_FRAME = 'ibvs_target'
#: The tool's frames, children of tool0.
TOOL_FRAMES = ('screwdriver', 'marker_1', 'marker_2')
#: (parent, child, T_child^parent) of each joint, as /tf and /tf_static carry them.
Transforms = list[tuple[str, str, NDArray[np.float64]]]


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


def tool_transforms(params: RobotParams = IRB4600) -> Transforms:
    """
    Return (tool0, child, T) of the tool's frames: the screwdriver and the two fiducials.

    Parameters
    ----------
    params : RobotParams
        The robot's geometry (L_tool).

    Returns
    -------
    list of (str, str, ndarray, shape (4, 4))

    """
    out = [(TOOL_FRAME, 'screwdriver', np.eye(4))]
    out += [(TOOL_FRAME, f'marker_{k}', translation(xyz))
            for k, xyz in enumerate(params.fiducials_E, start=1)]
    return out


def tool_solids(params: RobotParams = IRB4600) -> list[tuple[str, Solid]]:
    """
    Return (frame, solid) of the tool's shapes (:func:`ibvs_model.mass_model.tool_shapes`).

    Parameters
    ----------
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    list of (str, Solid)

    """
    return [(frame, solid) for frame, solids in tool_shapes(params).items()
            for solid in solids]


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
