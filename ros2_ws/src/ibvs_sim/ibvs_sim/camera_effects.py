"""
What a real stereo camera adds to the simulator's perfect one; numpy, scipy and OpenCV, no ROS.

Four imperfections, each off by default (sim_node parameters of the same names):

- image noise (``image_noise_stddev``): additive Gaussian noise, independent per pixel and
  channel, standard deviation in intensity units of [0, 1], as Gazebo's camera noise model.
  It is added to the rendered 8-bit image I / 255; the sum is clipped to [0, 1] and rounded
  to the nearest of the 256 levels of ``rgb8`` (:func:`add_image_noise`). Rounding adds
  the variance of a uniform quantisation step, (1/255)^2 / 12, i.e. a standard deviation of
  0.0011: 0.01 is published as 0.01006. Clipping narrows the noise on pixels within about
  3 sigma of black or white (it is not zero-mean there); elsewhere it is unbiased.
- frame drops (``frame_drop_probability``): each stereo frame is lost, both images, with this
  probability, independently of the others (:meth:`CameraEffects.frame_lost`).
- calibration error (``camera_pose_error_xyz_m``, ``camera_pose_error_rpy_deg``,
  ``focal_length_error``): the camera pose and intrinsics a calibration gives differ from
  the true ones that render the images (:func:`calibrated_pose`,
  :func:`calibrated_intrinsics`).
- latency is not here: it is the lockstep's ``feedback_latency_s``
  (ibvs_common.timing.feedback_frame_ns).

Randomness comes from one numpy Generator seeded with ``camera_seed``; per frame it draws the
drop decision first and, for a frame that is kept, the seed of the left image's noise and
then of the right one's, so that a run is the same every time. The noise itself is OpenCV's
normal draw (``cv2.randn``) from that seed: numpy's float64 draw costs several times as
much per image, and would make a noisy run several times slower than a noiseless one.
"""

from collections.abc import Iterable
import math

import cv2
from ibvs_model import StereoIntrinsics
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

#: Largest frame drop probability the simulator accepts (a camera that loses every frame
#: gives nothing to servo on).
MAX_DROP_PROBABILITY = 0.9
#: Largest image noise standard deviation, intensity units of [0, 1].
MAX_NOISE_STDDEV = 0.5


class EffectError(ValueError):
    """A camera effect's value cannot be used; ``param`` names its sim_node parameter."""

    def __init__(self, param: str, message: str) -> None:
        """Keep the parameter's name and the reason."""
        super().__init__(f'{param}: {message}')
        self.param = param


def add_image_noise(image: ArrayLike, stddev: float, rng: np.random.Generator
                    ) -> NDArray[np.uint8]:
    """
    Return an 8-bit image with additive Gaussian noise of ``stddev`` (module docstring).

    ``image``: uint8 array (any shape, e.g. (H, W, 3)); ``stddev``: standard deviation in
    intensity units of [0, 1]; ``rng``: numpy Generator, which draws the seed of OpenCV's
    generator for this image. The noise is drawn for every element (pixel and channel) in
    float32, 255 ``stddev`` in 8-bit units, added to the image, rounded and saturated to
    uint8 (``cv2.add``): image / 255 plus noise of ``stddev``, clipped to [0, 1]. ``stddev``
    0 returns the image unchanged and draws nothing.
    """
    image = np.asarray(image)
    if image.dtype != np.uint8:
        raise TypeError(f'image must be uint8, got {image.dtype}')
    if not (math.isfinite(stddev) and stddev >= 0.0):
        raise ValueError(f'stddev must be finite and >= 0, got {stddev}')
    if stddev == 0.0:
        return image
    cv2.setRNGSeed(int(rng.integers(2 ** 31)))
    column = np.ascontiguousarray(image).reshape(-1, 1)  # one channel: every element drawn
    noise = np.empty(column.shape, np.float32)
    cv2.randn(noise, 0.0, stddev * 255.0)
    return cv2.add(column, noise, dtype=cv2.CV_8U).reshape(image.shape)


