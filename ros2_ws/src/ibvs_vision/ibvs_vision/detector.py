"""
Hough detector of the two spherical fiducials in a rectified stereo pair (section 2.2, eq. 2-3).

Per image and per marker colour (:data:`ibvs_model.scene.MARKER_RGB`: marker 1 red,
marker 2 blue):

1. **Colour channels.** s = C_d - max(other two channels), C_d the marker's dominant
   channel (red: R - max(G, B)); grey, white and black give s ~ 0. The hue-selective
   s_sel = C_d - gamma max(others), gamma = clip(C_d / (2 max(others)), 1, 3) of the
   marker colour, is also 0 for nearby hues (orange for red). Both scale with brightness.
2. **Hough transform** (section 2.2, Figure 2): ``cv2.HoughCircles`` (HOUGH_GRADIENT) on
   s_sel gives circle candidates (centre on a 0.5 px grid, radius). It runs on the whole
   image, restricted to the 8 x 8 blocks where the marker's hue is present (grown by the
   largest radius), which finds the same circles in a fraction of the time.
3. **Sub-pixel refinement.** Around each circle, the outer contour of the marker-hue pixels
   (s_sel above half of ``min_score``) is the object, holes (highlights) filled. Its
   interior pixels count 1; each rim pixel p is unmixed as p = x * m + y * b (m the marker
   colour at any brightness, b the mean background colour just outside), so that its
   coverage 1 - y does not depend on the shading of the sphere. The centre is the area
   centroid of the coverage (image moments): the centre of the silhouette, free of the
   Hough grid. A candidate is rejected if it touches the image border, is too faint, or
   if its second moments or outline are not those of a disc (partly occluded), after
   taking out the radial stretch 1 / cos(theta) of a sphere seen off-axis. A thin rod in
   front of the marker (the tool's shaft, link 6's quill) cuts a notch into the outline;
   the notch is filled from the point-symmetric side of the ellipse before the centroid is
   taken (:func:`_symmetric_centre`; at the target pose this takes the vertical bias from
   0.07-0.09 px to under 0.01 px, and the implied tool-axis error from 0.16 to 0.06 deg).
4. **Stereo pairing** by the epipolar constraint of a rectified pair: same v within a
   tolerance, positive disparity u_l - u_r (ROS signs, DESIGN section 5: the left lens at
   x = -b/2 of {C}), and radii that agree with each other and with the depth given by the
   disparity (a sphere of radius R at depth Z = f_u b / d has an image radius
   f_u R / Z = R d / b).
5. **Perspective correction.** A sphere projects to an ellipse whose centre is not the
   projection of the sphere's centre: with the silhouette cone of a sphere of radius R
   at depth Z, the ellipse centre is c + (p - c) / (1 - (R / Z)^2) for the principal
   point c and the centre projection p (exact for a pinhole, derived from the cone's
   conic). At HD720 this is up to 0.2 px at the image edge for a marker 2 m away, so it
   is undone with Z from the disparity (intrinsics needed; skipped without them).

The result is p_I = [u_l1, u_r1, v1, u_l2, u_r2, v2] (eq. 2-3, 21-22), v the mean of the
left and right v, or a :class:`Reason` why not. Pure numpy/OpenCV, no ROS.
"""

from dataclasses import dataclass, field
import enum
import math

import cv2
from ibvs_model import StereoIntrinsics
from ibvs_model.camera import merge_windows
from ibvs_model.scene import MARKER_RADIUS_M, MARKER_RGB
import numpy as np

#: Channel order of the supported 8-bit colour encodings (ROS sensor_msgs names).
ENCODINGS = {'rgb8': (0, 1, 2), 'bgr8': (2, 1, 0)}

MARKER_NAMES = ('marker 1 (P1)', 'marker 2 (P2)')

_KERNEL3 = np.ones((3, 3), np.uint8)
_KERNEL5 = np.ones((5, 5), np.uint8)
_BLOCK = 8  # = 2 ** 3, see _hot_regions
_MAX_REGIONS = 12
#: Notch filling of _symmetric_centre: a pixel is in a notch when its coverage is this much
#: below the mirrored one; at most this share of the area may be filled; iterations.
NOTCH_COVERAGE = 0.3
NOTCH_SHARE = 0.1
NOTCH_ITERATIONS = 3
NOTCH_EDGE = 0.05


