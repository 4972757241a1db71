"""
The stereo detector: Hough candidates per image, refined, then paired across the pair.

Steps 2 and 4: ``cv2.HoughCircles`` on the hue-selective channel, restricted to the blocks
where the marker's hue is present; each circle refined (:mod:`.refine`); candidates of the
left and right image paired by the epipolar constraint, disparity sign and radius. Every
step is paid for from the pair's :class:`.budget.WorkBudget` before it runs.
"""

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
import math
import time

import cv2
from ibvs_model import StereoIntrinsics
from ibvs_model.camera import merge_windows
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .budget import hough_cost_ms, OverBudget, pass_cost_ms, WorkBudget
from .colour import check_image, ENCODINGS, MarkerColour, selective_score
from .config import DetectorConfig, MARKER_NAMES, Reason
from .refine import (axis_band_centres, find_object, refine_candidates, silhouette_to_centre,
                     window_half)

_BLOCK = 8  # = 2 ** 3, see _hot_regions
_MAX_REGIONS = 12
#: Largest half-width of the tool axis's band, as a share of a blob's radius (_axis_centres).
AXIS_BAND_MAX_SHARE = 0.5


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
    (for diagnostics and tests); ``search`` is 'roi' or 'full'; ``cost_ms`` is the
    estimated cost of the work done (:mod:`.budget`), over the budget or not.
    """

    features: np.ndarray = None
    reason: Reason = None
    detail: str = ''
    left: ImageDetections = None
    right: ImageDetections = None
    search: str = 'full'
    cost_ms: float = 0.0

    @property
    def ok(self) -> bool:
        """Return True when p_I was measured."""
        return self.features is not None


class _Stopwatch:
    """Adds the time since the last lap to ``timings['<search>: <stage>']``; None: nothing."""

    __slots__ = ('timings', 'search', 'last')

    def __init__(self, timings, search):
        self.timings, self.search = timings, search
        self.last = time.perf_counter() if timings is not None else 0.0

    def lap(self, stage):
        """Add the time since the last lap to ``stage``."""
        if self.timings is None:
            return
        now = time.perf_counter()
        key = f'{self.search}: {stage}'
        self.timings[key] = self.timings.get(key, 0.0) + now - self.last
        self.last = now


class StereoDetector:
    """
    Detect both fiducials in a rectified stereo pair and return p_I (eq. 2-3).

    ``intrinsics`` (:class:`ibvs_model.StereoIntrinsics`, from CameraInfo) enables the
    perspective correction and the off-axis stretch; without them the silhouette centres
    are returned.
    """

    def __init__(self, intrinsics: StereoIntrinsics | None = None,
                 config: DetectorConfig | None = None) -> None:
        """
        Keep the intrinsics and the tuning.

        Parameters
        ----------
        intrinsics : StereoIntrinsics, optional
            The pair's intrinsics (class docstring).
        config : DetectorConfig, optional
            The tuning; default ``DetectorConfig()``.

        """
        if intrinsics is not None and not isinstance(intrinsics, StereoIntrinsics):
            raise TypeError('intrinsics must be a StereoIntrinsics or None')
        self.intrinsics = intrinsics
        self.config = config if config is not None else DetectorConfig()
        self._colours = tuple(MarkerColour.of(rgb) for rgb in self.config.marker_rgb)
        self._buffers = {}
        #: None, or a dict the stages of each pair's search add their wall time (s) to, by
        #: '<search>: <stage>' (search 'roi' or 'full'), for benchmarks.
        self.timings = None

    # --- one image -------------------------------------------------------------------

    def detect_image(self, image: NDArray[np.uint8], encoding: str = 'rgb8',
                     rois: Sequence[tuple[int, int, int, int] | None] | None = None,
                     budget: WorkBudget | None = None) -> ImageDetections:
        """
        Return the refined candidates of both markers in one image.

        Parameters
        ----------
        image : ndarray of uint8, shape (H, W, 3 or 4)
            The image.
        encoding : str
            'rgb8', 'bgr8' or 'bgra8' (:data:`.colour.ENCODINGS`).
        rois : sequence of 2 (tuple of 4 int or None), optional
            Per marker, None or a window (x0, y0, x1, y1) to search instead of the whole
            image; None: the whole image for both.
        budget : WorkBudget, optional
            Pays for each step before it runs; None: no limit.

        Returns
        -------
        ImageDetections

        Raises
        ------
        OverBudget
            At the first step the budget cannot pay for.

        """
        return self._finish([self._find(image, encoding, rois, budget)])[0]

    def _find(self, image, encoding, rois, budget):
        """
        Return what each circle of both markers in one image gave, in order (detect_image).

        The Hough circles of each search window and the object each one finds
        (:func:`.refine.find_object`): a list of (marker, :class:`.refine.Candidate` or
        None, why not), refined by :meth:`_finish`. Raises OverBudget as
        :meth:`detect_image`.
        """
        check_image(image, encoding)
        budget = budget if budget is not None else WorkBudget()
        cfg = self.config
        found = []
        full = None
        pixels = image.shape[0] * image.shape[1]
        for k, rgb in enumerate(cfg.marker_rgb):
            roi = None if rois is None else rois[k]
            if roi is None:
                if full is None:
                    budget.pay(pass_cost_ms('score', pixels), 'colour channels of an image')
                    full = self._selective(image, encoding)
                budget.pay(pass_cost_ms('hot', pixels), 'hot blocks of an image')
                regions = [(full[k][y0:y1, x0:x1], (x0, y0, x1, y1))
                           for x0, y0, x1, y1 in self._hot_regions(full[k])]
            else:
                x0, y0, x1, y1 = roi
                budget.pay(pass_cost_ms('score', (x1 - x0) * (y1 - y0)),
                           'colour channels of a window')
                regions = [(selective_score(image[y0:y1, x0:x1], rgb, encoding), roi)]
            for score, bounds in regions:
                x0, y0 = bounds[:2]
                seen = []  # boxes (x0, y0, x1, y1) of the objects refined so far
                for u, v, r in self._hough(score, budget):
                    u, v = u + x0, v + y0
                    # Several circles on one object: refine it once.
                    if any(a <= u <= c and b <= v <= d for a, b, c, d in seen):
                        continue
                    side = 2 * window_half(r) + 1
                    budget.pay(pass_cost_ms('refine', side * side), 'refinement of a circle')
                    candidate, why, box = find_object(image, encoding, k, u, v, r, bounds, cfg)
                    if box is not None:
                        seen.append(box)
                    found.append((k, candidate, why))
        return found

    def _finish(self, images):
        """
        Return the ImageDetections of each image's :meth:`_find`, refined all at once.

        The candidates of every image go to :func:`.refine.refine_candidates` together;
        each image then keeps, per marker and in order, every blob that is not within half a
        pixel of one kept already, and counts each rejection by marker and reason.
        """
        candidates = [c for found in images for _, c, _ in found if c is not None]
        refined = iter(refine_candidates(candidates, self.config, self.intrinsics))
        out = []
        for found in images:
            result = ImageDetections(blobs=([], []), rejected={})
            for k, candidate, why in found:
                blob = None
                if candidate is not None:
                    blob, why = next(refined)
                if blob is None:
                    key = f'{MARKER_NAMES[k]}: {why}'
                    result.rejected[key] = result.rejected.get(key, 0) + 1
                elif not any(abs(b.u - blob.u) < 0.5 and abs(b.v - blob.v) < 0.5
                             for b in result.blobs[k]):
                    result.blobs[k].append(blob)
            result.blobs = tuple(tuple(b) for b in result.blobs)
            out.append(result)
        return out

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
        planes = cv2.split(image, [self._buffer(f'plane{i}', shape)
                                   for i in range(image.shape[2])])
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

        A circle is only accepted where the marker's colour is (s_sel >= min_colour_score / 2, as
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
        cv2.threshold(score, 0.5 * cfg.min_colour_score - 1e-3, 255, cv2.THRESH_BINARY,
                      dst=hot[:height, :width])
        # Mean of each block as a share of 255, by three 2 x 2 averages (OpenCV's fast path).
        means = hot
        for level in range(3):
            half = self._buffer(f'half{level}', (means.shape[0] // 2, means.shape[1] // 2))
            means = cv2.resize(means, (half.shape[1], half.shape[0]), dst=half,
                               interpolation=cv2.INTER_AREA)
        min_pixels = min(0.25 * math.pi * cfg.hough_min_radius_px ** 2, 0.5 * _BLOCK * _BLOCK)
        blocks = (means >= 255.0 * min_pixels / (_BLOCK * _BLOCK) - 0.5).astype(np.uint8)
        n, _, stats, _ = cv2.connectedComponentsWithStats(blocks, connectivity=8)
        if n - 1 > _MAX_REGIONS:
            return [(0, 0, width, height)]
        grow = 2 * cfg.hough_max_radius_px + 8
        boxes = []
        for x, y, w, h, _ in stats[1:]:
            boxes.append([max(0, x * _BLOCK - grow), max(0, y * _BLOCK - grow),
                          min(width, (x + w) * _BLOCK + grow),
                          min(height, (y + h) * _BLOCK + grow)])
        return merge_windows(boxes)

    def _hough(self, score, budget):
        """
        Return up to max_candidates circles (u, v, r) of ``score``, paid from ``budget``.

        The blur and the Canny edges are paid for by the pixel, then the transform by its
        edge pixels (:func:`.budget.hough_cost_ms`): the edges are the ones HOUGH_GRADIENT
        finds itself (Canny thresholds param1 / 2 and param1, 3 x 3 Sobel).
        """
        cfg = self.config
        h, w = score.shape
        if min(h, w) < 2 * cfg.hough_min_radius_px + 3:
            return []
        budget.pay(pass_cost_ms('edges', h * w), 'edges of a window')
        # A light blur keeps the gradient of a small disc whole where a highlight dents it.
        blurred = cv2.GaussianBlur(score, (3, 3), 0)
        edges = cv2.countNonZero(cv2.Canny(blurred, max(1.0, 0.5 * cfg.hough_canny_high),
                                           cfg.hough_canny_high))
        budget.pay(hough_cost_ms(edges, h * w),
                   f'Hough transform of {w} x {h} px with {edges} edge pixels')
        circles = cv2.HoughCircles(blurred, cv2.HOUGH_GRADIENT,
                                   dp=1,
                                   minDist=max(4.0, 2.0 * cfg.hough_min_radius_px),
                                   param1=cfg.hough_canny_high, param2=cfg.hough_votes,
                                   minRadius=cfg.hough_min_radius_px,
                                   maxRadius=cfg.hough_max_radius_px)
        if circles is None:
            return []
        return [tuple(float(x) for x in c) for c in circles[0, :cfg.max_candidates]]

    # --- stereo ------------------------------------------------------------------------

    def detect(self, left: NDArray[np.uint8], right: NDArray[np.uint8],
               encoding: str = 'rgb8', prior: ArrayLike | None = None,
               budget_ms: float | None = None) -> StereoDetection:
        """
        Return p_I (eq. 2-3) of a rectified stereo pair, or why not.

        Parameters
        ----------
        left, right : ndarray of uint8, shape (H, W, 3 or 4)
            The pair.
        encoding : str
            'rgb8', 'bgr8' or 'bgra8' (:data:`.colour.ENCODINGS`).
        prior : array_like, shape (6,), optional
            A predicted p_I, e.g. F(q_T) corrected by the last measurement: both images
            are first searched in windows of ``roi_margin_px`` around it; if that does
            not give both markers, the whole images are searched, as far as the budget
            goes.
        budget_ms : float, optional
            The estimated cost (ms, :mod:`.budget`) the pair may take; None: no limit.
            At the first step it cannot pay for, the search stops and the pair gives
            Reason.OVER_BUDGET (the regions of interest come first, so that a pair
            whose markers are where predicted is measured whatever the rest holds).

        Returns
        -------
        StereoDetection

        """
        if left.shape != right.shape:
            raise ValueError(f'left and right images differ in size: {left.shape} vs '
                             f'{right.shape}')
        budget = WorkBudget(budget_ms)
        search, found = 'full', ''
        try:
            budget.pay(pass_cost_ms('pair', 0), 'a stereo pair')
            if prior is not None and self.config.roi_margin_px > 0:
                rois = self._rois(prior, left.shape)
                if rois is not None:
                    search = 'roi'
                    result = self._detect_pair(left, right, encoding, rois, 'roi', budget)
                    if result.ok:
                        return replace(result, cost_ms=budget.spent_ms)
                    found = f'; near the prediction: {result.reason.value}: {result.detail}'
            search = 'full'
            result = self._detect_pair(left, right, encoding, None, 'full', budget)
        except OverBudget as exc:
            return StereoDetection(None, Reason.OVER_BUDGET, f'{search} search: {exc}{found}',
                                   search=search, cost_ms=budget.spent_ms)
        return replace(result, cost_ms=budget.spent_ms)

    def _rois(self, prior, shape):
        prior = np.asarray(prior, dtype=float)
        if prior.shape != (6,) or not np.all(np.isfinite(prior)):
            return None
        height, width = shape[:2]
        m = self.config.roi_margin_px + self.config.hough_max_radius_px // 2 + 4
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

    def _detect_pair(self, left, right, encoding, rois, search, budget):
        clock = _Stopwatch(self.timings, search)
        found = [self._find(left, encoding, None if rois is None else rois[0], budget),
                 self._find(right, encoding, None if rois is None else rois[1], budget)]
        clock.lap('colour channels, Hough, objects')
        det_l, det_r = self._finish(found)
        clock.lap('refinement')
        pairs = []
        problems = []
        for k in range(2):
            pair, reason, detail = self._pair_marker(k, det_l.blobs[k], det_r.blobs[k],
                                                     det_l.rejected, det_r.rejected)
            if pair is None:
                problems.append((reason, detail))
            else:
                pairs.append(pair)
        if problems:
            missing = [p for p in problems if p[0] is Reason.MARKER_MISSING]
            if len(missing) == 2 and not any(det_l.blobs) and not any(det_r.blobs) \
                    and not det_l.rejected and not det_r.rejected:
                reason = Reason.NOT_IN_VIEW
            else:
                order = (Reason.AMBIGUOUS, Reason.EPIPOLAR_MISMATCH, Reason.MARKER_MISSING)
                reason = min((p[0] for p in problems), key=order.index)
            clock.lap('pairing')
            return StereoDetection(None, reason, '; '.join(p[1] for p in problems),
                                   det_l, det_r, search)
        clock.lap('pairing')
        features = np.empty(6)
        centred = self._axis_centres(pairs)
        clock.lap('axis band')
        for k, (bl, br) in enumerate(centred):
            features[3 * k:3 * k + 3] = self._centre(bl, br)
        clock.lap('pairing')
        return StereoDetection(features, None, '', det_l, det_r, search)

    def _axis_centres(self, pairs):
        """
        Return the pairs of blobs with their centres taken outside the tool axis's band.

        In each image the line through both markers' centres is the tool axis, along which
        the rods lie (:func:`.refine.axis_band_centre`); the band's half-width is the rods'
        image radius (``rod_radius_m`` scaled by the blob's radius) plus ``axis_band_px``.
        A blob whose band would be wider than AXIS_BAND_MAX_SHARE of its radius keeps its
        notch-filled centre (:func:`.coverage.symmetric_centre`): the band would leave
        too little of its rim (a marker of 4 px at VGA).
        """
        cfg = self.config
        out = [list(pair) for pair in pairs]
        todo = []  # (k, side, blob, direction, half-width)
        for side in range(2):
            first, second = pairs[0][side], pairs[1][side]
            direction = (second.u - first.u, second.v - first.v)
            if math.hypot(*direction) < 1.0:
                continue
            for k, blob in enumerate((first, second)):
                half_width = cfg.axis_band_px + blob.radius * cfg.rod_radius_m \
                    / cfg.marker_radius_m
                if half_width > AXIS_BAND_MAX_SHARE * blob.radius:
                    continue  # too little rim left: keep the notch-filled centre
                todo.append((k, side, blob, direction, half_width))
        centres = axis_band_centres([t[2] for t in todo], [t[3] for t in todo],
                                    [t[4] for t in todo])
        for (k, side, blob, _, _), (u, v) in zip(todo, centres):
            out[k][side] = replace(blob, u=u, v=v)
        return out

    def _pair_marker(self, k, lefts, rights, rej_l, rej_r):
        """Pair the candidates of marker k; return ((left, right), None, '') or a reason."""
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
        return pairs[0], None, ''

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
