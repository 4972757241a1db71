"""
The marker's coverage of each pixel, and its centre with a rod's notches filled.

Step 3 of :mod:`ibvs_vision.detector`: inside an object the marker covers a pixel whole;
each rim pixel p is unmixed as p = x m + y b (m the marker's colour at any brightness, b the
local background's), its coverage 1 - y (:func:`coverage`); the notch that a rod in front
of the marker cuts into that coverage is filled from the point-symmetric side of the
ellipse before its centroid is taken (:func:`symmetric_centre`). Pure numpy/OpenCV.

:func:`.refine.refine_candidates` takes every object of a stereo pair at once, their arrays
side by side in one stack (:class:`_Tiles`, each within a border of :data:`PAD` px), one
numpy or OpenCV call for all of them; :func:`coverage` and :func:`symmetric_centre` are
the same for one object.
"""

from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

_KERNEL3 = np.ones((3, 3), np.uint8)
_KERNEL5 = np.ones((5, 5), np.uint8)
#: Notch filling of symmetric_centre: a pixel is in a notch when its coverage is this much
#: below the mirrored one; at most this share of the area may be filled; iterations.
NOTCH_COVERAGE = 0.3
NOTCH_SHARE = 0.1
NOTCH_ITERATIONS = 3
NOTCH_EDGE = 0.05
#: Border of each array of a _Tiles stack: a 5 x 5 filter stays within its tile.
PAD = 3


class _Tiles:
    """
    Several 2-D arrays of different sizes side by side, for one numpy or OpenCV call each.

    Tile i holds an (h_i, w_i) array at rows and columns [PAD, PAD + h_i) x [PAD, PAD +
    w_i) of a (TH, TW) block, the blocks stacked as one (n TH, TW) image: a filter up to
    5 x 5 (and a mirror no farther than PAD outside an array) stays within its tile.
    ``shapes``: (h_i, w_i) of each.
    """

    def __init__(self, shapes):
        self.shapes = shapes
        self.n = len(shapes)
        self.th = max(h for h, _ in shapes) + 2 * PAD
        self.tw = max(w for _, w in shapes) + 2 * PAD

    def empty(self, dtype, channels=None):
        """Return a zero stack of ``dtype`` (n, TH, TW[, channels])."""
        shape = (self.n, self.th, self.tw) + (() if channels is None else (channels,))
        return np.zeros(shape, dtype)

    def put(self, stack, i, array, pad=0):
        """Put ``array`` (tile i's, ``pad`` px of border around it) into ``stack``."""
        h, w = self.shapes[i]
        stack[i, PAD - pad:PAD + h + pad, PAD - pad:PAD + w + pad] = array

    def get(self, stack, i):
        """Return tile i's array of ``stack`` (a view)."""
        h, w = self.shapes[i]
        return stack[i, PAD:PAD + h, PAD:PAD + w]

    @staticmethod
    def flat(stack):
        """Return ``stack`` as one image (n TH, TW[, channels]), a view."""
        return stack.reshape((-1,) + stack.shape[2:])


