"""
The geometry of rendering the stereo pair: pure numpy, no OpenGL, no PyBullet, no ROS.

Rendering. Each lens is a pinhole with the intrinsics of :class:`ibvs_model.StereoIntrinsics`
at the pose of :class:`ibvs_model.StereoCamera` shifted by -b/2 (left) or +b/2 (right) along
x of {C} (ROS sign convention, ibvs_model.camera). The OpenGL projection matrix is built from
f_u, f_v, c_u, c_v so that a point projects where eq. (16)-(22) put it, with the pixel
convention of ibvs_model.camera (the centre of pixel (i, j) is at u = i, v = j):

    x_ndc = 2 (u + 1/2) / W - 1,   y_ndc = 1 - 2 (v + 1/2) / H.

OpenGL's rasteriser samples pixel (i, j) of the window at (i + 1/2, j + 1/2), so under this
projection it samples image pixel (i, j) exactly at u = i, v = j (:mod:`.gl_renderer`).

Pixel integration. The renderer samples each pixel at one point, so a marker's outline is
a staircase and its measured centre jumps by a few hundredths of a pixel as it moves, which
stereo turns into millimetres of depth. A camera pixel integrates light over its area:
``supersampling`` s > 1 renders s x s samples per pixel (the same pinhole with f and the
principal point scaled, c' = s (c + 1/2) - 1/2, so that the samples sit at the centres of
an s x s grid inside each pixel) and averages them (a box filter, rounded to 8 bits).
Where it matters most, around the fiducials, ``focus`` spheres are rendered again with
``focus_supersampling`` samples per pixel along each axis (default 8 x 8) in small windows
that hold their whole images (:func:`focus_windows`), pasted over the full image: each window
is the same pinhole with the principal point moved to the window's corner, so it keeps the
geometry. With 8 x 8 samples around the markers and 1 elsewhere, the detected disparity of
a marker moves by 0.005 px rms with its sub-pixel position instead of 0.02-0.04 px with 2 x 2
everywhere (about 0.3 mm instead of 1.3 mm of tool position at 2.4 m), for a quarter of the
cost (measured at HD720 near the target pose).

:class:`Renderer` is what :class:`ibvs_sim.world.World` draws with (one per World):
:class:`ibvs_sim.gl_renderer.GLRenderer` implements it; World computes the passes with what
this module computes and pastes the images together.
"""

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
import math
from typing import Protocol, TYPE_CHECKING

from ibvs_model.camera import merge_windows, StereoIntrinsics
import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from ibvs_model.camera import StereoCamera

#: Near and far clipping planes of the render, m.
NEAR_M = 0.05
FAR_M = 30.0
#: Largest number of samples per pixel along each axis (render_stereo's supersampling).
MAX_SUPERSAMPLING = 4
#: The simulator's default (sim_node parameter render_supersampling): see the docstring.
DEFAULT_SUPERSAMPLING = 1
#: Samples per pixel along each axis in the windows around the fiducials: largest and the
#: simulator's default (sim_node parameter render_marker_supersampling).
MAX_FOCUS_SUPERSAMPLING = 16
DEFAULT_FOCUS_SUPERSAMPLING = 8
#: Pixels added around the bound of a focus sphere's image (covers the partly covered rim).
FOCUS_MARGIN_PX = 2


#: One pass of :meth:`Renderer.render_passes`: (view, projection, width, height, covered).
Pass = tuple[ArrayLike, ArrayLike, int, int, Sequence[tuple[int, int, int, int]]]


@dataclass(frozen=True)
class RenderDevice:
    """
    What draws a :class:`Renderer`'s images: the OpenGL implementation and its kind.

    ``gl_renderer``: OpenGL's GL_RENDERER string (e.g. 'llvmpipe (LLVM 15.0.6, 256 bits)',
    'NVIDIA H100 80GB HBM3/PCIe/SSE2'); ``hardware``: True on a GPU, False on a software
    rasteriser (Mesa's llvmpipe).
    """

    gl_renderer: str
    hardware: bool


class Renderer(Protocol):
    """
    What :class:`ibvs_sim.world.World` draws with: a fixed scene of parts moved by poses.

    The scene (the shapes of every part) is given at construction; each call draws it with
    the parts at ``part_poses`` (P, 4, 4), poses in {O}. :class:`ibvs_sim.gl_renderer.
    GLRenderer` is the implementation.
    """

    #: The OpenGL implementation that draws, chosen once at construction.
    device: RenderDevice

    def render_passes(self, part_poses: ArrayLike, passes: Sequence[Pass]
                      ) -> list[NDArray[np.uint8]]:
        """
        Return one (height, width, 3) uint8 image per pass, the parts at ``part_poses``.

        A pass is (view, projection, width, height, covered): the OpenGL view matrix
        (:func:`view_matrix`), the projection of the image (:func:`projection_matrix`), its
        size, and windows (u0, v0, u1, v1) of it that the caller paints over, whose pixels
        may then be anything.
        """

    def close(self) -> None:
        """Release what the renderer holds (idempotent)."""


def projection_matrix(intrinsics: StereoIntrinsics, near: float = NEAR_M, far: float = FAR_M
                      ) -> NDArray[np.float64]:
    """
    Return the 4x4 OpenGL projection matrix of a pinhole with ``intrinsics`` (eq. 16).

    Eye coordinates are OpenGL's (x right, y up, looking along -z); see the module docstring
    for the pixel convention.
    """
    k = intrinsics
    w, h = float(k.width), float(k.height)
    return np.array([
        [2.0 * k.fu / w, 0.0, 1.0 - 2.0 * (k.cu + 0.5) / w, 0.0],
        [0.0, 2.0 * k.fv / h, 2.0 * (k.cv + 0.5) / h - 1.0, 0.0],
        [0.0, 0.0, -(far + near) / (far - near), -2.0 * far * near / (far - near)],
        [0.0, 0.0, -1.0, 0.0],
    ])


