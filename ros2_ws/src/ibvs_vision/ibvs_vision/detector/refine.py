"""
Sub-pixel refinement of one Hough circle, and the sphere's silhouette geometry.

Steps 3 and 5 of :mod:`ibvs_vision.detector`: the coverage of the marker over each pixel
(rim pixels unmixed against the local background), its area centroid with the notch of a
rod in front of it filled from the symmetric side, the disc test after the off-axis
stretch, and the perspective shift between a sphere's silhouette centre and the
projection of its centre. Pure numpy/OpenCV.
"""

from dataclasses import dataclass, field
import math

import cv2
from ibvs_model import StereoIntrinsics
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .colour import colour_scores, ENCODINGS
from .config import DetectorConfig

_KERNEL3 = np.ones((3, 3), np.uint8)
_KERNEL5 = np.ones((5, 5), np.uint8)
#: Notch filling of symmetric_centre: a pixel is in a notch when its coverage is this much
#: below the mirrored one; at most this share of the area may be filled; iterations.
NOTCH_COVERAGE = 0.3
NOTCH_SHARE = 0.1
NOTCH_ITERATIONS = 3
NOTCH_EDGE = 0.05
#: Steps of axis_band_centre.
AXIS_BAND_ITERATIONS = 4


def silhouette_to_centre(u: ArrayLike, v: ArrayLike, depth: float,
                         intrinsics: StereoIntrinsics, radius_m: float
                         ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return the projection of a sphere's centre from the centre of its silhouette ellipse.

    The silhouette of a sphere of radius R whose centre is at depth Z is the conic
    x^T (d d^T - (|d|^2 - R^2) I) x = 0 (d: the centre in the lens frame); its centre is
    d_xy d_z / (d_z^2 - R^2), i.e. (ellipse centre - c) = (centre projection - c) /
    (1 - (R / Z)^2) about the principal point c. This inverts that radial stretch.

    Parameters
    ----------
    u, v : array_like
        The silhouette centre (px).
    depth : float
        Z of the sphere's centre (m).
    intrinsics : StereoIntrinsics
        c_u, c_v of the image.
    radius_m : float
        The sphere's radius R (m).

    Returns
    -------
    tuple of ndarray
        (u, v) of the projection of the sphere's centre (px).

    """
    k = 1.0 - (radius_m / depth) ** 2
    return (intrinsics.cu + (np.asarray(u) - intrinsics.cu) * k,
            intrinsics.cv + (np.asarray(v) - intrinsics.cv) * k)


def centre_to_silhouette(u: ArrayLike, v: ArrayLike, depth: float,
                         intrinsics: StereoIntrinsics, radius_m: float
                         ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return the silhouette ellipse centre of a sphere whose centre projects to (u, v).

    The inverse of :func:`silhouette_to_centre`.

    Parameters
    ----------
    u, v : array_like
        The projection of the sphere's centre (px).
    depth : float
        Z of the sphere's centre (m).
    intrinsics : StereoIntrinsics
        c_u, c_v of the image.
    radius_m : float
        The sphere's radius R (m).

    Returns
    -------
    tuple of ndarray
        (u, v) of the silhouette centre (px).

    """
    k = 1.0 - (radius_m / depth) ** 2
    return (intrinsics.cu + (np.asarray(u) - intrinsics.cu) / k,
            intrinsics.cv + (np.asarray(v) - intrinsics.cv) / k)


@dataclass(frozen=True)
class Blob:
    """
    One refined marker candidate in one image.

    (u, v): centre of the silhouette (area centroid), px; ``radius``: radius of a disc of
    the same area after taking out the off-axis stretch, px; ``roundness``: smaller over
    larger second moment (1 for a disc); ``hough``: the Hough circle (u, v, r) it came from.
    ``cover``: the coverage of each pixel of the window whose top-left pixel is ``origin``
    (x0, y0), for :func:`axis_band_centre` (notches not filled).
    """

    u: float
    v: float
    radius: float
    roundness: float
    hough: tuple
    cover: NDArray[np.float64] | None = field(default=None, repr=False, compare=False)
    origin: tuple = (0, 0)


def line_of_sight_stretch(intrinsics: StereoIntrinsics | None, u: float,
                          v: float) -> tuple[NDArray[np.float64], float]:
    """
    Return the radial direction and the stretch of the line of sight through (u, v).

    Parameters
    ----------
    intrinsics : StereoIntrinsics or None
        The image's intrinsics; None: no stretch.
    u, v : float
        The pixel (px).

    Returns
    -------
    tuple of (ndarray, shape (2,), float)
        The unit radial direction in the image and 1 / cos(theta), theta the angle
        between the line of sight and the optical axis.

    """
    k = intrinsics
    if k is None:
        return np.array([1.0, 0.0]), 1.0
    x, y = (u - k.cu) / k.fu, (v - k.cv) / k.fv
    rho = math.hypot(x, y)
    direction = np.array([x, y]) / rho if rho > 1e-12 else np.array([1.0, 0.0])
    return direction, math.sqrt(1.0 + rho * rho)


def window_half(r: float) -> int:
    """Return the half side (px) of :func:`refine_circle`'s window around a circle of radius r."""
    return int(math.ceil(2.0 * r + 6.0))


def refine_circle(image: NDArray[np.uint8], encoding: str, k: int, u: float, v: float,
                  r: float, bounds: tuple[int, int, int, int], config: DetectorConfig,
                  intrinsics: StereoIntrinsics | None = None
                  ) -> tuple[Blob | None, str | None, tuple[int, int, int, int] | None]:
    """
    Refine one Hough circle of marker k to the area centroid of the marker's coverage.

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3)
        The whole image.
    encoding : str
        'rgb8' or 'bgr8'.
    k : int
        The marker, 0 (P1) or 1 (P2).
    u, v, r : float
        The Hough circle in full-image pixels.
    bounds : tuple of 4 int
        (x0, y0, x1, y1): the window used stays inside it.
    config : DetectorConfig
        The tuning.
    intrinsics : StereoIntrinsics, optional
        Undo the off-axis stretch with them.

    Returns
    -------
    tuple
        (:class:`Blob` or None, rejection reason or None, bounding box (x0, y0, x1, y1) of
        the object or None).

    """
    cfg = config
    half = window_half(r)
    iu, iv = int(round(u)), int(round(v))
    x0, y0 = max(iu - half, bounds[0]), max(iv - half, bounds[1])
    x1, y1 = min(iu + half + 1, bounds[2]), min(iv + half + 1, bounds[3])
    if x1 - x0 < 3 or y1 - y0 < 3:
        return None, 'too small', None
    linear, selective = colour_scores(image[y0:y1, x0:x1], cfg.marker_rgb[k], encoding)
    # The object: the outer contour of the marker-hue pixels around the circle's centre.
    binary = (selective >= 0.5 * cfg.min_colour_score).astype(np.uint8)
    contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    centre = (float(u - x0), float(v - y0))
    best, best_dist = None, -max(r, 1.5)
    for contour in contours:
        dist = cv2.pointPolygonTest(contour, centre, True)
        if dist > best_dist:
            best, best_dist = contour, dist
    if best is None:
        return None, 'no marker colour at the circle', None
    bx, by, bw, bh = cv2.boundingRect(best)
    box = (x0 + bx, y0 + by, x0 + bx + bw - 1, y0 + by + bh - 1)
    height, width = binary.shape
    if bx == 0 or by == 0 or bx + bw == width or by + bh == height:
        if (bx == 0 and x0 == 0) or (by == 0 and y0 == 0) \
                or (bx + bw == width and x1 == image.shape[1]) \
                or (by + bh == height and y1 == image.shape[0]):
            return None, 'at image border', box
        if (x0, y0, x1, y1) != (iu - half, iv - half, iu + half + 1, iv + half + 1):
            return None, 'at search window border', box
        return None, 'larger than the circle', box
    filled = np.zeros_like(binary)
    cv2.drawContours(filled, [best], -1, 1, cv2.FILLED)
    inside = filled.astype(bool)
    level = float(np.median(linear[inside]))
    if level < cfg.min_colour_score:
        return None, 'too faint', box
    patch = image[y0:y1, x0:x1]
    if encoding != 'rgb8':
        patch = patch[:, :, list(ENCODINGS[encoding])]
    cover = coverage(patch, filled, linear, level, cfg.marker_rgb[k])
    m00 = float(cover.sum())
    xs = np.arange(x0, x1, dtype=np.float64)
    ys = np.arange(y0, y1, dtype=np.float64)
    cu = float(cover.sum(axis=0) @ xs) / m00
    cv = float(cover.sum(axis=1) @ ys) / m00
    direction, stretch = line_of_sight_stretch(intrinsics, cu, cv)
    radius = math.sqrt(m00 / (math.pi * stretch))
    if radius < 0.5 * cfg.hough_min_radius_px:
        return None, 'too small', box
    # Shape: second moments and the extent of the outline, the off-axis stretch undone.
    dx, dy = xs - cu, ys - cv
    cov = np.empty((2, 2))
    cov[0, 0] = float(cover.sum(axis=0) @ dx ** 2) / m00
    cov[1, 1] = float(cover.sum(axis=1) @ dy ** 2) / m00
    cov[0, 1] = cov[1, 0] = float(dy @ cover @ dx) / m00
    squeeze = np.eye(2) + (1.0 / stretch - 1.0) * np.outer(direction, direction)
    eig = np.linalg.eigvalsh(squeeze @ cov @ squeeze)
    roundness = float(eig[0] / eig[1]) if eig[1] > 0.0 else 0.0
    outline = (best[:, 0, :] + np.array([x0 - cu, y0 - cv])) @ squeeze
    reach = np.hypot(outline[:, 0], outline[:, 1])
    if roundness < cfg.min_roundness or reach.max() > 1.2 * radius + 0.75 \
            or reach.min() < 0.8 * radius - 1.25:
        return None, 'not round (partly occluded?)', box
    centre = symmetric_centre(cover, cu - x0, cv - y0, m00)
    if centre is None:
        return None, 'not round (partly occluded?)', box
    cu, cv = centre[0] + x0, centre[1] + y0
    return Blob(u=cu, v=cv, radius=radius, roundness=roundness, hough=(u, v, r), cover=cover,
                origin=(x0, y0)), None, box


def axis_band_centre(blob: Blob, direction: ArrayLike, half_width: float,
                     iterations: int = AXIS_BAND_ITERATIONS) -> tuple[float, float]:
    """
    Return the centre (u, v) of a blob's coverage outside a band along the tool axis.

    The rods that carry the fiducials (link 6's quill, the screwdriver's shaft) lie on the
    tool axis, which passes through both markers' centres: in the image they touch a
    marker's outline only where the line through both markers' images crosses it, at two
    opposite ends. There the coverage is wrong both ways: a rod in front of the sphere cuts
    a notch, a rod (or the other marker) just behind the outline darkens the background
    that a rim pixel is unmixed against, which makes it look more covered. Mirroring a notch
    (:func:`symmetric_centre`) then copies the other end's error. Weighting out a band of
    half-width ``half_width`` about the line through the current centre along
    ``direction`` removes both ends at once and keeps the rest point-symmetric about the
    ellipse's centre, whose centroid is therefore still that centre: iterated from the
    blob's centre, each step moves towards it. The band's edge is a one-pixel ramp (a hard
    edge would make the result depend on the centre's sub-pixel position).

    Parameters
    ----------
    blob : Blob
        A blob with its ``cover``.
    direction : array_like, shape (2,)
        The image direction of the tool axis (any length but zero).
    half_width : float
        Half-width of the band (px).
    iterations : int
        Steps from the blob's centre.

    Returns
    -------
    tuple of (float, float)
        The centre (u, v) in the image (px); the blob's own without a cover.

    """
    if blob.cover is None:
        return blob.u, blob.v
    d = np.asarray(direction, dtype=np.float64)
    d = d / math.hypot(d[0], d[1])
    height, width = blob.cover.shape
    x0, y0 = blob.origin
    xs = np.arange(x0, x0 + width, dtype=np.float64)
    ys = np.arange(y0, y0 + height, dtype=np.float64)
    cu, cv = blob.u, blob.v
    for _ in range(iterations):
        # Distance of each pixel centre from the line through (cu, cv) along d.
        dist = np.abs(np.subtract.outer((ys - cv) * d[0], (xs - cu) * d[1]))
        weighted = blob.cover * np.clip(dist - half_width + 0.5, 0.0, 1.0)
        total = float(weighted.sum())
        if total <= 0.0:
            return blob.u, blob.v
        cu = float(weighted.sum(axis=0) @ xs) / total
        cv = float(weighted.sum(axis=1) @ ys) / total
    return cu, cv


def symmetric_centre(cover: NDArray[np.float64], cx: float, cy: float,
                     area: float) -> tuple[float, float] | None:
    """
    Return the centre (x, y) of a disc's coverage with its notches filled, or None.

    An ellipse is symmetric about its centre c: the coverage at p equals that at 2 c - p. A
    thin object in front of the marker (the tool's shaft, the quill of link 6) cuts a notch
    into the outline and moves the area centroid by up to 0.1 px (measured at the target
    pose), which the stereo pair turns into a tilt of the tool axis. Where the coverage at p
    falls short of the mirrored one by more than NOTCH_COVERAGE (a notch: the centre's own
    error moves rim pixels by a tenth of that), the mirrored value (bilinear) is used;
    the centroid of that and the mirror are iterated from the area centroid (cx, cy).
    None when the notches hold more than NOTCH_SHARE of the ``area``: not a marker with a
    rod across it, but one partly hidden.

    Parameters
    ----------
    cover : ndarray, shape (h, w)
        The coverage of each pixel (:func:`coverage`).
    cx, cy : float
        Its area centroid (px, in ``cover``).
    area : float
        Its sum.

    Returns
    -------
    tuple of (float, float) or None
        The centre (x, y) in ``cover`` (px).

    """
    height, width = cover.shape
    xs, ys = np.meshgrid(np.arange(width, dtype=np.float32), np.arange(height, dtype=np.float32))
    cover32 = cover.astype(np.float32)
    columns = np.arange(width, dtype=np.float64)
    rows = np.arange(height, dtype=np.float64)
    for _ in range(NOTCH_ITERATIONS):
        mirrored = cv2.remap(cover32, np.float32(2.0 * cx) - xs, np.float32(2.0 * cy) - ys,
                             cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
        short = mirrored - cover32
        notch = short > NOTCH_COVERAGE
        # The rod's edges cover pixels partly: next to a notch, any shortfall counts.
        notch |= (cv2.dilate(notch.astype(np.uint8), _KERNEL3) > 0) & (short > NOTCH_EDGE)
        filled = np.where(notch, mirrored, cover32).astype(np.float64)
        if float((filled - cover).sum()) > NOTCH_SHARE * area:
            return None
        total = float(filled.sum())
        cx = float(filled.sum(axis=0) @ columns) / total
        cy = float(filled.sum(axis=1) @ rows) / total
    return cx, cy


def coverage(patch: NDArray[np.uint8], filled: NDArray[np.uint8], linear: NDArray[np.uint8],
             level: float, marker_rgb: ArrayLike) -> NDArray[np.float64]:
    """
    Return the fraction of each pixel of an RGB ``patch`` covered by the marker.

    Pixels inside the object (``filled`` eroded) count 1, pixels two or more pixels
    outside count 0. A rim pixel p is unmixed as p = x * m + y * b, with m the marker's
    colour (any brightness: shading only scales x) and b the mean colour of the background
    pixels within 2 px; its coverage is 1 - y. Where m and b are nearly parallel (a dark
    background) it falls back to s / (level of the interior pixels next to it), s being
    the linear colour channel.

    Parameters
    ----------
    patch : ndarray of uint8, shape (h, w, 3)
        The RGB pixels.
    filled : ndarray of uint8, shape (h, w)
        1 inside the object's outer contour, holes filled.
    linear : ndarray of uint8, shape (h, w)
        The linear colour channel s.
    level : float
        The median s inside the object.
    marker_rgb : array_like, shape (3,)
        The marker's colour m.

    Returns
    -------
    ndarray, shape (h, w)
        The coverage, 0 to 1.

    """
    interior = cv2.erode(filled, _KERNEL3)
    if not np.any(interior):
        interior = filled
    support = cv2.dilate(filled, _KERNEL3)
    cover = interior.astype(np.float64)
    rim = (support > interior)
    if not np.any(rim):
        return cover
    outside = (1 - support).astype(np.float32)
    rgb = patch.astype(np.float32)
    count = cv2.boxFilter(outside, -1, (5, 5), normalize=False)
    back = cv2.boxFilter(rgb * outside[..., None], -1, (5, 5), normalize=False)
    local = cv2.dilate(linear * interior, _KERNEL5).astype(np.float64)
    local[local < 0.5 * level] = level
    fallback = np.clip(linear[rim] / local[rim], 0.0, 1.0)
    pix = rgb[rim].astype(np.float64)
    n = count[rim].astype(np.float64)
    b = back[rim].astype(np.float64) / np.maximum(n, 1.0)[:, None]
    m = np.asarray(marker_rgb, dtype=np.float64)
    a11 = m @ m
    a12 = b @ m
    a22 = np.einsum('ij,ij->i', b, b)
    b1 = pix @ m
    b2 = np.einsum('ij,ij->i', b, pix)
    det = a11 * a22 - a12 * a12
    good = (n > 0) & (det > 0.05 * a11 * np.maximum(a22, 1e-9)) & (a22 > 100.0)
    y = np.where(good, (a11 * b2 - a12 * b1) / np.where(good, det, 1.0), 0.0)
    cover[rim] = np.where(good, np.clip(1.0 - y, 0.0, 1.0), fallback)
    return cover
