"""
Colour channels of the marker detector (step 1 of :mod:`ibvs_vision.detector`).

s = C_d - max(other two channels), C_d the marker's dominant channel (red: R - max(G, B));
grey, white and black give s ~ 0. The hue-selective s_sel = C_d - gamma max(others),
gamma = clip(C_d / (2 max(others)), 1, 3) of the marker colour, is also 0 for nearby hues
(orange for red). Both scale with brightness. Pure numpy/OpenCV.
"""

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Channel order of the supported 8-bit colour encodings (ROS sensor_msgs names).
ENCODINGS = {'rgb8': (0, 1, 2), 'bgr8': (2, 1, 0)}


def score_of(rgb: ArrayLike) -> float:
    """
    Return s = C_d - max(other two channels) of one colour ``rgb``.

    Parameters
    ----------
    rgb : array_like, shape (3,)
        The colour (0-255).

    Returns
    -------
    float
        s.

    """
    rgb = np.asarray(rgb, dtype=float)
    d = int(np.argmax(rgb))
    return rgb[d] - max(rgb[i] for i in range(3) if i != d)


@dataclass(frozen=True)
class MarkerColour:
    """Dominant channel d, the other two, and the selectivity gamma of one marker colour."""

    d: int
    others: tuple
    gamma: float

    @classmethod
    def of(cls, rgb: ArrayLike) -> 'MarkerColour':
        """
        Return the dominant channel, the others and gamma of colour ``rgb``.

        Parameters
        ----------
        rgb : array_like, shape (3,)
            The marker's colour (0-255).

        Returns
        -------
        MarkerColour

        """
        rgb = np.asarray(rgb, dtype=float)
        d = int(np.argmax(rgb))
        others = tuple(i for i in range(3) if i != d)
        top = max(rgb[others[0]], rgb[others[1]], 1.0)
        return cls(d, others, float(np.clip(0.5 * rgb[d] / top, 1.0, 3.0)))


def colour_scores(image: NDArray[np.uint8], rgb: ArrayLike,
                  encoding: str = 'rgb8') -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """
    Return the uint8 channels (s, s_sel) of marker colour ``rgb`` in an (H, W, 3) image.

    s = C_d - max(others) is linear in the colour (used for the coverage);
    s_sel = C_d - gamma * max(others), gamma = clip(C_d / (2 max(others)), 1, 3) of the
    marker colour, is also zero for nearby hues (orange for red; used for the Hough
    transform and to accept a disc). Both saturate at 0.

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3)
        The image; may be a view.
    rgb : array_like, shape (3,)
        The marker's colour (0-255).
    encoding : str
        'rgb8' or 'bgr8' (:data:`ENCODINGS`).

    Returns
    -------
    tuple of ndarray of uint8, shape (H, W)
        s and s_sel.

    """
    order = ENCODINGS[encoding]
    colour = MarkerColour.of(rgb)
    planes = cv2.split(image)
    top = cv2.max(planes[order[colour.others[0]]], planes[order[colour.others[1]]])
    dominant = planes[order[colour.d]]
    return (cv2.subtract(dominant, top),
            cv2.addWeighted(dominant, 1.0, top, -colour.gamma, 0.0))


def check_image(image: NDArray[np.uint8], encoding: str) -> None:
    """
    Raise ValueError unless ``image`` is an (H, W, 3) uint8 array in a known encoding.

    Parameters
    ----------
    image : ndarray
        The image to check.
    encoding : str
        Its encoding, one of :data:`ENCODINGS`.

    """
    if encoding not in ENCODINGS:
        raise ValueError(f'unsupported encoding {encoding!r}, expected one of '
                         f'{sorted(ENCODINGS)}')
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim != 3 \
            or image.shape[2] != 3:
        raise ValueError('image must be an (H, W, 3) uint8 array')