def ground_obj(half_size_m: float) -> str:
    """
    Return a Wavefront OBJ of the ground: one square of ``half_size_m`` each side, facing up.

    One-sided: seen from above only (the renderer culls back faces, :mod:`.gl_renderer`).
    """
    h = float(half_size_m)
    if not (math.isfinite(h) and h > 0.0):
        raise ValueError(f'half_size_m must be > 0, got {half_size_m!r}')
    corners = ((-h, -h), (h, -h), (h, h), (-h, h))  # counter-clockwise seen from +z
    lines = ['# The ground square: ibvs_sim.rendering.ground_obj.']
    lines += [f'v {x:.6f} {y:.6f} 0.0' for x, y in corners]
    lines += ['vn 0.0 0.0 1.0', 'f 1//1 2//1 3//1', 'f 1//1 3//1 4//1']
    return '\n'.join(lines) + '\n'


def supersampled(intrinsics: StereoIntrinsics, factor: int) -> StereoIntrinsics:
    """Return the intrinsics of an image ``factor`` times finer with the same view (above)."""
    k, s = intrinsics, int(factor)
    return StereoIntrinsics(k.width * s, k.height * s, k.fu * s, k.fv * s,
                            s * (k.cu + 0.5) - 0.5, s * (k.cv + 0.5) - 0.5, k.baseline)


def box_downsample(image: NDArray[np.uint8], factor: int) -> NDArray[np.uint8]:
    """
    Return the mean of each ``factor`` x ``factor`` block of ``image`` as uint8.

    Rounded half to even, as ``np.rint`` of the mean; computed on integers (the sum of each
    block, then its quotient and remainder by the block's size), five times faster than a
    float mean of the 8 x 8 marker windows and equal to it to the bit.
    """
    s = int(factor)
    if s == 1:
        return image
    h, w = image.shape[0] // s, image.shape[1] // s
    channels = image.shape[2]
    rows = image[:h * s, :w * s].reshape(h, s, w * s * channels).sum(axis=1, dtype=np.uint32)
    total = rows.reshape(h, w, s, channels).sum(axis=2, dtype=np.uint32)
    size = s * s
    quotient, remainder = np.divmod(total, size)
    up = (2 * remainder > size) | ((2 * remainder == size) & (quotient % 2 == 1))
    return (quotient + up).astype(np.uint8)


def focus_windows(intrinsics: StereoIntrinsics, lens_pose: ArrayLike,
                  spheres: Iterable[tuple[ArrayLike, float]], margin_px: int = FOCUS_MARGIN_PX
                  ) -> list[tuple[int, int, int, int]]:
    """
    Return the windows (u0, v0, u1, v1), u1 and v1 excluded, that hold the images of ``spheres``.

    ``spheres``: (centre (3,) in {O}, radius m) pairs; ``lens_pose``: T of the lens's
    optical frame in {O}. A sphere lies in its axis-aligned cube in the lens frame, whose
    image is the convex hull of its eight projected corners: their bounding box, grown by
    ``margin_px``, holds the sphere's image. Windows that overlap are merged, all are clipped
    to the image; a sphere that reaches behind the near plane or lies outside the image gives
    none.
    """
    k = intrinsics
    to_lens = np.linalg.inv(np.asarray(lens_pose, dtype=float))
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
                       dtype=float)
    boxes = []
    for centre, radius in spheres:
        c = to_lens[:3, :3] @ np.asarray(centre, dtype=float) + to_lens[:3, 3]
        points = c + radius * corners
        if np.any(points[:, 2] <= NEAR_M):
            continue
        u = k.fu * points[:, 0] / points[:, 2] + k.cu
        v = k.fv * points[:, 1] / points[:, 2] + k.cv
        box = [max(0, math.floor(u.min() - margin_px)), max(0, math.floor(v.min() - margin_px)),
               min(k.width, math.ceil(u.max() + margin_px) + 1),
               min(k.height, math.ceil(v.max() + margin_px) + 1)]
        if box[0] < box[2] and box[1] < box[3]:
            boxes.append(box)
    return merge_windows(boxes)


def window_intrinsics(intrinsics: StereoIntrinsics, window: Sequence[int]) -> StereoIntrinsics:
    """Return the intrinsics of the window (u0, v0, u1, v1) of an image: c moved to its corner."""
    u0, v0, u1, v1 = window
    k = intrinsics
    return StereoIntrinsics(u1 - u0, v1 - v0, k.fu, k.fv, k.cu - u0, k.cv - v0, k.baseline)


def lens_poses(camera: 'StereoCamera') -> tuple[NDArray[np.float64], ...]:
    """Return (T_left^O, T_right^O): the lenses at x = -b/2 and +b/2 of {C} (ROS signs)."""
    poses = []
    for sign in (-1.0, 1.0):
        shift = np.eye(4)
        shift[0, 3] = sign * camera.intrinsics.baseline / 2.0
        poses.append(camera.pose_C_O @ shift)
    return tuple(poses)


def view_matrix(lens_pose: ArrayLike) -> NDArray[np.float64]:
    """Return the OpenGL view matrix of an optical frame (x right, y down, z forward) in {O}."""
    flip = np.diag([1.0, -1.0, -1.0, 1.0])  # optical axes -> OpenGL eye axes
    return flip @ np.linalg.inv(lens_pose)