def _coverage(tiles, interiors, supports, linears, rgbs, levels, colours):
    """
    Return the coverage (:func:`coverage`) of each tile's object, as a stack of ``tiles``.

    ``interiors``, ``supports``, ``linears``, ``rgbs``: each object's arrays (as
    :class:`.refine.Candidate` holds them); ``levels``, ``colours``: its median s and its
    marker's colour. The box sums of the background are sums of whole numbers in float32,
    the same in any order, and each rim pixel's arithmetic is its own: the same coverage as
    one object at a time.
    """
    n = tiles.n
    interior, support, linear = (tiles.empty(np.uint8) for _ in range(3))
    outside, rgb = tiles.empty(np.float32), tiles.empty(np.uint8, 3)
    for i in range(n):
        tiles.put(interior, i, interiors[i])
        tiles.put(support, i, supports[i])
        tiles.put(linear, i, linears[i])
        # Beyond an array's edge its pixels mirrored, as cv2.boxFilter reads the window.
        tiles.put(outside, i, cv2.copyMakeBorder(
            np.subtract(1.0, supports[i], dtype=np.float32), 2, 2, 2, 2,
            cv2.BORDER_REFLECT_101), pad=2)
        tiles.put(rgb, i, cv2.copyMakeBorder(np.ascontiguousarray(rgbs[i]), 2, 2, 2, 2,
                                             cv2.BORDER_REFLECT_101), pad=2)
    cover = interior.astype(np.float64)
    # The rim's pixels by their flat index, in the order a boolean mask takes them.
    rim = np.flatnonzero(np.greater(support, interior))
    if not rim.size:
        return cover
    owner = rim // (tiles.th * tiles.tw)
    count = cv2.boxFilter(_Tiles.flat(outside), -1, (5, 5), normalize=False)
    weighted = rgb.astype(np.float32)
    weighted *= outside[..., None]
    back = cv2.boxFilter(_Tiles.flat(weighted), -1, (5, 5), normalize=False)
    level = np.asarray(levels, dtype=np.float64)[owner]
    local = cv2.dilate(_Tiles.flat(linear * interior), _KERNEL5).take(rim).astype(np.float64)
    low = local < 0.5 * level
    local[low] = level[low]
    fallback = np.clip(linear.take(rim) / local, 0.0, 1.0)
    pix = rgb.reshape(-1, 3)[rim].astype(np.float64)
    count = count.take(rim).astype(np.float64)
    b = back.reshape(-1, 3)[rim].astype(np.float64) / np.maximum(count, 1.0)[:, None]
    # Each rim pixel p = x m + y b (module docstring of coverage), m its marker's colour.
    a11, a12, b1 = np.empty(rim.size), np.empty(rim.size), np.empty(rim.size)
    kinds = {colour: j for j, colour in enumerate(dict.fromkeys(tuple(c) for c in colours))}
    kind = np.array([kinds[tuple(c)] for c in colours])[owner]
    for colour, j in kinds.items():
        rows = kind == j
        m = np.asarray(colour, dtype=np.float64)
        a11[rows] = m @ m
        a12[rows] = b[rows] @ m
        b1[rows] = pix[rows] @ m
    a22 = np.einsum('ij,ij->i', b, b)
    b2 = np.einsum('ij,ij->i', b, pix)
    det = a11 * a22 - a12 * a12
    good = (count > 0) & (det > 0.05 * a11 * np.maximum(a22, 1e-9)) & (a22 > 100.0)
    y = np.where(good, (a11 * b2 - a12 * b1) / np.where(good, det, 1.0), 0.0)
    cover.put(rim, np.where(good, np.clip(1.0 - y, 0.0, 1.0), fallback))
    return cover


