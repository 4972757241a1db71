"""
The simulator's configuration (:class:`SimConfig`): its parameters, declared once.

Each field of :class:`SimConfig` is a sim_node parameter of the same name
(:class:`ibvs_common.params.Param`: default, units, allowed values); sim_node's
:class:`.node_params.SimNodeConfig` extends it with the node's own parameters and is built
from the declared values (:func:`ibvs_common.kit.config`); the replay builds a SimConfig
from recorded values (:meth:`SimConfig.from_values`), a test builds one directly. No ROS
here.
"""

from dataclasses import dataclass

from ibvs_common.params import Param, param_field, ParamConfig
from ibvs_common.shared_params import (CAMERA_RATE_HZ, DISTURBANCE_DEG, L2_SCALE, L4_SCALE,
                                       PHYSICS_RATE_HZ, SCENARIO, START_JOINTS)
from ibvs_common.teach import TEACH_FRAMES
from ibvs_model import paper

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

    Each value is checked against its Param at construction (ParameterError naming it);
    what depends on several values or on the robot (camera rate against physics rate,
    a reachable start pose, a camera that sees the scene) the Simulator checks.
    """

    scenario: int = param_field(SCENARIO)
    start_joints: tuple[float, ...] = param_field(START_JOINTS)
    disturbance_deg: tuple[float, ...] = param_field(DISTURBANCE_DEG)
    physics_rate_hz: float = param_field(PHYSICS_RATE_HZ)
    camera_rate_hz: float = param_field(CAMERA_RATE_HZ)
    resolution: str = param_field(RESOLUTION)
    pub_downscale_factor: float = param_field(PUB_DOWNSCALE_FACTOR)
    camera_eye: tuple[float, float, float] = param_field(CAMERA_EYE)
    camera_look_at: tuple[float, float, float] = param_field(CAMERA_LOOK_AT)
    l2_scale: float = param_field(L2_SCALE)
    l4_scale: float = param_field(L4_SCALE)
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
