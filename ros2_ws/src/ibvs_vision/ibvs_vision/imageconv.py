"""
sensor_msgs/Image -> numpy for the 8-bit colour encodings the detector reads (no cv_bridge).

The other way is :func:`ibvs_common.conversions.image_msg`, which the simulator uses too.

Readers raise :class:`ibvs_common.conversions.InputError` with a short reason, used as
the rejection reason on /diagnostics.
"""

from ibvs_common.conversions import InputError
import numpy as np

from .detector import ENCODINGS


def image_array(msg):
    """
    Return (array (H, W, 3) uint8, encoding) of an rgb8 or bgr8 Image, without a copy.

    Raises :class:`InputError` for another encoding, an empty image, a row step shorter
    than the row, or data whose length is not step * height.
    """
    if msg.encoding not in ENCODINGS:
        raise InputError('unsupported encoding',
                         f'{msg.encoding!r}, expected one of {sorted(ENCODINGS)}')
    height, width, step = int(msg.height), int(msg.width), int(msg.step)
    if height <= 0 or width <= 0:
        raise InputError('empty image', f'{width} x {height}')
    if step < 3 * width:
        raise InputError('bad image step', f'step {step} < 3 * width {3 * width}')
    data = np.frombuffer(msg.data, dtype=np.uint8)
    if data.size != step * height:
        raise InputError('bad image data length',
                         f'{data.size} bytes, expected step * height = {step * height}')
    return data.reshape(height, step)[:, :3 * width].reshape(height, width, 3), msg.encoding
