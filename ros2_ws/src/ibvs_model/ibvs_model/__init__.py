"""
Pure-Python model of the IRB 4600 and the ZED 2 stereo camera (no ROS).

Kinematics (eq. 4-10, 43), stereo camera (eq. 12-22) and the camera-and-robot model F
(eq. 30-32, 42) of Li and Assadian, "Innovative Adaptive Image Based Visual Servoing
Control of 6 DoFs Industrial Robot Manipulators".
"""

from ._validate import nearest_rotation
from .camera import look_at, StereoCamera, StereoIntrinsics
from .combined import CameraRobotModel
from .errors import (BehindCameraError, InvalidInputError, ModelError, TriangulationError,
                     UnreachablePoseError)
from .robot import (condition_number, fiducial_points, forward_kinematics,
                    forward_kinematics_batch, geometric_jacobian, ik_position_axis,
                    ik_solutions, inverse_kinematics, IRB4600, joint_frames, point_jacobian,
                    pose_error, pose_from, RobotParams, tool_axis_angle)

__all__ = [
    'BehindCameraError', 'CameraRobotModel', 'condition_number', 'fiducial_points',
    'forward_kinematics', 'forward_kinematics_batch', 'geometric_jacobian', 'ik_position_axis',
    'ik_solutions',
    'InvalidInputError',
    'inverse_kinematics', 'IRB4600', 'joint_frames', 'look_at', 'ModelError',
    'nearest_rotation', 'point_jacobian', 'pose_error', 'pose_from', 'RobotParams',
    'StereoCamera', 'StereoIntrinsics', 'tool_axis_angle', 'TriangulationError',
    'UnreachablePoseError', 'default_camera', 'default_model',
]


def default_camera(resolution: str = 'HD720') -> StereoCamera:
    """
    Return the ZED 2 at ``resolution`` at the default pose (docs/design.md §5).

    Parameters
    ----------
    resolution : str
        The ZED 2 mode: 'HD720', 'VGA' or 'HD1080'.

    Returns
    -------
    StereoCamera
        The paper's camera at ``paper.CAMERA_EYE``, looking at ``paper.CAMERA_LOOK_AT``.

    """
    from . import paper
    return StereoCamera(StereoIntrinsics.zed2(resolution),
                        look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT))


def default_model(resolution: str = 'HD720', params: RobotParams = IRB4600) -> CameraRobotModel:
    """
    Return F for the paper's robot and the ZED 2 at the default pose (docs/design.md §5).

    Parameters
    ----------
    resolution : str
        The ZED 2 mode: 'HD720', 'VGA' or 'HD1080'.
    params : RobotParams
        The robot's geometry.

    Returns
    -------
    CameraRobotModel
        F (eq. 30) of that robot seen by :func:`default_camera`.

    """
    return CameraRobotModel(default_camera(resolution), params)