def error_transform(xyz_m: ArrayLike, rpy_deg: ArrayLike) -> NDArray[np.float64]:
    """
    Return the 4x4 calibration error T_err: translation ``xyz_m``, rotation ``rpy_deg``.

    The rotation is roll, pitch, yaw about the fixed x, y, z axes (R = Rz Ry Rx, the URDF
    convention), in degrees.
    """
    xyz = np.asarray(xyz_m, dtype=float)
    rpy = np.asarray(rpy_deg, dtype=float)
    for name, values in (('camera_pose_error_xyz_m', xyz), ('camera_pose_error_rpy_deg', rpy)):
        if values.shape != (3,) or not np.all(np.isfinite(values)):
            raise EffectError(name, f'{values.tolist()}: needs 3 finite values')
    tf = np.eye(4)
    tf[:3, :3] = Rotation.from_euler('xyz', rpy, degrees=True).as_matrix()
    tf[:3, 3] = xyz
    return tf


def calibrated_pose(pose_C_O: ArrayLike, xyz_m: ArrayLike, rpy_deg: ArrayLike
                    ) -> NDArray[np.float64]:
    """
    Return the camera pose a calibration with this error gives: T_C^O T_err.

    The error is expressed in the true camera frame {C} (x right, y down, z along the
    optical axis): ``xyz_m`` moves the calibrated frame by that many metres along the true
    camera's axes, ``rpy_deg`` turns it about them (:func:`error_transform`). So
    inv(true) @ calibrated = T_err exactly.
    """
    return np.asarray(pose_C_O, dtype=float) @ error_transform(xyz_m, rpy_deg)


def calibrated_intrinsics(intrinsics: StereoIntrinsics, focal_length_error: float
                          ) -> StereoIntrinsics:
    """
    Return ``intrinsics`` with f_u and f_v multiplied by ``focal_length_error``.

    The principal point, image size and baseline are kept: a 1 % error in f scales every
    image offset from the principal point by 1 % in the model, and the depth that the
    model reads from a disparity by the same factor.
    """
    scale = float(focal_length_error)
    if not (math.isfinite(scale) and scale > 0.0):
        raise EffectError('focal_length_error', f'{scale}: must be finite and > 0')
    k = intrinsics
    return StereoIntrinsics(k.width, k.height, k.fu * scale, k.fv * scale, k.cu, k.cv,
                            k.baseline)


class CameraEffects:
    """
    Image noise and frame drops of one camera, drawn from one seeded Generator.

    ``noise_stddev``: see :func:`add_image_noise`; ``drop_probability``: in
    [0, MAX_DROP_PROBABILITY]; ``seed``: the Generator's seed (``camera_seed``).
    """

    def __init__(self, noise_stddev: float = 0.0, drop_probability: float = 0.0,
                 seed: int | None = 0) -> None:
        """Check the values and seed the Generator."""
        if not (math.isfinite(noise_stddev) and 0.0 <= noise_stddev <= MAX_NOISE_STDDEV):
            raise EffectError('image_noise_stddev', f'{noise_stddev}: must be in '
                              f'[0, {MAX_NOISE_STDDEV}]')
        if not (math.isfinite(drop_probability)
                and 0.0 <= drop_probability <= MAX_DROP_PROBABILITY):
            raise EffectError('frame_drop_probability', f'{drop_probability}: must be in '
                              f'[0, {MAX_DROP_PROBABILITY}]')
        self.noise_stddev = float(noise_stddev)
        self.drop_probability = float(drop_probability)
        self.rng = np.random.default_rng(seed)

    def frame_lost(self) -> bool:
        """Return True if the next frame is lost (draws one uniform number when p > 0)."""
        if self.drop_probability == 0.0:
            return False
        return bool(self.rng.random() < self.drop_probability)

    def noisy(self, images: Iterable[ArrayLike]) -> tuple[NDArray[np.uint8], ...]:
        """Return the images (left, right) with noise added, left first."""
        return tuple(add_image_noise(image, self.noise_stddev, self.rng) for image in images)
