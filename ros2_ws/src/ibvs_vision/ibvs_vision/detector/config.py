"""The detector's tuning (:class:`DetectorConfig`), and why a pair gives no p_I (Reason)."""

from collections.abc import Mapping
from dataclasses import dataclass
import enum
from typing import Any

from ibvs_common.params import Param, ParameterError
from ibvs_model.mass_model import QUILL_RADIUS_M
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
    OVER_BUDGET = 'over budget'


#: PyBullet draws a cylinder 1 mm thicker than the URDF's (its convex margin), and the
#: 'opengl' renderer draws it as PyBullet does (ibvs_sim.world.PYBULLET_CYLINDER_MARGIN_M).
RENDERED_ROD_MARGIN_M = 0.001

#: The detector's tuning that feature_node declares as parameters, under these names.
EPIPOLAR_TOLERANCE_PX = Param(
    'epipolar_tolerance_px', 1.5, 'largest |v_left - v_right| of one marker in a rectified '
    'pair', 'px', low=0.0, high=50.0, low_open=True)
HOUGH_MIN_RADIUS_PX = Param('hough_min_radius_px', 2, 'smallest marker image radius searched '
                            'by the Hough transform', 'px', low=1, high=200)
HOUGH_MAX_RADIUS_PX = Param('hough_max_radius_px', 40, 'largest marker image radius searched '
                            'by the Hough transform (above hough_min_radius_px)', 'px',
                            low=2, high=1000)
HOUGH_CANNY_HIGH = Param('hough_canny_high', 60.0, 'upper Canny threshold of the Hough '
                         'transform on the colour channel (cv2.HoughCircles param1)', '-',
                         low=1.0, high=1000.0)
HOUGH_VOTES = Param('hough_votes', 6, 'accumulator votes a circle centre needs '
                    '(cv2.HoughCircles param2)', '-', low=1, high=1000)
MIN_COLOUR_SCORE = Param('min_colour_score', 25.0, 'least median colour channel (dominant '
                         'channel minus the largest other) inside a marker', '0-255',
                         low=1.0, high=255.0)
ROI_MARGIN_PX = Param('roi_margin_px', 40, 'search first within this margin around the last '
                      'measured or the estimated features, then the whole image; 0: always '
                      'the whole image', 'px', low=0, high=2000)
NODE_PARAMS = (EPIPOLAR_TOLERANCE_PX, HOUGH_MIN_RADIUS_PX, HOUGH_MAX_RADIUS_PX,
               HOUGH_CANNY_HIGH, HOUGH_VOTES, MIN_COLOUR_SCORE, ROI_MARGIN_PX)
#: Tuning fixed by the scene and the detector's design (not node parameters).
OTHER_PARAMS = (
    Param('max_candidates', 6, 'Hough circles refined per marker and search window', '-',
          low=1, high=100),
    Param('min_roundness', 0.6, 'least ratio of the smaller to the larger second moment of a '
          'candidate, the off-axis stretch undone (1: a disc)', '-', low=0.0, high=1.0,
          low_open=True),
    Param('radius_tolerance', 0.3, 'relative difference allowed between the left and right '
          'radii and the radius the disparity implies', '-', low=0.0, high=10.0,
          low_open=True),
    Param('marker_radius_m', MARKER_RADIUS_M, 'radius of the spherical fiducials', 'm',
          low=0.0, high=1.0, low_open=True, high_open=True),
    Param('rod_radius_m', QUILL_RADIUS_M + RENDERED_ROD_MARGIN_M, 'radius of the thickest '
          'rod on the tool axis as drawn (the link-6 quill, and the margin the renderers '
          'draw cylinders with)', 'm', low=0.0, high=1.0),
    Param('axis_band_px', 2.5, 'half-width of the band about the tool axis left out of a '
          "marker's centre, beyond the rods' image radius: the reach of a rim pixel's "
          'background (2 px) and half a pixel', 'px', low=0.0, high=100.0),
)
_DEFAULTS = {spec.name: spec.default for spec in NODE_PARAMS + OTHER_PARAMS}


@dataclass(frozen=True)
class DetectorConfig:
    """
    Tuning of the detector, each field checked against its :class:`Param` above.

    The fields of :data:`NODE_PARAMS` are feature_node parameters of the same name
    (:meth:`from_parameters`). Radii are image radii in pixels of the full-resolution image.
    """

    epipolar_tolerance_px: float = _DEFAULTS['epipolar_tolerance_px']
    hough_min_radius_px: int = _DEFAULTS['hough_min_radius_px']
    hough_max_radius_px: int = _DEFAULTS['hough_max_radius_px']
    hough_canny_high: float = _DEFAULTS['hough_canny_high']
    hough_votes: int = _DEFAULTS['hough_votes']
    min_colour_score: float = _DEFAULTS['min_colour_score']
    roi_margin_px: int = _DEFAULTS['roi_margin_px']
    max_candidates: int = _DEFAULTS['max_candidates']
    min_roundness: float = _DEFAULTS['min_roundness']
    radius_tolerance: float = _DEFAULTS['radius_tolerance']
    marker_radius_m: float = _DEFAULTS['marker_radius_m']
    rod_radius_m: float = _DEFAULTS['rod_radius_m']
    axis_band_px: float = _DEFAULTS['axis_band_px']
    marker_rgb: tuple = MARKER_RGB

    @classmethod
    def from_parameters(cls, values: Mapping[str, Any]) -> 'DetectorConfig':
        """
        Return the config of the node parameter values ``values``.

        Parameters
        ----------
        values : mapping of str to value
            The values of :data:`NODE_PARAMS` by name (others are ignored).

        Returns
        -------
        DetectorConfig

        """
        return cls(**{spec.name: values[spec.name] for spec in NODE_PARAMS})

    def __post_init__(self):
        """Check every field; ParameterError (a ValueError) names the one out of range."""
        for spec in NODE_PARAMS + OTHER_PARAMS:
            spec.check(getattr(self, spec.name))
        if self.hough_max_radius_px <= self.hough_min_radius_px:
            raise ParameterError(
                f"parameter 'hough_max_radius_px' = {self.hough_max_radius_px} is invalid: it "
                f"must exceed 'hough_min_radius_px' = {self.hough_min_radius_px}")
        rgb = np.asarray(self.marker_rgb, dtype=float)
        if rgb.shape != (2, 3) or len({int(np.argmax(c)) for c in rgb}) != 2 \
                or any(score_of(c) <= 0.0 for c in rgb):
            raise ValueError('DetectorConfig.marker_rgb needs two colours with distinct '
                             f'dominant channels, got {self.marker_rgb!r}')
