"""
sensor_msgs/Image -> numpy for the 8-bit encodings the detector reads (no cv_bridge).

The other way is :func:`ibvs_common.conversions.image_msg`, which the simulator uses too.

Readers raise :class:`ibvs_common.conversions.InputError` with a short reason, used as
the rejection reason on /diagnostics.
"""

from typing import TYPE_CHECKING

import cv2
from ibvs_common.conversions import InputError
import numpy as np
from numpy.typing import NDArray

from .detector import ENCODINGS

if TYPE_CHECKING:
    from sensor_msgs.msg import Image


#: Encodings :func:`image_array` converts to three channels: channels per pixel, and the
#: encoding their first three channels become. bgra8 is what zed-ros2-wrapper publishes
#: (:func:`image_array` drops its alpha, :func:`image_view` keeps the image as it is; its
#: rows may be padded: ``sl_tools.cpp`` L200, L244-245 at 33dfefa, docs/real_cell.md);
#: mono8 is spread over three equal channels (the
#: detector finds the markers by colour, so a monochrome camera is not expected to give
#: measured features; feature_status says which mode each frame had).
CONVERTED = {'bgra8': (4, 'bgr8'), 'mono8': (1, 'rgb8')}


def image_view(msg: 'Image') -> tuple[NDArray[np.uint8], str]:
    """
    Return the pixels of an rgb8, bgr8, bgra8 or mono8 Image as the detector reads them.

    As :func:`image_array`, but a bgra8 image stays bgra8, a view of the message's data
    (the detector reads its windows of it: :data:`.detector.ENCODINGS`): no pixel of a ZED
    wrapper's image is copied before the detector reads it. mono8 is still repeated over
    three channels, in a copy.

    Parameters
    ----------
    msg : sensor_msgs.msg.Image
        The image message.

    Returns
    -------
    tuple of (ndarray of uint8, shape (H, W, 3 or 4), str)
        The pixels and their encoding, 'rgb8', 'bgr8' or 'bgra8'.

    Raises
    ------
    InputError
        As :func:`image_array`.

    """
    if msg.encoding == 'bgra8':
        return _pixels(msg, 4), 'bgra8'
    return image_array(msg)


def rgb_pixels(pixels: NDArray[np.uint8], encoding: str) -> NDArray[np.uint8]:
    """
    Return the R, G, B channels of ``pixels`` in ``encoding`` (a view: no copy).

    Parameters
    ----------
    pixels : ndarray of uint8, shape (H, W, 3 or 4)
        An image of :data:`.detector.ENCODINGS`.
    encoding : str
        Its encoding.

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)
        The same pixels, in R, G, B order.

    """
    return pixels[_RGB_VIEWS[encoding]]


#: The R, G, B channels of each encoding of :data:`.detector.ENCODINGS`, as a slice.
_RGB_VIEWS = {'rgb8': np.s_[:, :, :3], 'bgr8': np.s_[:, :, ::-1], 'bgra8': np.s_[:, :, 2::-1]}


def _pixels(msg: 'Image', channels: int) -> NDArray[np.uint8]:
    """Return the (H, W, channels) pixels of ``msg``, a view of its data; InputError if bad."""
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    if height <= 0 or width <= 0:
        raise InputError('empty image', f'{width} x {height}')
    if step < channels * width:
        raise InputError('bad image step',
                         f'step {step} < {channels} * width {channels * width}')
    data = np.frombuffer(msg.data, dtype=np.uint8)
    if data.size != step * height:
        raise InputError('bad image data length',
                         f'{data.size} bytes, expected step * height = {step * height}')
    return data.reshape(height, step)[:, :channels * width].reshape(height, width, channels)


def image_array(msg: 'Image') -> tuple[NDArray[np.uint8], str]:
    """
    Return the pixels and detector encoding of an rgb8, bgr8, bgra8 or mono8 Image.

    rgb8 and bgr8 come without a copy; bgra8 loses its alpha channel (as bgr8) and mono8 is
    repeated over three channels (as rgb8), in a copy.

    Parameters
    ----------
    msg : sensor_msgs.msg.Image
        The image message.

    Returns
    -------
    tuple of (ndarray of uint8, shape (H, W, 3), str)
        The pixels and their encoding, 'rgb8' or 'bgr8'.

    Raises
    ------
    InputError
        For another encoding, an empty image, a row step shorter than the row, or data
        whose length is not step * height.

    """
    channels, encoding = CONVERTED.get(msg.encoding, (3, msg.encoding))
    if encoding not in ENCODINGS:
        raise InputError('unsupported encoding',
                         f'{msg.encoding!r}, expected one of '
                         f'{sorted(set(ENCODINGS) | set(CONVERTED))}')
    pixels = _pixels(msg, channels)
    if channels == 3:
        return pixels, encoding
    if channels == 1:
        return np.repeat(pixels, 3, axis=2), encoding
    # OpenCV drops the alpha in 0.1 ms an HD720 image; numpy's strided copy takes 4-5 ms,
    # a quarter of the feature node's CPU a frame on the ZED wrapper's images (make bench).
    return cv2.cvtColor(pixels, cv2.COLOR_BGRA2BGR), encoding
