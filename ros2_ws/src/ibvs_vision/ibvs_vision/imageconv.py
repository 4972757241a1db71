"""
sensor_msgs/Image <-> numpy for the 8-bit colour encodings the detector reads (no cv_bridge).

Readers raise :class:`ibvs_common.conversions.InputError` with a short reason, used as
the rejection reason on /diagnostics.
"""

from builtin_interfaces.msg import Time
from ibvs_common.conversions import InputError, ns_stamp
import numpy as np
from sensor_msgs.msg import Image

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


def image_msg(array, stamp, encoding='rgb8', frame_id=''):
    """Return an (H, W, 3) uint8 array as a sensor_msgs/Image of ``encoding``."""
    array = np.ascontiguousarray(array, dtype=np.uint8)
    if array.ndim != 3 or array.shape[2] != 3:
        raise ValueError('array must be (H, W, 3)')
    msg = Image()
    msg.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
    msg.header.frame_id = frame_id
    msg.height, msg.width = int(array.shape[0]), int(array.shape[1])
    msg.encoding = encoding
    msg.is_bigendian = 0
    msg.step = 3 * msg.width
    msg.data = array.tobytes()
    return msg
