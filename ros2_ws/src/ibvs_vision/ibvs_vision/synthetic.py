"""
Synthetic stereo images of the two spherical fiducials, for tests and the bench.

Each pixel is ray-traced through the pinhole model of :mod:`ibvs_model.camera` (pixel (i, j)
centred at u = i, v = j; ROS stereo signs, eq. 19-22): ``supersample`` x ``supersample``
rays per pixel give anti-aliased edges; the spheres are shaded (ambient + Lambert + a
specular highlight) and hide each other by depth. The background is a grey gradient with
clutter in other hues (rectangles, grey and dark discs, an orange "arm" band), optional
occluders drawn in front, and Gaussian noise. Ground truth is the model projection of the
sphere centres, so the detector is judged against eq. (21)-(22) itself.
"""

from collections.abc import Sequence
import math

import cv2
from ibvs_model import StereoCamera
from ibvs_model.scene import MARKER_RADIUS_M, MARKER_RGB
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Clutter colours: none has much of the markers' chroma (R - max(G, B) or B - max(R, G)).
CLUTTER_RGB = ((128, 128, 128), (40, 40, 40), (230, 230, 230), (90, 160, 90),
               (235, 150, 70), (170, 170, 120), (200, 200, 210), (120, 140, 150))


def render_sphere_patch(camera: StereoCamera, centre_O: ArrayLike, lens: str,
                        radius: float = MARKER_RADIUS_M, rgb: ArrayLike = MARKER_RGB[0],
                        supersample: int = 4, light_C: ArrayLike = (-0.4, -0.6, -1.0),
                        ambient: float = 0.35, specular: float = 0.25
                        ) -> tuple[int, int, NDArray[np.float64], NDArray[np.float64],
                                   NDArray[np.float64]] | None:
    """
    Ray-trace one sphere in one lens.

    Parameters
    ----------
    camera : StereoCamera
        The stereo camera.
    centre_O : array_like, shape (3,)
        The sphere's centre in {O} (m).
    lens : str
        'left' or 'right'.
    radius : float
        The sphere's radius (m).
    rgb : array_like, shape (3,)
        Its colour (0-255).
    supersample : int
        Rays per pixel along each axis.
    light_C : array_like, shape (3,)
        From the scene towards the light, in {C} (default: up and left of the camera).
    ambient, specular : float
        Shares of ambient light and of the specular highlight.

    Returns
    -------
    tuple or None
        (x0, y0, colour (h, w, 3), cover (h, w), depth (h, w)) of the patch at (x0, y0):
        ``cover`` the covered fraction of each pixel, ``depth`` the mean depth of the hits
        (inf where none), for compositing; None when the sphere is not in front of the lens.

    """
    k = camera.intrinsics
    centre_C = camera.to_camera(np.asarray(centre_O, dtype=float)[None])[0]
    offset = k.baseline / 2.0 if lens == 'left' else -k.baseline / 2.0
    c = centre_C + np.array([offset, 0.0, 0.0])
    if c[2] <= radius * 1.01:
        return None
    # Bounding box of the silhouette from the cone of half angle asin(R / |c|).
    dist = np.linalg.norm(c)
    ang = math.asin(radius / dist)
    box = []
    for axis, f, cc, size in ((0, k.fu, k.cu, k.width), (1, k.fv, k.cv, k.height)):
        mid = math.atan2(c[axis], c[2])
        lo = f * math.tan(max(mid - ang, -1.5)) + cc
        hi = f * math.tan(min(mid + ang, 1.5)) + cc
        box.append((max(0, int(math.floor(lo)) - 1), min(size, int(math.ceil(hi)) + 2)))
    (x0, x1), (y0, y1) = box
    if x1 <= x0 or y1 <= y0:
        return None
    n = supersample
    sub = (np.arange(n) + 0.5) / n - 0.5
    us = (np.arange(x0, x1)[:, None] + sub[None, :]).ravel()
    vs = (np.arange(y0, y1)[:, None] + sub[None, :]).ravel()
    dx = (us - k.cu) / k.fu
    dy = (vs - k.cv) / k.fv
    ray = np.empty((len(vs), len(us), 3))
    ray[..., 0] = dx[None, :]
    ray[..., 1] = dy[:, None]
    ray[..., 2] = 1.0
    ray /= np.linalg.norm(ray, axis=2, keepdims=True)
    tc = ray @ c
    miss2 = dist * dist - tc * tc
    hit = (miss2 < radius * radius) & (tc > 0)
    t = tc - np.sqrt(np.maximum(radius * radius - miss2, 0.0))
    point = ray * t[..., None]
    normal = (point - c) / radius
    light = np.asarray(light_C, dtype=float)
    light = light / np.linalg.norm(light)
    lambert = np.clip(normal @ light, 0.0, None)
    half = light - ray
    half /= np.linalg.norm(half, axis=2, keepdims=True)
    spec = specular * np.clip(np.sum(normal * half, axis=2), 0.0, None) ** 40
    shade = ambient + (1.0 - ambient) * lambert
    colour = np.clip(shade[..., None] * np.asarray(rgb, float) + 255.0 * spec[..., None],
                     0.0, 255.0)
    colour = colour * hit[..., None]
    h, w = y1 - y0, x1 - x0
    cover = hit.reshape(h, n, w, n).mean(axis=(1, 3))
    summed = colour.reshape(h, n, w, n, 3).sum(axis=(1, 3))
    hits = hit.reshape(h, n, w, n).sum(axis=(1, 3))
    mean_colour = summed / np.maximum(hits, 1)[..., None]
    depth = np.where(hit, t * ray[..., 2], 0.0).reshape(h, n, w, n).sum(axis=(1, 3))
    depth = np.where(hits > 0, depth / np.maximum(hits, 1), np.inf)
    return x0, y0, mean_colour, cover, depth


