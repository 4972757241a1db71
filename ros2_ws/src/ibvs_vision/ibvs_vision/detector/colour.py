"""
Colour channels of the marker detector (step 1 of :mod:`ibvs_vision.detector`).

s = C_d - max(other two channels), C_d the marker's dominant channel (red: R - max(G, B));
grey, white and black give s ~ 0. The hue-selective s_sel = C_d - gamma max(others),
gamma = clip(C_d / (2 max(others)), 1, 3) of the marker colour, is also 0 for nearby hues
(orange for red). Both scale with brightness. Pure numpy/OpenCV.
"""

from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Channel order of the supported 8-bit colour encodings (ROS sensor_msgs names): where R,
#: G and B are among a pixel's channels. bgra8 (the ZED wrapper's) is read as it is, its
#: alpha unread, so that a frame's image is not copied to drop it.
ENCODINGS = {'rgb8': (0, 1, 2), 'bgr8': (2, 1, 0), 'bgra8': (2, 1, 0)}
#: Channels per pixel of each encoding.
CHANNELS = {'rgb8': 3, 'bgr8': 3, 'bgra8': 4}


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
        if type(rgb) is tuple:  # a config's colour, hashable as it is
            return _marker_colour(rgb)
        return _marker_colour(tuple(float(c) for c in np.asarray(rgb, dtype=float).reshape(3)))

    @classmethod
    def _of(cls, rgb: tuple) -> 'MarkerColour':
        """Return :meth:`of` of a tuple of 3 floats (computed once a colour)."""
        rgb = np.asarray(rgb, dtype=float)
        d = int(np.argmax(rgb))
        others = tuple(i for i in range(3) if i != d)
        top = max(rgb[others[0]], rgb[others[1]], 1.0)
        return cls(d, others, float(np.clip(0.5 * rgb[d] / top, 1.0, 3.0)))


@lru_cache(maxsize=64)
def _marker_colour(rgb: tuple) -> MarkerColour:
    """Return :meth:`MarkerColour.of` of ``rgb`` (a tuple), once a colour."""
    return MarkerColour._of(rgb)


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
    image : ndarray of uint8, shape (H, W, 3 or 4)
        The image; may be a view.
    rgb : array_like, shape (3,)
        The marker's colour (0-255).
    encoding : str
        A key of :data:`ENCODINGS`.

    Returns
    -------
    tuple of ndarray of uint8, shape (H, W)
        s and s_sel.

    """
    dominant, top, colour = _dominant_and_top(image, rgb, encoding)
    return (cv2.subtract(dominant, top),
            cv2.addWeighted(dominant, 1.0, top, -colour.gamma, 0.0))


def selective_score(image: NDArray[np.uint8], rgb: ArrayLike,
                    encoding: str = 'rgb8') -> NDArray[np.uint8]:
    """
    Return s_sel of marker colour ``rgb`` alone (:func:`colour_scores`' second channel).

    Parameters
    ----------
    image : ndarray of uint8, shape (H, W, 3 or 4)
        The image; may be a view.
    rgb : array_like, shape (3,)
        The marker's colour (0-255).
    encoding : str
        A key of :data:`ENCODINGS`.

    Returns
    -------
    ndarray of uint8, shape (H, W)
        s_sel.

    """
    dominant, top, colour = _dominant_and_top(image, rgb, encoding)
    return cv2.addWeighted(dominant, 1.0, top, -colour.gamma, 0.0)


def _dominant_and_top(image, rgb, encoding):
    """Return (C_d, max(others), MarkerColour) of marker colour ``rgb`` in ``image``."""
    order = ENCODINGS[encoding]
    colour = MarkerColour.of(rgb)
    # cv2.split reads a window of a larger image (its rows apart) slowly: the window is
    # copied first, and its copy split.
    planes = cv2.split(np.ascontiguousarray(image))
    top = cv2.max(planes[order[colour.others[0]]], planes[order[colour.others[1]]])
    return planes[order[colour.d]], top, colour


def check_image(image: NDArray[np.uint8], encoding: str) -> None:
    """
    Raise ValueError unless ``image`` is an (H, W, C) uint8 array of a known encoding.

    Parameters
    ----------
    image : ndarray
        The image to check.
    encoding : str
        Its encoding, one of :data:`ENCODINGS`; C is its :data:`CHANNELS` (3, 4 for bgra8).

    """
    if encoding not in ENCODINGS:
        raise ValueError(f'unsupported encoding {encoding!r}, expected one of '
                         f'{sorted(ENCODINGS)}')
    channels = CHANNELS[encoding]
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim != 3 \
            or image.shape[2] != channels:
        raise ValueError(f'image must be an (H, W, {channels}) uint8 array for {encoding}')