def coverage(patch: NDArray[np.uint8], filled: NDArray[np.uint8], linear: NDArray[np.uint8],
             level: float, marker_rgb: ArrayLike) -> NDArray[np.float64]:
    """
    Return the fraction of each pixel of an RGB ``patch`` covered by the marker.

    Pixels inside the object (``filled`` eroded) count 1, pixels two or more pixels
    outside count 0. A rim pixel p is unmixed as p = x * m + y * b, with m the marker's
    colour (any brightness: shading only scales x) and b the mean colour of the background
    pixels within 2 px; its coverage is 1 - y. Where m and b are nearly parallel (a dark
    background) it falls back to s / (level of the interior pixels next to it), s being
    the linear colour channel. (:func:`.refine.refine_candidates` takes several objects at
    once.)

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
    if not cv2.countNonZero(interior):
        interior = filled
    tiles = _Tiles([filled.shape])
    cover = _coverage(tiles, [interior], [cv2.dilate(filled, _KERNEL3)], [linear], [patch],
                      [level], [tuple(np.asarray(marker_rgb, dtype=np.float64))])
    return tiles.get(cover, 0).copy()


def _symmetric_centres(tiles, cover, crops, windows, cx, cy, area, which):
    """
    Return {i: centre (x, y) in its window, or None} of the tiles ``which`` of ``cover``.

    :func:`symmetric_centre` of each: tile i is the part ``crops[i]`` (x0, y0, x1, y1) of a
    window of shape ``windows[i]`` whose coverage is zero elsewhere; (cx[i], cy[i]) its
    area centroid in the window, ``area[i]`` its sum. Each mirror image is OpenCV's of the
    whole window, as one object at a time; the sums are over the tiles.
    """
    cover32 = cover.astype(np.float32)
    mirrored = tiles.empty(np.float32)
    columns = np.array([c[0] - PAD for c in crops], dtype=np.float64)[:, None] \
        + np.arange(tiles.tw, dtype=np.float64)
    rows = np.array([c[1] - PAD for c in crops], dtype=np.float64)[:, None] \
        + np.arange(tiles.th, dtype=np.float64)
    cx, cy = [float(x) for x in cx], [float(y) for y in cy]
    sources, result, active = {}, {}, list(which)
    for _ in range(NOTCH_ITERATIONS):
        if not active:
            break
        for i in active:
            x0, y0, x1, y1 = crops[i]
            source = sources.get(i)
            if source is None:
                source = sources[i] = np.zeros(windows[i], np.float32)
                source[y0:y1, x0:x1] = tiles.get(cover32, i)
            xs, ys = _window_grid(x0, y0, x1, y1)
            tiles.put(mirrored, i, cv2.remap(source, np.float32(2.0 * cx[i]) - xs,
                                             np.float32(2.0 * cy[i]) - ys, cv2.INTER_LINEAR,
                                             borderMode=cv2.BORDER_CONSTANT, borderValue=0.0))
        short = mirrored - cover32
        notch = short > NOTCH_COVERAGE
        # The rod's edges cover pixels partly: next to a notch, any shortfall counts.
        notch |= (cv2.dilate(_Tiles.flat(notch.view(np.uint8)), _KERNEL3).reshape(notch.shape)
                  > 0) & (short > NOTCH_EDGE)
        filled = np.where(notch, mirrored, cover32).astype(np.float64)
        by_column, by_row = filled.sum(axis=1), filled.sum(axis=2)
        total = by_row.sum(axis=1)
        with np.errstate(invalid='ignore', divide='ignore'):
            nx = np.einsum('ij,ij->i', by_column, columns) / total
            ny = np.einsum('ij,ij->i', by_row, rows) / total
        still = []
        for i in active:
            if total[i] - area[i] > NOTCH_SHARE * area[i]:  # what the notches filled
                result[i] = None
            elif (float(nx[i]), float(ny[i])) == (cx[i], cy[i]):
                result[i] = (cx[i], cy[i])  # a fixed point: every further step gives it
            else:
                cx[i], cy[i] = float(nx[i]), float(ny[i])
                still.append(i)
        active = still
    for i in active:
        result[i] = (cx[i], cy[i])
    return result


@lru_cache(maxsize=256)
def _window_grid(x0, y0, x1, y1):
    """Return the float32 x and y of the window pixels [x0, x1) x [y0, y1) (read-only)."""
    xs, ys = np.meshgrid(np.arange(x0, x1, dtype=np.float32),
                         np.arange(y0, y1, dtype=np.float32))
    xs.flags.writeable = ys.flags.writeable = False
    return xs, ys


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
    rod across it, but one partly hidden. (:func:`.refine.refine_candidates` takes several
    at once.)

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
    tiles = _Tiles([cover.shape])
    stack = tiles.empty(np.float64)
    tiles.put(stack, 0, cover)
    return _symmetric_centres(tiles, stack, [(0, 0, width, height)], [cover.shape], [cx],
                              [cy], [area], [0])[0]
