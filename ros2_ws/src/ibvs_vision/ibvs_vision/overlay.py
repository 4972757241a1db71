"""
The debug overlay: a camera image with what the feature node found, estimated and aims at.

Drawn as ViSP's ``vpServoDisplay::display`` draws a servo task (current features in green,
desired ones in red), with what our feature node adds:

- the detector's marker candidates (Hough + sub-pixel blobs, section 2.2): cyan circles of
  their measured radius;
- the estimate F(q_T) of the camera-and-robot model (eq. 30, 46): a yellow x;
- the features published on /ibvs/features, p_I (measured, estimated or blended): a green +
  with the marker's number beside it, light green for marker 1 (P1, the flange) and dark
  green for marker 2 (P2, on the shaft), so the two can be told apart;
- the target features p_bar: a red + in a red circle;
- the sim time, the mode (measured / blending / estimated) and why the markers were not
  measured, and a legend.

Pure OpenCV on numpy arrays (no ROS): the feature node calls it only when someone listens
to /ibvs/debug/{left,right}/image or ``publish_debug_images`` is set, and ``ibvs video``
uses the images it recorded. Every colour is drawn exactly (no anti-aliasing), so a test can
find a drawn cross by its colour (:func:`find_drawn_features`): the two markers' crosses
are kept apart, and each centres on its published feature within the pixel's rounding.
"""

from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: The published features' crosses, marker 1 and marker 2.
FEATURE_RGB = ((0, 255, 0), (0, 170, 0))
TARGET_RGB = (255, 0, 0)
ESTIMATE_RGB = (255, 255, 0)
CANDIDATE_RGB = (0, 255, 255)
TEXT_RGB = (255, 255, 255)
#: Half length of the drawn crosses (px), before scaling with the image width.
CROSS_PX = 8
#: OpenCV's fixed-point shift: points are drawn to 1/16 px.
_SHIFT = 4
_ONE = 1 << _SHIFT
_SIDE_COLUMN = {'left': 0, 'right': 1}


def _fixed(u, v):
    return int(round(u * _ONE)), int(round(v * _ONE))


def _plus(image, u, v, arm, colour, thickness):
    cv2.line(image, _fixed(u - arm, v), _fixed(u + arm, v), colour, thickness, cv2.LINE_8,
             _SHIFT)
    cv2.line(image, _fixed(u, v - arm), _fixed(u, v + arm), colour, thickness, cv2.LINE_8,
             _SHIFT)


def _cross(image, u, v, arm, colour, thickness):
    cv2.line(image, _fixed(u - arm, v - arm), _fixed(u + arm, v + arm), colour, thickness,
             cv2.LINE_8, _SHIFT)
    cv2.line(image, _fixed(u - arm, v + arm), _fixed(u + arm, v - arm), colour, thickness,
             cv2.LINE_8, _SHIFT)


def side_points(features: ArrayLike, side: str) -> NDArray[np.float64]:
    """
    Return the (u, v) of both markers in one image from p_I rows (u_l, u_r, v).

    Parameters
    ----------
    features : array_like, shape (6,)
        p_I (px).
    side : str
        'left' or 'right'.

    Returns
    -------
    ndarray, shape (2, 2)
        (u, v) of marker 1 and marker 2 (px).

    """
    p = np.asarray(features, dtype=float).reshape(2, 3)
    return p[:, [_SIDE_COLUMN[side], 2]]


