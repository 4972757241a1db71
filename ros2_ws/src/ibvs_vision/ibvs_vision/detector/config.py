"""The detector's tuning (:class:`DetectorConfig`), and why a pair gives no p_I (Reason)."""

from dataclasses import dataclass
import enum

from ibvs_model.scene import MARKER_RADIUS_M, MARKER_RGB
import numpy as np

from .colour import score_of

MARKER_NAMES = ('marker 1 (P1)', 'marker 2 (P2)')


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
                or any(score_of(c) <= 0.0 for c in rgb):
            raise ValueError('DetectorConfig.marker_rgb needs two colours with distinct '
                             f'dominant channels, got {self.marker_rgb!r}')
