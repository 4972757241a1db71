"""
Sub-pixel refinement of Hough circles, and the sphere's silhouette geometry.

Steps 3 and 5 of :mod:`ibvs_vision.detector`: each circle's object and the tests it must
pass, the area centroid of the marker's coverage (:mod:`.coverage`: rim pixels unmixed
against the local background, the notch of a rod in front of it filled from the symmetric
side), the disc test after the off-axis stretch, the centre without a band along the tool
axis, and the perspective shift between a sphere's silhouette centre and the projection of
its centre. Pure numpy/OpenCV.

Each circle's object is found on its own (:func:`find_object`: its window, contour and
tests), then every object of a stereo pair is refined at once (:func:`refine_candidates`):
their arrays side by side in one stack (:class:`.coverage._Tiles`), so that a pair costs
about as many numpy and OpenCV calls as one object, each on the object's box and a margin
(:data:`CROP_MARGIN`) rather than on its whole window. :func:`refine_circle`,
:func:`.coverage.coverage`, :func:`.coverage.symmetric_centre` and
:func:`axis_band_centre` are the same for one object.
"""

from dataclasses import dataclass, field
import math

import cv2
from ibvs_model import StereoIntrinsics
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .colour import colour_scores, ENCODINGS
from .config import DetectorConfig
from .coverage import _coverage, _KERNEL3, _symmetric_centres, _Tiles, PAD

#: OpenCV's conversion to RGB of each encoding that is not RGB already (a copy either way).
_TO_RGB = {'bgr8': cv2.COLOR_BGR2RGB, 'bgra8': cv2.COLOR_BGRA2RGB}
#: Steps of axis_band_centre.
AXIS_BAND_ITERATIONS = 4
#: Pixels around an object's bounding box that its refinement keeps (Candidate.crop): its
#: coverage reaches a pixel beyond the box, a rim pixel's background 2 px further, and the
#: mirror of a pixel (symmetric_centre) lands beyond the box by twice the centroid's
#: distance from the box's centre, which a round object keeps within 2.5 px.
CROP_MARGIN = 8


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