class Reason(enum.Enum):
    """Why a stereo pair gives no measured p_I."""

    NOT_IN_VIEW = 'not in view'
    MARKER_MISSING = 'marker missing'
    AMBIGUOUS = 'ambiguous'
    EPIPOLAR_MISMATCH = 'epipolar mismatch'


@dataclass(frozen=True)
class DetectorConfig:
    """
    Tuning of the detector; every field is a node parameter of the same name.

    Radii are image radii in pixels of the full-resolution image. ``canny_high`` and
    ``votes`` are ``cv2.HoughCircles``' param1 (upper Canny threshold on the colour
    channel) and param2 (accumulator votes a centre needs).
    """

    min_radius_px: int = 2
    max_radius_px: int = 40
    canny_high: float = 60.0
    votes: int = 6
    min_score: float = 25.0
    max_candidates: int = 6
    min_fill: float = 0.8
    min_roundness: float = 0.6
    epipolar_tolerance_px: float = 1.5
    radius_tolerance: float = 0.3
    roi_margin_px: int = 40
    marker_radius_m: float = MARKER_RADIUS_M
    marker_rgb: tuple = MARKER_RGB

    def __post_init__(self):
        """Reject values that make the detector meaningless (ValueError names the field)."""
        checks = (
            ('min_radius_px', 1 <= self.min_radius_px <= 200),
            ('max_radius_px', self.min_radius_px < self.max_radius_px <= 1000),
            ('canny_high', 1.0 <= self.canny_high <= 1000.0),
            ('votes', 1 <= self.votes <= 1000),
            ('min_score', 1.0 <= self.min_score <= 255.0),
            ('max_candidates', 1 <= self.max_candidates <= 100),
            ('min_fill', 0.0 < self.min_fill <= 1.0),
            ('min_roundness', 0.0 < self.min_roundness <= 1.0),
            ('epipolar_tolerance_px', 0.0 < self.epipolar_tolerance_px <= 100.0),
            ('radius_tolerance', 0.0 < self.radius_tolerance <= 10.0),
            ('roi_margin_px', 0 <= self.roi_margin_px <= 10000),
            ('marker_radius_m', 0.0 < self.marker_radius_m < 1.0),
        )
        for name, ok in checks:
            if not ok:
                raise ValueError(
                    f'DetectorConfig.{name} = {getattr(self, name)!r} is out of range')
        rgb = np.asarray(self.marker_rgb, dtype=float)
        if rgb.shape != (2, 3) or len({int(np.argmax(c)) for c in rgb}) != 2 \
                or any(_score_of(c) <= 0.0 for c in rgb):
            raise ValueError('DetectorConfig.marker_rgb needs two colours with distinct '
                             f'dominant channels, got {self.marker_rgb!r}')


def _score_of(rgb):
    rgb = np.asarray(rgb, dtype=float)
    d = int(np.argmax(rgb))
    return rgb[d] - max(rgb[i] for i in range(3) if i != d)


@dataclass(frozen=True)
class _Colour:
    """Dominant channel d, the other two, and the selectivity gamma of one marker colour."""

    d: int
    others: tuple
    gamma: float

    @classmethod
    def of(cls, rgb):
        rgb = np.asarray(rgb, dtype=float)
        d = int(np.argmax(rgb))
        others = tuple(i for i in range(3) if i != d)
        top = max(rgb[others[0]], rgb[others[1]], 1.0)
        return cls(d, others, float(np.clip(0.5 * rgb[d] / top, 1.0, 3.0)))


def colour_scores(image, rgb, encoding='rgb8'):
    """
    Return the uint8 channels (s, s_sel) of marker colour ``rgb`` in an (H, W, 3) image.

    s = C_d - max(others) is linear in the colour (used for the coverage);
    s_sel = C_d - gamma * max(others), gamma = clip(C_d / (2 max(others)), 1, 3) of the
    marker colour, is also zero for nearby hues (orange for red; used for the Hough
    transform and to accept a disc). Both saturate at 0. ``image`` may be a view.
    """
    order = ENCODINGS[encoding]
    colour = _Colour.of(rgb)
    planes = cv2.split(image)
    top = cv2.max(planes[order[colour.others[0]]], planes[order[colour.others[1]]])
    dominant = planes[order[colour.d]]
    return (cv2.subtract(dominant, top),
            cv2.addWeighted(dominant, 1.0, top, -colour.gamma, 0.0))