def draw(image: ArrayLike, side: str, t_s: float, mode: str, reason: str = '',
         features: ArrayLike | None = None, estimate: ArrayLike | None = None,
         target: ArrayLike | None = None, candidates: Sequence[Sequence] = ()
         ) -> NDArray[np.uint8]:
    """
    Return a copy of the rgb8 ``image`` of lens ``side`` with the overlay drawn on it.

    Parameters
    ----------
    image : array_like of uint8, shape (H, W, 3)
        The rgb8 camera image.
    side : str
        'left' or 'right'.
    t_s : float
        The image's sim time (s), printed.
    mode : str
        measured, blending or estimated, printed.
    reason : str
        Why the markers were not measured, printed.
    features, estimate, target : array_like, shape (6,), optional
        The published p_I, F(q_T) (eq. 46) and p_bar: (u_l, u_r, v) per marker, or None.
    candidates : sequence of sequences
        The detector's blobs of this image, per marker objects with ``u``, ``v`` and
        ``radius`` (px).

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)

    """
    out = np.array(image, dtype=np.uint8, copy=True)
    height, width = out.shape[:2]
    scale = max(1.0, width / 640.0)
    thickness = 1 + 2 * int(scale // 2)  # odd: a line is centred on its pixel row
    arm = CROSS_PX * scale
    for blobs in candidates:
        for blob in blobs:
            cv2.circle(out, _fixed(blob.u, blob.v), int(round(blob.radius * _ONE)),
                       CANDIDATE_RGB, thickness, cv2.LINE_8, _SHIFT)
    if target is not None:
        for u, v in side_points(target, side):
            _plus(out, u, v, arm, TARGET_RGB, thickness)
            cv2.circle(out, _fixed(u, v), int(round(arm * 1.3 * _ONE)), TARGET_RGB, thickness,
                       cv2.LINE_8, _SHIFT)
    if estimate is not None:
        for u, v in side_points(estimate, side):
            _cross(out, u, v, arm * 0.8, ESTIMATE_RGB, thickness)
    if features is not None:
        points = side_points(features, side)
        # Each cross within its own square: no cross hides part of the other.
        apart = np.max(np.abs(points[0] - points[1]))
        feature_arm = max(3.0, min(arm, 0.45 * apart))
        for k, (u, v) in enumerate(points, start=1):
            cv2.putText(out, str(k), (int(u + feature_arm + 3), int(v - feature_arm)),
                        cv2.FONT_HERSHEY_SIMPLEX, 0.5 * scale, TEXT_RGB, thickness)
        for k, (u, v) in enumerate(points, start=1):
            _plus(out, u, v, feature_arm, FEATURE_RGB[k - 1], thickness)
    font = 0.5 * scale
    line = int(20 * scale)
    cv2.putText(out, f'{side}  t = {t_s:.3f} s  {mode}', (8, line),
                cv2.FONT_HERSHEY_SIMPLEX, font, TEXT_RGB, thickness)
    if reason:
        cv2.putText(out, reason[:90], (8, 2 * line), cv2.FONT_HERSHEY_SIMPLEX, font * 0.8,
                    TEXT_RGB, thickness)
    legend = (('+ p_I published', FEATURE_RGB[0]), ('x F(q_T) estimate', ESTIMATE_RGB),
              ('(+) p_bar target', TARGET_RGB), ('o detected', CANDIDATE_RGB))
    x = 8
    for text, colour in legend:
        cv2.putText(out, text, (x, height - 8), cv2.FONT_HERSHEY_SIMPLEX, font * 0.8, colour,
                    thickness)
        x += int(150 * scale)
    return out


def find_drawn_features(image: ArrayLike, side: str, features: ArrayLike,
                        window_px: float | None = None) -> NDArray[np.float64]:
    """
    Return the (u, v) centres of the :data:`FEATURE_RGB` crosses near each marker, or NaN.

    Within ``window_px`` of where ``features`` put each marker in image ``side``, the +
    drawn in that marker's colour: its horizontal arm gives v (the rows that hold at least
    half as many of its pixels as the fullest row), its vertical arm u (likewise by
    column), so that the marker's number drawn beside it does not count. The check that an
    overlay draws what was published.

    Parameters
    ----------
    image : array_like of uint8, shape (H, W, 3)
        An image :func:`draw` returned.
    side : str
        'left' or 'right'.
    features : array_like, shape (6,)
        The p_I it was drawn with (px).
    window_px : float, optional
        Half size of the search window; default 1.5 cross arms.

    Returns
    -------
    ndarray, shape (2, 2)
        (u, v) of each marker's cross, NaN where none is found.

    """
    image = np.asarray(image)
    height, width = image.shape[:2]
    arm = CROSS_PX * max(1.0, width / 640.0)
    window = int(np.ceil(window_px or 1.5 * arm))
    out = []
    for colour, (u, v) in zip(FEATURE_RGB, side_points(features, side)):
        u0, v0 = max(0, int(u) - window), max(0, int(v) - window)
        u1, v1 = min(width, int(u) + window + 1), min(height, int(v) + window + 1)
        if u1 <= u0 or v1 <= v0:
            out.append((np.nan, np.nan))
            continue
        mask = np.all(image[v0:v1, u0:u1] == np.array(colour, dtype=np.uint8), axis=2)
        rows, cols = mask.sum(axis=1), mask.sum(axis=0)
        if not rows.any():
            out.append((np.nan, np.nan))
            continue
        out.append((u0 + np.flatnonzero(cols >= cols.max() / 2.0).mean(),
                    v0 + np.flatnonzero(rows >= rows.max() / 2.0).mean()))
    return np.array(out)