def median_u8(values: NDArray[np.uint8]) -> float:
    """
    Return the median of uint8 ``values``, as ``np.median`` gives it, from their histogram.

    The same float (the middle value, or the mean of the two middle ones) without the
    partial sort.

    Parameters
    ----------
    values : ndarray of uint8, shape (n,)
        The values, n > 0.

    Returns
    -------
    float
        Their median.

    """
    n = values.size
    if n == 0:
        return float(np.median(values))
    cumulative = np.cumsum(np.bincount(values, minlength=256))
    upper = int(np.searchsorted(cumulative, n // 2, side='right'))
    if n % 2:
        return float(upper)
    lower = int(np.searchsorted(cumulative, n // 2 - 1, side='right'))
    return (lower + upper) / 2.0


def rgb_window(window: NDArray[np.uint8], encoding: str) -> NDArray[np.uint8]:
    """
    Return the R, G, B planes of an image ``window`` in ``encoding`` as an (h, w, 3) array.

    An rgb8 window as it is (a view); the others reordered (and bgra8's alpha dropped) into
    a copy of the window alone.

    Parameters
    ----------
    window : ndarray of uint8, shape (h, w, 3 or 4)
        Pixels of an image, possibly a view into it.
    encoding : str
        A key of :data:`.colour.ENCODINGS`.

    Returns
    -------
    ndarray of uint8, shape (h, w, 3)
        The pixels in R, G, B order.

    """
    if encoding == 'rgb8':
        return window
    conversion = _TO_RGB.get(encoding)
    if conversion is not None:
        return cv2.cvtColor(window, conversion)
    return window[:, :, list(ENCODINGS[encoding])]


@dataclass(eq=False)
class Candidate:
    """
    A Hough circle's object, found and checked by :func:`find_object`, to be refined.

    ``k``: the marker; ``hough``: the circle (u, v, r); ``box``: the object's bounding box
    (x0, y0, x1, y1, inclusive) in the image; ``window``: the refinement window (x0, y0,
    x1, y1) in the image; ``crop``: the part of it refined, (x0, y0, x1, y1) in the window:
    the object's box and :data:`CROP_MARGIN` px around it (the coverage, and every
    centroid, is zero beyond); ``interior``, ``support``, ``linear``, ``rgb``: the crop's
    object (1 inside its outer contour) less a pixel all round (the object itself when that
    leaves nothing), the object grown by a pixel, the linear colour channel s and the R, G,
    B pixels; ``level``: the median s inside the object;
    ``contour``: its outer contour (window pixels); ``marker_rgb``: the marker's colour.
    """

    k: int
    hough: tuple
    box: tuple
    window: tuple
    crop: tuple
    interior: NDArray[np.uint8]
    support: NDArray[np.uint8]
    linear: NDArray[np.uint8]
    rgb: NDArray[np.uint8]
    level: float
    contour: NDArray[np.int32]
    marker_rgb: tuple


def refine_circle(image: NDArray[np.uint8], encoding: str, k: int, u: float, v: float,
                  r: float, bounds: tuple[int, int, int, int], config: DetectorConfig,
                  intrinsics: StereoIntrinsics | None = None
                  ) -> tuple[Blob | None, str | None, tuple[int, int, int, int] | None]:
    """
    Refine one Hough circle of marker k to the area centroid of the marker's coverage.

    :func:`find_object`, then :func:`refine_candidates` of the one candidate; the detector
    refines all the circles of a stereo pair together the same way.

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3 or 4)
        The whole image.
    encoding : str
        'rgb8', 'bgr8' or 'bgra8' (:data:`.colour.ENCODINGS`).
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
    candidate, why, box = find_object(image, encoding, k, u, v, r, bounds, config)
    if candidate is None:
        return None, why, box
    (blob, why), = refine_candidates([candidate], config, intrinsics)
    return blob, why, box


def find_object(image: NDArray[np.uint8], encoding: str, k: int, u: float, v: float,
                r: float, bounds: tuple[int, int, int, int], config: DetectorConfig
                ) -> tuple[Candidate | None, str | None, tuple[int, int, int, int] | None]:
    """
    Find the object of a Hough circle of marker k: the part of the refinement that is a test.

    The window of :func:`window_half` around the circle (inside ``bounds``), the outer
    contour of the marker-hue pixels (s_sel above half of ``min_colour_score``) that holds
    the circle's centre or comes nearest it, and the tests that need no coverage: the
    object must not touch the window (the image's border, the search window's, or a circle
    too small for it) and must be bright enough.

    Parameters
    ----------
    image, encoding, k, u, v, r, bounds, config
        As :func:`refine_circle`.

    Returns
    -------
    tuple
        (:class:`Candidate` or None, rejection reason or None, bounding box (x0, y0, x1,
        y1) of the object or None).

    """
    cfg = config
    half = window_half(r)
    iu, iv = int(round(u)), int(round(v))
    x0, y0 = max(iu - half, bounds[0]), max(iv - half, bounds[1])
    x1, y1 = min(iu + half + 1, bounds[2]), min(iv + half + 1, bounds[3])
    if x1 - x0 < 3 or y1 - y0 < 3:
        return None, 'too small', None
    window = image[y0:y1, x0:x1]
    linear, selective = colour_scores(window, cfg.marker_rgb[k], encoding)
    # The object: the outer contour of the marker-hue pixels around the circle's centre.
    binary = np.greater_equal(selective, 0.5 * cfg.min_colour_score).view(np.uint8)
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
    cx0, cy0 = max(bx - CROP_MARGIN, 0), max(by - CROP_MARGIN, 0)
    cx1, cy1 = min(bx + bw + CROP_MARGIN, width), min(by + bh + CROP_MARGIN, height)
    filled = np.zeros((cy1 - cy0, cx1 - cx0), np.uint8)
    cv2.drawContours(filled, [best], -1, 1, cv2.FILLED, offset=(-cx0, -cy0))
    linear = linear[cy0:cy1, cx0:cx1]
    level = median_u8(linear[filled.view(bool)])
    if level < cfg.min_colour_score:
        return None, 'too faint', box
    interior = cv2.erode(filled, _KERNEL3)
    if not cv2.countNonZero(interior):
        interior = filled
    return Candidate(k=k, hough=(u, v, r), box=box, window=(x0, y0, x1, y1),
                     crop=(cx0, cy0, cx1, cy1), interior=interior,
                     support=cv2.dilate(filled, _KERNEL3), linear=linear,
                     rgb=rgb_window(window[cy0:cy1, cx0:cx1], encoding), level=level,
                     contour=best, marker_rgb=tuple(cfg.marker_rgb[k])), None, box


def refine_candidates(candidates: list[Candidate], config: DetectorConfig,
                      intrinsics: StereoIntrinsics | None = None
                      ) -> list[tuple[Blob | None, str | None]]:
    """
    Refine candidates (:func:`find_object`) to their blobs, all at once.

    Each candidate's coverage (:func:`.coverage.coverage`), its area centroid, radius and shape
    (the second moments and the reach of its outline after the off-axis stretch is undone: not
    round enough, it is rejected) and its notch-filled centre (:func:`.coverage.symmetric_centre`).
    The work is done for all the candidates together, one array operation for all of them
    where the arithmetic is each pixel's own: the same numbers as one candidate at a time,
    the sums over the candidates' pixels up to their rounding.

    Parameters
    ----------
    candidates : list of Candidate
        The candidates, of any markers and images.
    config : DetectorConfig
        The tuning.
    intrinsics : StereoIntrinsics, optional
        Undo the off-axis stretch with them.

    Returns
    -------
    list of (Blob or None, str or None)
        Each candidate's blob, or None and why it was rejected, in order.

    """
    if not candidates:
        return []
    cfg = config
    tiles = _Tiles([c.interior.shape for c in candidates])
    cover = _coverage(tiles, [c.interior for c in candidates],
                      [c.support for c in candidates], [c.linear for c in candidates],
                      [c.rgb for c in candidates], [c.level for c in candidates],
                      [c.marker_rgb for c in candidates])
    # Image coordinates of each tile's columns and rows.
    left = np.array([c.window[0] + c.crop[0] - PAD for c in candidates], dtype=np.float64)
    top = np.array([c.window[1] + c.crop[1] - PAD for c in candidates], dtype=np.float64)
    xs = left[:, None] + np.arange(tiles.tw, dtype=np.float64)
    ys = top[:, None] + np.arange(tiles.th, dtype=np.float64)
    m00 = cover.sum(axis=(1, 2))
    columns, rows = cover.sum(axis=1), cover.sum(axis=2)
    cu = np.einsum('ij,ij->i', columns, xs) / m00
    cv = np.einsum('ij,ij->i', rows, ys) / m00
    direction, stretch = _line_of_sight_stretch(intrinsics, cu, cv)
    radius = np.sqrt(m00 / (math.pi * stretch))
    # Shape: second moments and the extent of the outline, the off-axis stretch undone.
    dx, dy = xs - cu[:, None], ys - cv[:, None]
    cov = np.empty((tiles.n, 2, 2))
    cov[:, 0, 0] = np.einsum('ij,ij->i', columns, dx ** 2) / m00
    cov[:, 1, 1] = np.einsum('ij,ij->i', rows, dy ** 2) / m00
    cov[:, 0, 1] = cov[:, 1, 0] = np.einsum('ij,ij->i', dy, np.matmul(
        cover, dx[:, :, None])[:, :, 0]) / m00
    squeeze = np.eye(2) + (1.0 / stretch - 1.0)[:, None, None] \
        * (direction[:, :, None] * direction[:, None, :])
    eig = np.linalg.eigvalsh(squeeze @ cov @ squeeze)
    roundness = np.where(eig[:, 1] > 0.0, eig[:, 0] / np.where(eig[:, 1] > 0.0, eig[:, 1], 1.0),
                         0.0)
    lengths = [len(c.contour) for c in candidates]
    owner = np.repeat(np.arange(tiles.n), lengths)
    points = np.concatenate([c.contour[:, 0, :] for c in candidates]).astype(np.float64)
    points += np.array([c.window[:2] for c in candidates], dtype=np.float64)[owner]
    points -= np.stack([cu, cv], axis=1)[owner]
    outline = np.einsum('ij,ijk->ik', points, squeeze[owner])
    reach = np.hypot(outline[:, 0], outline[:, 1])
    starts = np.cumsum([0] + lengths[:-1])
    reach_max, reach_min = np.maximum.reduceat(reach, starts), np.minimum.reduceat(reach, starts)
    out = []
    for i, c in enumerate(candidates):
        if radius[i] < 0.5 * cfg.hough_min_radius_px:
            out.append('too small')
        elif roundness[i] < cfg.min_roundness or reach_max[i] > 1.2 * radius[i] + 0.75 \
                or reach_min[i] < 0.8 * radius[i] - 1.25:
            out.append('not round (partly occluded?)')
        else:
            out.append(None)
    round_ = [i for i, why in enumerate(out) if why is None]
    origin_x = np.array([c.window[0] for c in candidates], dtype=np.float64)
    origin_y = np.array([c.window[1] for c in candidates], dtype=np.float64)
    centres = _symmetric_centres(tiles, cover, [c.crop for c in candidates],
                                 [(c.window[3] - c.window[1], c.window[2] - c.window[0])
                                  for c in candidates], cu - origin_x, cv - origin_y, m00,
                                 round_)
    results = []
    for i, c in enumerate(candidates):
        centre = centres.get(i)
        if out[i] is None and centre is None:
            out[i] = 'not round (partly occluded?)'
        if out[i] is not None:
            results.append((None, out[i]))
            continue
        # The cover kept: the object grown by a pixel, beyond which it is zero.
        x0, y0 = c.box[0] - 1, c.box[1] - 1
        tx, ty = x0 - c.window[0] - c.crop[0] + PAD, y0 - c.window[1] - c.crop[1] + PAD
        kept = cover[i, ty:ty + c.box[3] - c.box[1] + 3, tx:tx + c.box[2] - c.box[0] + 3]
        results.append((Blob(u=centre[0] + c.window[0], v=centre[1] + c.window[1],
                             radius=float(radius[i]), roundness=float(roundness[i]),
                             hough=c.hough, cover=kept, origin=(x0, y0)), None))
    return results


def _line_of_sight_stretch(intrinsics, u, v):
    """Return :func:`line_of_sight_stretch` of the arrays ``u``, ``v``: (n, 2), (n,)."""
    if intrinsics is None:
        return np.tile([1.0, 0.0], (len(u), 1)), np.ones(len(u))
    k = intrinsics
    x, y = (u - k.cu) / k.fu, (v - k.cv) / k.fv
    rho = np.hypot(x, y)
    far = rho > 1e-12
    safe = np.where(far, rho, 1.0)
    direction = np.where(far[:, None], np.stack([x / safe, y / safe], axis=1), [1.0, 0.0])
    return direction, np.sqrt(1.0 + rho * rho)


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
    (:func:`.coverage.symmetric_centre`) then copies the other end's error. Weighting out a
    band of half-width ``half_width`` about the line through the current centre along
    ``direction`` removes both ends at once and keeps the rest point-symmetric about the
    ellipse's centre, whose centroid is therefore still that centre: iterated from the
    blob's centre, each step moves towards it. The band's edge is a one-pixel ramp (a hard
    edge would make the result depend on the centre's sub-pixel position).
    (:func:`axis_band_centres` takes several blobs at once.)

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
    return axis_band_centres([blob], [direction], [half_width], iterations)[0]


def axis_band_centres(blobs: list[Blob], directions: list[ArrayLike],
                      half_widths: list[float], iterations: int = AXIS_BAND_ITERATIONS
                      ) -> list[tuple[float, float]]:
    """
    Return :func:`axis_band_centre` of each blob, all at once.

    Parameters
    ----------
    blobs : list of Blob
        The blobs.
    directions : list of array_like, shape (2,)
        Each one's tool-axis direction.
    half_widths : list of float
        Each one's band half-width (px).
    iterations : int
        Steps from each blob's centre.

    Returns
    -------
    list of (float, float)
        The centres (u, v) in the image (px), in order.

    """
    out = [(b.u, b.v) for b in blobs]
    use = [i for i, b in enumerate(blobs) if b.cover is not None]
    if not use or iterations < 1:
        return out
    tiles = _Tiles([blobs[i].cover.shape for i in use])
    cover = tiles.empty(np.float64)
    for j, i in enumerate(use):
        tiles.put(cover, j, blobs[i].cover)
    xs = np.array([blobs[i].origin[0] - PAD for i in use], dtype=np.float64)[:, None] \
        + np.arange(tiles.tw, dtype=np.float64)
    ys = np.array([blobs[i].origin[1] - PAD for i in use], dtype=np.float64)[:, None] \
        + np.arange(tiles.th, dtype=np.float64)
    d = np.empty((len(use), 2))
    for j, i in enumerate(use):
        d[j] = np.asarray(directions[i], dtype=np.float64)
        d[j] /= math.hypot(d[j, 0], d[j, 1])
    half = np.asarray([half_widths[i] for i in use], dtype=np.float64)[:, None, None]
    cu = np.array([blobs[i].u for i in use], dtype=np.float64)
    cv = np.array([blobs[i].v for i in use], dtype=np.float64)
    weighted = np.empty_like(cover)
    active = list(range(len(use)))
    for _ in range(iterations):
        # Distance of each pixel centre from the line through (cu, cv) along d.
        np.subtract(((ys - cv[:, None]) * d[:, 0:1])[:, :, None],
                    ((xs - cu[:, None]) * d[:, 1:2])[:, None, :], out=weighted)
        np.abs(weighted, out=weighted)
        weighted -= half
        weighted += 0.5
        np.clip(weighted, 0.0, 1.0, out=weighted)
        weighted *= cover
        total = weighted.sum(axis=(1, 2))
        with np.errstate(invalid='ignore', divide='ignore'):
            nu = np.einsum('ij,ij->i', weighted.sum(axis=1), xs) / total
            nv = np.einsum('ij,ij->i', weighted.sum(axis=2), ys) / total
        still = []
        for j in active:
            i = use[j]
            if total[j] <= 0.0:
                out[i] = (blobs[i].u, blobs[i].v)
            elif (float(nu[j]), float(nv[j])) == (cu[j], cv[j]):
                out[i] = (float(cu[j]), float(cv[j]))  # a fixed point
            else:
                cu[j], cv[j] = nu[j], nv[j]
                still.append(j)
                out[i] = (float(cu[j]), float(cv[j]))
        active = still
        if not active:
            break
    return out