def silhouette_to_centre(u, v, depth, intrinsics, radius_m):
    """
    Return the projection of a sphere's centre from the centre of its silhouette ellipse.

    The silhouette of a sphere of radius R whose centre is at depth Z is the conic
    x^T (d d^T - (|d|^2 - R^2) I) x = 0 (d: the centre in the lens frame); its centre is
    d_xy d_z / (d_z^2 - R^2), i.e. (ellipse centre - c) = (centre projection - c) /
    (1 - (R / Z)^2) about the principal point c. This inverts that radial stretch.
    """
    k = 1.0 - (radius_m / depth) ** 2
    return (intrinsics.cu + (np.asarray(u) - intrinsics.cu) * k,
            intrinsics.cv + (np.asarray(v) - intrinsics.cv) * k)


def centre_to_silhouette(u, v, depth, intrinsics, radius_m):
    """Return the silhouette ellipse centre of a sphere whose centre projects to (u, v)."""
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
    """

    u: float
    v: float
    radius: float
    roundness: float
    hough: tuple


@dataclass
class ImageDetections:
    """Refined candidates of both markers in one image and what was rejected, by reason."""

    blobs: tuple = ((), ())
    rejected: dict = field(default_factory=dict)


@dataclass(frozen=True)
class StereoDetection:
    """
    Result of one stereo pair: ``features`` p_I (6,) or None with a ``reason``.

    ``detail`` says which marker and which image; ``left``/``right`` keep the candidates
    (for diagnostics and tests); ``search`` is 'roi' or 'full'.
    """

    features: np.ndarray = None
    reason: Reason = None
    detail: str = ''
    left: ImageDetections = None
    right: ImageDetections = None
    search: str = 'full'

    @property
    def ok(self):
        """Return True when p_I was measured."""
        return self.features is not None


class StereoDetector:
    """
    Detect both fiducials in a rectified stereo pair and return p_I (eq. 2-3).

    ``intrinsics`` (:class:`ibvs_model.StereoIntrinsics`, from CameraInfo) enables the
    perspective correction and the off-axis stretch; without them the silhouette centres
    are returned.
    """

    def __init__(self, intrinsics=None, config=None):
        """Keep the intrinsics and the :class:`DetectorConfig` (default if None)."""
        if intrinsics is not None and not isinstance(intrinsics, StereoIntrinsics):
            raise TypeError('intrinsics must be a StereoIntrinsics or None')
        self.intrinsics = intrinsics
        self.config = config if config is not None else DetectorConfig()
        self._colours = tuple(_Colour.of(rgb) for rgb in self.config.marker_rgb)
        self._buffers = {}

    # --- one image -------------------------------------------------------------------

    def detect_image(self, image, encoding='rgb8', rois=None):
        """
        Return :class:`ImageDetections` of both markers in one (H, W, 3) uint8 image.

        ``rois`` is None (search the whole image) or, per marker, None or a window
        (x0, y0, x1, y1) to search instead.
        """
        _check_image(image, encoding)
        cfg = self.config
        result = ImageDetections(blobs=([], []), rejected={})
        full = None
        for k, rgb in enumerate(cfg.marker_rgb):
            roi = None if rois is None else rois[k]
            if roi is None:
                if full is None:
                    full = self._selective(image, encoding)
                regions = [(full[k][y0:y1, x0:x1], (x0, y0, x1, y1))
                           for x0, y0, x1, y1 in self._hot_regions(full[k])]
            else:
                x0, y0, x1, y1 = roi
                regions = [(colour_scores(image[y0:y1, x0:x1], rgb, encoding)[1], roi)]
            for score, bounds in regions:
                x0, y0 = bounds[:2]
                seen = []  # boxes (x0, y0, x1, y1) of the objects refined so far
                for u, v, r in self._hough(score):
                    u, v = u + x0, v + y0
                    # Several circles on one object: refine it once.
                    if any(a <= u <= c and b <= v <= d for a, b, c, d in seen):
                        continue
                    blob, why, box = self._refine(image, encoding, k, u, v, r, bounds)
                    if box is not None:
                        seen.append(box)
                    if blob is None:
                        key = f'{MARKER_NAMES[k]}: {why}'
                        result.rejected[key] = result.rejected.get(key, 0) + 1
                    elif not any(abs(b.u - blob.u) < 0.5 and abs(b.v - blob.v) < 0.5
                                 for b in result.blobs[k]):
                        result.blobs[k].append(blob)
        result.blobs = tuple(tuple(b) for b in result.blobs)
        return result

    def _buffer(self, name, shape):
        """
        Return a reusable uint8 array for a whole-image intermediate.

        Fresh arrays of a megabyte come from mmap and cost a page fault per 4 kB page on
        first touch (measured: 2.6 ms for cv2.split of an HD720 image instead of 0.15 ms);
        keeping them makes the cost independent of the allocator's state. A detector is
        therefore not to be shared between threads.
        """
        buf = self._buffers.get(name)
        if buf is None or buf.shape != shape:
            buf = self._buffers[name] = np.empty(shape, np.uint8)
        return buf

    def _selective(self, image, encoding):
        """Return s_sel of both markers over the whole image, splitting the planes once."""
        order = ENCODINGS[encoding]
        shape = image.shape[:2]
        planes = cv2.split(image, [self._buffer(f'plane{i}', shape) for i in range(3)])
        planes = [planes[order[i]] for i in range(3)]
        top = self._buffer('top', shape)
        scores = []
        for k, colour in enumerate(self._colours):
            cv2.max(planes[colour.others[0]], planes[colour.others[1]], dst=top)
            scores.append(cv2.addWeighted(planes[colour.d], 1.0, top, -colour.gamma, 0.0,
                                          dst=self._buffer(f'score{k}', shape)))
        return scores

    def _hot_regions(self, score):
        """
        Return the windows (x0, y0, x1, y1) of ``score`` where the Hough transform can matter.

        A circle is only accepted where the marker's colour is (s_sel >= min_score / 2, as
        in :meth:`_refine`), so the transform runs on the blocks of 8 x 8 pixels that hold
        enough such pixels, grown by the largest radius and merged: the same circles as on
        the whole image, for a fraction of the time. Many scattered blocks (clutter) give
        the whole image.
        """
        cfg = self.config
        height, width = score.shape
        bw, bh = -(-width // _BLOCK), -(-height // _BLOCK)
        hot = self._buffer('hot', (bh * _BLOCK, bw * _BLOCK))
        hot[height:], hot[:, width:] = 0, 0
        cv2.threshold(score, 0.5 * cfg.min_score - 1e-3, 255, cv2.THRESH_BINARY,
                      dst=hot[:height, :width])
        # Mean of each block as a share of 255, by three 2 x 2 averages (OpenCV's fast path).
        means = hot
        for level in range(3):
            half = self._buffer(f'half{level}', (means.shape[0] // 2, means.shape[1] // 2))
            means = cv2.resize(means, (half.shape[1], half.shape[0]), dst=half,
                               interpolation=cv2.INTER_AREA)
        min_pixels = min(0.25 * math.pi * cfg.min_radius_px ** 2, 0.5 * _BLOCK * _BLOCK)
        blocks = (means >= 255.0 * min_pixels / (_BLOCK * _BLOCK) - 0.5).astype(np.uint8)
        n, _, stats, _ = cv2.connectedComponentsWithStats(blocks, connectivity=8)
        if n - 1 > _MAX_REGIONS:
            return [(0, 0, width, height)]
        grow = 2 * cfg.max_radius_px + 8
        boxes = []
        for x, y, w, h, _ in stats[1:]:
            boxes.append([max(0, x * _BLOCK - grow), max(0, y * _BLOCK - grow),
                          min(width, (x + w) * _BLOCK + grow),
                          min(height, (y + h) * _BLOCK + grow)])
        return merge_windows(boxes)

    def _hough(self, score):
        cfg = self.config
        h, w = score.shape
        if min(h, w) < 2 * cfg.min_radius_px + 3:
            return []
        # A light blur keeps the gradient of a small disc whole where a highlight dents it.
        circles = cv2.HoughCircles(cv2.GaussianBlur(score, (3, 3), 0), cv2.HOUGH_GRADIENT,
                                   dp=1,
                                   minDist=max(4.0, 2.0 * cfg.min_radius_px),
                                   param1=cfg.canny_high, param2=cfg.votes,
                                   minRadius=cfg.min_radius_px, maxRadius=cfg.max_radius_px)
        if circles is None:
            return []
        return [tuple(float(x) for x in c) for c in circles[0, :cfg.max_candidates]]

    def _stretch(self, u, v):
        """Return (unit radial direction, 1/cos(theta)) of the line of sight through (u, v)."""
        k = self.intrinsics
        if k is None:
            return np.array([1.0, 0.0]), 1.0
        x, y = (u - k.cu) / k.fu, (v - k.cv) / k.fv
        rho = math.hypot(x, y)
        direction = np.array([x, y]) / rho if rho > 1e-12 else np.array([1.0, 0.0])
        return direction, math.sqrt(1.0 + rho * rho)

    def _refine(self, image, encoding, k, u, v, r, bounds):
        """
        Refine one Hough circle of marker k to the area centroid of the marker's coverage.

        (u, v, r) is the circle in full-image pixels; the window used stays inside
        ``bounds`` (x0, y0, x1, y1). Returns (:class:`Blob` or None, rejection reason or None,
        bounding box (x0, y0, x1, y1) of the object in the image or None).
        """
        cfg = self.config
        half = int(math.ceil(2.0 * r + 6.0))
        iu, iv = int(round(u)), int(round(v))
        x0, y0 = max(iu - half, bounds[0]), max(iv - half, bounds[1])
        x1, y1 = min(iu + half + 1, bounds[2]), min(iv + half + 1, bounds[3])
        if x1 - x0 < 3 or y1 - y0 < 3:
            return None, 'too small', None
        linear, selective = colour_scores(image[y0:y1, x0:x1], cfg.marker_rgb[k], encoding)
        # The object: the outer contour of the marker-hue pixels around the circle's centre.
        binary = (selective >= 0.5 * cfg.min_score).astype(np.uint8)
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
        if level < cfg.min_score:
            return None, 'too faint', box
        patch = image[y0:y1, x0:x1]
        if encoding != 'rgb8':
            patch = patch[:, :, list(ENCODINGS[encoding])]
        cover = _coverage(patch, filled, linear, level, cfg.marker_rgb[k])
        m00 = float(cover.sum())
        xs = np.arange(x0, x1, dtype=np.float64)
        ys = np.arange(y0, y1, dtype=np.float64)
        cu = float(cover.sum(axis=0) @ xs) / m00
        cv = float(cover.sum(axis=1) @ ys) / m00
        direction, stretch = self._stretch(cu, cv)
        radius = math.sqrt(m00 / (math.pi * stretch))
        if radius < 0.5 * cfg.min_radius_px:
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
        centre = _symmetric_centre(cover, cu - x0, cv - y0, m00)
        if centre is None:
            return None, 'not round (partly occluded?)', box
        cu, cv = centre[0] + x0, centre[1] + y0
        return Blob(u=cu, v=cv, radius=radius, roundness=roundness, hough=(u, v, r)), None, box

    # --- stereo ------------------------------------------------------------------------

    def detect(self, left, right, encoding='rgb8', prior=None):
        """
        Return the :class:`StereoDetection` of a rectified pair of (H, W, 3) uint8 images.

        ``prior`` (optional) is a predicted p_I (6,), e.g. the last measurement or F(q_T):
        both images are first searched in windows of ``roi_margin_px`` around it; if that
        does not give both markers, the whole images are searched.
        """
        if left.shape != right.shape:
            raise ValueError(f'left and right images differ in size: {left.shape} vs '
                             f'{right.shape}')
        if prior is not None and self.config.roi_margin_px > 0:
            rois = self._rois(prior, left.shape)
            if rois is not None:
                result = self._detect_pair(left, right, encoding, rois, 'roi')
                if result.ok:
                    return result
        return self._detect_pair(left, right, encoding, None, 'full')

    def _rois(self, prior, shape):
        prior = np.asarray(prior, dtype=float)
        if prior.shape != (6,) or not np.all(np.isfinite(prior)):
            return None
        height, width = shape[:2]
        m = self.config.roi_margin_px + self.config.max_radius_px // 2 + 4
        rois = ([], [])
        for k in range(2):
            u_l, u_r, v = prior[3 * k:3 * k + 3]
            for side, u in enumerate((u_l, u_r)):
                x0, y0 = max(0, int(u) - m), max(0, int(v) - m)
                x1, y1 = min(width, int(u) + m + 1), min(height, int(v) + m + 1)
                if x1 - x0 < 8 or y1 - y0 < 8:
                    return None
                rois[side].append((x0, y0, x1, y1))
        return rois

    def _detect_pair(self, left, right, encoding, rois, search):
        det_l = self.detect_image(left, encoding, None if rois is None else rois[0])
        det_r = self.detect_image(right, encoding, None if rois is None else rois[1])
        features = np.empty(6)
        problems = []
        for k in range(2):
            row, reason, detail = self._pair_marker(k, det_l.blobs[k], det_r.blobs[k],
                                                    det_l.rejected, det_r.rejected)
            if row is None:
                problems.append((reason, detail))
            else:
                features[3 * k:3 * k + 3] = row
        if problems:
            missing = [p for p in problems if p[0] is Reason.MARKER_MISSING]
            if len(missing) == 2 and not any(det_l.blobs) and not any(det_r.blobs) \
                    and not det_l.rejected and not det_r.rejected:
                reason = Reason.NOT_IN_VIEW
            else:
                order = (Reason.AMBIGUOUS, Reason.EPIPOLAR_MISMATCH, Reason.MARKER_MISSING)
                reason = min((p[0] for p in problems), key=order.index)
            return StereoDetection(None, reason, '; '.join(p[1] for p in problems),
                                   det_l, det_r, search)
        return StereoDetection(features, None, '', det_l, det_r, search)

    def _pair_marker(self, k, lefts, rights, rej_l, rej_r):
        """Pair the candidates of marker k; return ((u_l, u_r, v), None, '') or a reason."""
        cfg = self.config
        name = MARKER_NAMES[k]
        if not lefts or not rights:
            where = ' and '.join(s for s, b in (('left', lefts), ('right', rights)) if not b)
            rejected = [f'{key.split(": ", 1)[1]} x{n}' for rej in (rej_l, rej_r)
                        for key, n in rej.items() if key.startswith(name)]
            extra = f' (rejected: {", ".join(rejected)})' if rejected else ''
            return None, Reason.MARKER_MISSING, f'{name} not found in {where} image{extra}'
        pairs = []
        for bl in lefts:
            for br in rights:
                disparity = bl.u - br.u
                if abs(bl.v - br.v) > cfg.epipolar_tolerance_px or disparity <= 0.0:
                    continue
                expected = cfg.marker_radius_m * disparity / self._baseline()
                radius = 0.5 * (bl.radius + br.radius)
                if abs(bl.radius - br.radius) > cfg.radius_tolerance * radius + 0.5:
                    continue
                if self.intrinsics is not None \
                        and abs(radius - expected) > cfg.radius_tolerance * expected + 0.5:
                    continue
                pairs.append((bl, br))
        if not pairs:
            return None, Reason.EPIPOLAR_MISMATCH, (
                f'{name}: {len(lefts)} left and {len(rights)} right candidates, none on a '
                f'common epipolar line (|dv| <= {cfg.epipolar_tolerance_px} px, u_l > u_r)')
        if len(pairs) > 1:
            return None, Reason.AMBIGUOUS, f'{name}: {len(pairs)} stereo pairs fit'
        bl, br = pairs[0]
        return self._centre(bl, br), None, ''

    def _baseline(self):
        return self.intrinsics.baseline if self.intrinsics is not None else 1.0

    def _centre(self, bl, br):
        """Return (u_l, u_r, v) of the sphere centre from both silhouette centres."""
        v = 0.5 * (bl.v + br.v)
        k = self.intrinsics
        if k is None:
            return np.array([bl.u, br.u, v])
        radius = self.config.marker_radius_m
        disparity = bl.u - br.u
        depth = k.fu * k.baseline / disparity
        depth = k.fu * k.baseline / (disparity * (1.0 - (radius / depth) ** 2))
        (u_l, u_r), v = silhouette_to_centre(np.array([bl.u, br.u]), v, depth, k, radius)
        return np.array([u_l, u_r, float(v)])


def _symmetric_centre(cover, cx, cy, area):
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


def _coverage(patch, filled, linear, level, marker_rgb):
    """
    Return the fraction of each pixel of an RGB ``patch`` covered by the marker.

    Pixels inside the object (``filled`` eroded) count 1, pixels two or more pixels
    outside count 0. A rim pixel p is unmixed as p = x * m + y * b, with m the marker's
    colour (any brightness: shading only scales x) and b the mean colour of the background
    pixels within 2 px; its coverage is 1 - y. Where m and b are nearly parallel (a dark
    background) it falls back to s / (level of the interior pixels next to it), s being
    the linear colour channel.
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


def _check_image(image, encoding):
    if encoding not in ENCODINGS:
        raise ValueError(f'unsupported encoding {encoding!r}, expected one of '
                         f'{sorted(ENCODINGS)}')
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim != 3 \
            or image.shape[2] != 3:
        raise ValueError('image must be an (H, W, 3) uint8 array')
