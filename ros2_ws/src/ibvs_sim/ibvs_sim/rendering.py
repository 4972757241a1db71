"""
The geometry of rendering the stereo pair with PyBullet: pure numpy, no PyBullet, no ROS.

Rendering. Each lens is a pinhole with the intrinsics of :class:`ibvs_model.StereoIntrinsics`
at the pose of :class:`ibvs_model.StereoCamera` shifted by -b/2 (left) or +b/2 (right) along
x of {C} (ROS sign convention, ibvs_model.camera). The OpenGL projection matrix is built from
f_u, f_v, c_u, c_v so that a point projects where eq. (16)-(22) put it, with the pixel
convention of ibvs_model.camera (the centre of pixel (i, j) is at u = i, v = j):

    x_ndc = 2 (u + 1/2) / W - 1,   y_ndc = 1 - 2 (v + 1/2) / H.

The two renderers need two corrections to honour this convention exactly (measured: without
them marker centres are off by up to 0.6 px):

- TinyRenderer samples pixel (i, j) at its corner (window coordinates (i, H - 1 - j)), not at
  its centre, so the projection it is given has its principal point moved by half a pixel:
  (c_u - 1/2, c_v + 1/2).
- The EGL plugin draws into a 1024 x 768 window and resamples larger requests by nearest
  neighbour (bullet3 eglRendererVisualShapeConverter.cpp), which shifts features by up to
  0.6 px at HD720. Images wider or taller than the window are rendered in tiles (each with
  its own principal point) and put together.

Pixel integration. Both renderers sample each pixel at one point, so a marker's outline is
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

:class:`ibvs_sim.world.World` makes the PyBullet calls with what this module computes.
"""

from collections.abc import Iterable, Sequence
import math
from typing import TYPE_CHECKING

from ibvs_model.camera import merge_windows, StereoIntrinsics
import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from ibvs_model.camera import StereoCamera

#: Near and far clipping planes of the render, m.
NEAR_M = 0.05
FAR_M = 30.0
#: Size of the EGL plugin's window (bullet3: START_WIDTH, START_HEIGHT).
EGL_WINDOW = (1024, 768)
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


def projection_matrix(intrinsics: StereoIntrinsics, near: float = NEAR_M, far: float = FAR_M,
                      renderer: str = 'egl') -> NDArray[np.float64]:
    """
    Return the 4x4 OpenGL projection matrix of a pinhole with ``intrinsics`` (eq. 16).

    Eye coordinates are OpenGL's (x right, y up, looking along -z); see the module docstring
    for the pixel convention and the half-pixel shift that ``renderer`` 'tiny' needs.
    """
    k = intrinsics
    w, h = float(k.width), float(k.height)
    cu, cv = (k.cu - 0.5, k.cv + 0.5) if renderer == 'tiny' else (k.cu, k.cv)
    return np.array([
        [2.0 * k.fu / w, 0.0, 1.0 - 2.0 * (cu + 0.5) / w, 0.0],
        [0.0, 2.0 * k.fv / h, 2.0 * (cv + 0.5) / h - 1.0, 0.0],
        [0.0, 0.0, -(far + near) / (far - near), -2.0 * far * near / (far - near)],
        [0.0, 0.0, -1.0, 0.0],
    ])


def ground_obj(half_size_m: float) -> str:
    """
    Return a Wavefront OBJ of the ground: one square of ``half_size_m`` each side, facing up.

    One-sided on purpose. The EGL plugin draws the back faces of every body into its shadow
    map (2048 x 2048 texels, drawn again for every image, whatever the image's size); a
    ground box's underside covered all of it, which cost 9 ms of each EGL call on llvmpipe
    (measured) and put the box's own top in its shadow. A square seen from above only is
    never drawn there: the ground takes the light as the rest of the scene does, and the
    robot casts its shadow on it.
    """
    h = float(half_size_m)
    if not (math.isfinite(h) and h > 0.0):
        raise ValueError(f'half_size_m must be > 0, got {half_size_m!r}')
    corners = ((-h, -h), (h, -h), (h, h), (-h, h))  # counter-clockwise seen from +z
    lines = ['# The ground square: ibvs_sim.rendering.ground_obj.']
    lines += [f'v {x:.6f} {y:.6f} 0.0' for x, y in corners]
    lines += ['vn 0.0 0.0 1.0', 'f 1//1 2//1 3//1', 'f 1//1 3//1 4//1']
    return '\n'.join(lines) + '\n'


def tiles(intrinsics: StereoIntrinsics, max_width: int = EGL_WINDOW[0],
          max_height: int = EGL_WINDOW[1]) -> list[tuple[int, int, StereoIntrinsics]]:
    """
    Return the tiles of an image no larger than ``max_width`` x ``max_height``.

    Each tile is (u0, v0, intrinsics of the tile): the same f_u, f_v with the principal
    point moved to (c_u - u0, c_v - v0). Tiles split the image as evenly as possible.
    """
    k = intrinsics
    nu = -(-k.width // max_width)
    nv = -(-k.height // max_height)
    u_edges = [round(i * k.width / nu) for i in range(nu + 1)]
    v_edges = [round(j * k.height / nv) for j in range(nv + 1)]
    out = []
    for v0, v1 in zip(v_edges[:-1], v_edges[1:]):
        for u0, u1 in zip(u_edges[:-1], u_edges[1:]):
            out.append((u0, v0, StereoIntrinsics(u1 - u0, v1 - v0, k.fu, k.fv, k.cu - u0,
                                                 k.cv - v0, k.baseline)))
    return out


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


def render_windows(windows: Sequence[tuple[int, int, int, int]], factor: int,
                   max_size: tuple[int, int] = EGL_WINDOW) -> list[tuple[int, int, int, int]]:
    """
    Return the windows to render with ``factor`` x ``factor`` samples per pixel, one call each.

    Each call of the EGL renderer costs about 8 ms whatever its size (measured at HD720:
    the plugin draws its whole 1024 x 768 window and its shadow map every time), so
    separate ``windows`` whose bounding box, ``factor`` times finer, still fits
    ``max_size`` are rendered as that one box; otherwise they stay as they are.
    """
    if len(windows) < 2:
        return list(windows)
    box = (min(w[0] for w in windows), min(w[1] for w in windows),
           max(w[2] for w in windows), max(w[3] for w in windows))
    if (box[2] - box[0]) * factor <= max_size[0] and (box[3] - box[1]) * factor <= max_size[1]:
        return [box]
    return list(windows)


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


def gl_matrix(matrix: ArrayLike) -> list[float]:
    """Return a 4x4 matrix as the column-major list of 16 floats that PyBullet expects."""
    return [float(v) for v in np.asarray(matrix).T.reshape(16)]