def background(camera: StereoCamera, rng: np.random.Generator, clutter: int = 25,
               noise_free: bool = False) -> NDArray[np.float32]:
    """
    Return a background image: grey gradient and clutter in other hues.

    Parameters
    ----------
    camera : StereoCamera
        Gives the image size.
    rng : numpy.random.Generator
        Places the clutter.
    clutter : int
        How many rectangles and discs.
    noise_free : bool
        Unused.

    Returns
    -------
    ndarray of float32, shape (H, W, 3)

    """
    k = camera.intrinsics
    h, w = k.height, k.width
    ramp = np.linspace(90.0, 150.0, w)[None, :, None] + np.linspace(-20.0, 20.0, h)[:, None, None]
    img = np.broadcast_to(ramp, (h, w, 3)).astype(np.float32).copy()
    for _ in range(clutter):
        colour = tuple(float(c) for c in CLUTTER_RGB[rng.integers(len(CLUTTER_RGB))])
        x, y = int(rng.integers(0, w)), int(rng.integers(0, h))
        if rng.random() < 0.5:
            size = int(rng.integers(4, max(5, w // 8)))
            cv2.rectangle(img, (x, y), (x + size, y + int(rng.integers(4, h // 6))), colour, -1)
        else:
            cv2.circle(img, (x, y), int(rng.integers(3, 30)), colour, -1, cv2.LINE_AA)
    return img


def render_stereo(camera: StereoCamera, markers_O: ArrayLike,
                  rng: np.random.Generator | None = None, clutter: int = 25,
                  noise_sigma: float = 2.0, supersample: int = 4,
                  occluders: Sequence[tuple] = (), colours: Sequence[ArrayLike] = MARKER_RGB,
                  radius: float = MARKER_RADIUS_M, **shading: float
                  ) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """
    Return the left and right RGB images of spheres at ``markers_O``.

    Parameters
    ----------
    camera : StereoCamera
        The stereo camera.
    markers_O : array_like, shape (N, 3)
        The spheres' centres in {O} (m).
    rng : numpy.random.Generator, optional
        For the clutter and the noise; default a fresh one.
    clutter : int
        How many clutter shapes in the background.
    noise_sigma : float
        Standard deviation of the Gaussian pixel noise (0-255 scale).
    supersample : int
        Rays per pixel along each axis.
    occluders : sequence of (points, disparity_px, rgb)
        Polygons (lists of (u, v) in left-image pixels, drawn shifted by ``disparity_px``
        in the right image) painted in front of everything, e.g. the arm hiding a marker.
    colours : sequence of rgb
        The spheres' colours, in the order of ``markers_O``.
    radius : float
        The spheres' radius (m).
    **shading : float
        ``light_C``, ``ambient``, ``specular`` of :func:`render_sphere_patch`.

    Returns
    -------
    tuple of ndarray of uint8, shape (H, W, 3)
        The left and right images.

    """
    rng = np.random.default_rng() if rng is None else rng
    markers_O = np.asarray(markers_O, dtype=float).reshape(-1, 3)
    base = background(camera, rng, clutter)
    images = []
    for lens in ('left', 'right'):
        img = base.copy()
        zbuf = np.full(img.shape[:2], np.inf)
        cover_acc = np.zeros(img.shape[:2])
        for centre, rgb in zip(markers_O, colours):
            patch = render_sphere_patch(camera, centre, lens, radius, rgb, supersample,
                                        **shading)
            if patch is None:
                continue
            x0, y0, colour, cover, depth = patch
            h, w = cover.shape
            region = (slice(y0, y0 + h), slice(x0, x0 + w))
            front = depth < zbuf[region]
            a = np.where(front, cover, np.clip(cover - cover_acc[region], 0.0, 1.0))
            img[region] = img[region] * (1.0 - a[..., None]) + colour * a[..., None]
            zbuf[region] = np.minimum(zbuf[region], depth)
            cover_acc[region] = np.clip(cover_acc[region] + a, 0.0, 1.0)
        for points, disparity, rgb in occluders:
            pts = np.asarray(points, dtype=float)
            if lens == 'right':
                pts = pts - np.array([disparity, 0.0])
            cv2.fillPoly(img, [np.round(pts * 16).astype(np.int32)],
                         tuple(float(c) for c in rgb), cv2.LINE_AA, shift=4)
        if noise_sigma > 0:
            img += rng.normal(0.0, noise_sigma, img.shape).astype(np.float32)
        images.append(np.clip(np.round(img), 0, 255).astype(np.uint8))
    return images[0], images[1]


def disc_occluder(camera: StereoCamera, centre_O: ArrayLike, margin_px: float = 1.0,
                  rgb: Sequence[float] = (128, 128, 128)
                  ) -> tuple[NDArray[np.float64], float, Sequence[float]]:
    """
    Return an occluder for :func:`render_stereo` that hides the marker at ``centre_O``.

    A disc around the marker's image in the left image, as large as the silhouette's long
    axis (image radius times the off-axis stretch 1 / cos(theta)) plus ``margin_px``,
    shifted by the marker's disparity in the right image: an object just in front of it.

    Parameters
    ----------
    camera : StereoCamera
        The stereo camera.
    centre_O : array_like, shape (3,)
        The marker's centre in {O} (m).
    margin_px : float
        Added to the disc's radius (px).
    rgb : sequence of 3 float
        The occluder's colour.

    Returns
    -------
    tuple
        (outline (48, 2) in left-image pixels, disparity (px), rgb).

    """
    k = camera.intrinsics
    centre_O = np.asarray(centre_O, dtype=float)[None]
    u_l, u_r, v = camera.project(centre_O)[0]
    depth = camera.to_camera(centre_O)[0, 2]
    stretch = math.sqrt(1.0 + ((u_l - k.cu) / k.fu) ** 2 + ((v - k.cv) / k.fv) ** 2)
    radius = k.fu * MARKER_RADIUS_M / depth * stretch + margin_px
    angles = np.linspace(0.0, 2.0 * math.pi, 48, endpoint=False)
    outline = np.c_[u_l + radius * np.cos(angles), v + radius * np.sin(angles)]
    return (outline, u_l - u_r, rgb)


def hostile_image(kind: str, width: int, height: int,
                  rng: np.random.Generator) -> NDArray[np.uint8]:
    """
    Return an RGB image (height, width, 3) uint8 that makes a circle search expensive.

    The detector's worst cases, as the fuzz classes name them:

    - 'noise': mid-grey with Gaussian noise of 0.5 (of the full range) per pixel and
      channel, as ``image_noise_stddev`` 0.5 gives: edges everywhere;
    - 'checkerboard': 8 px squares of marker 1's red on grey, and 5 px squares of marker
      2's blue in the right half: a grid of strong edges in both markers' hues;
    - 'circles': 800 discs of 3-30 px radius in both markers' colours, overlapping: more
      circle centres than any budget can refine.

    Parameters
    ----------
    kind : str
        'noise', 'checkerboard' or 'circles' (HOSTILE_KINDS).
    width, height : int
        The size (px).
    rng : numpy.random.Generator
        The draws.

    Returns
    -------
    ndarray of uint8, shape (height, width, 3)

    """
    if kind == 'noise':
        return np.clip(np.round(rng.normal(127.5, 0.5 * 255.0, (height, width, 3))),
                       0, 255).astype(np.uint8)
    image = np.full((height, width, 3), 128, np.uint8)
    if kind == 'checkerboard':
        ys, xs = np.mgrid[:height, :width]
        red = ((xs // 8 + ys // 8) % 2 == 0) & (xs < width // 2)
        blue = ((xs // 5 + ys // 5) % 2 == 0) & (xs >= width // 2)
        image[red], image[blue] = MARKER_RGB[0], MARKER_RGB[1]
        return image
    if kind == 'circles':
        for _ in range(800):
            centre = (int(rng.integers(0, width)), int(rng.integers(0, height)))
            colour = tuple(int(c) for c in MARKER_RGB[int(rng.integers(2))])
            cv2.circle(image, centre, int(rng.integers(3, 31)), colour, -1, cv2.LINE_AA)
        return image
    raise ValueError(f'kind must be one of {HOSTILE_KINDS}, got {kind!r}')


#: The kinds of :func:`hostile_image`.
HOSTILE_KINDS = ('noise', 'checkerboard', 'circles')
