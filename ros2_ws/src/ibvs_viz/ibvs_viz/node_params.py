"""
viz_node's typed configuration (:class:`VizConfig`), no ROS.

Each value is checked against its Param at construction; the shared groups it reads
(:class:`ibvs_common.shared_params.Plant`, :class:`~ibvs_common.shared_params.Target`,
:class:`~ibvs_common.shared_params.Timing`) are one field each, and the camera pose's rule
(:func:`ibvs_common.shared_params.camera_pose_from`) runs at start and in ``ibvs run``.
"""

from dataclasses import dataclass

from ibvs_common import shared_params
from ibvs_common.params import group_field, Param, param_field, ParamConfig


@dataclass(frozen=True)
class VizConfig(ParamConfig):
    """The viz node's parameters, typed (:func:`ibvs_common.kit.config`)."""

    #: Rules between parameters, run at start and by ``ibvs run`` before any node starts.
    RULES = (shared_params.camera_pose_from,)

    plant: shared_params.Plant = group_field(shared_params.Plant)
    target: shared_params.Target = group_field(shared_params.Target)
    camera_pose: tuple = param_field(shared_params.CAMERA_POSE)
    timing: shared_params.Timing = group_field(shared_params.Timing)
    marker_rate_hz: float = param_field(Param(
        'marker_rate_hz', 10.0, 'most /ibvs/markers messages per second of sim time (/tf '
        'goes out with every joint state)', 'Hz', low=shared_params.MIN_RATE_HZ, high=1000.0))
    frustum_depth_m: float = param_field(Param(
        'frustum_depth_m', 3.0, "how far each lens's drawn field of view reaches", 'm',
        low=0.0, high=100.0, low_open=True))
    image_frames_tf: bool = param_field(Param(
        'image_frames_tf', True, "publish on /tf_static the frame each lens's CameraInfo "
        'names, where it is not ours, at our optical frame of that lens (false where the '
        'camera driver publishes its frames itself, e.g. zed-ros2-wrapper with its URDF)', '-'))
    tool_frames_tf: bool = param_field(Param(
        'tool_frames_tf', True, "publish the tool's frames (screwdriver, marker_1, marker_2) "
        "on /tf_static fixed to tool0 (false where the cell's URDF has the tool)", '-'))
    tool_path_points: int = param_field(Param(
        'tool_path_points', 20000, 'most tool positions kept for the drawn path (the oldest '
        'go first)', '-', low=2, high=1_000_000))
