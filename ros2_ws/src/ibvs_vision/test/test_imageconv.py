"""sensor_msgs/Image <-> numpy without cv_bridge: round trips and the rejections."""

from ibvs_common.conversions import image_msg, InputError, stamp_ns
from ibvs_vision.imageconv import image_array
import numpy as np
import pytest


@pytest.fixture
def image():
    return np.random.default_rng(0).integers(0, 256, (5, 7, 3), dtype=np.uint8)


@pytest.mark.parametrize('encoding', ['rgb8', 'bgr8'])
def test_round_trip(image, encoding):
    msg = image_msg(image, 1_500_000_123, encoding, 'left')
    assert stamp_ns(msg.header.stamp) == 1_500_000_123 and msg.step == 21
    array, got = image_array(msg)
    assert got == encoding and np.array_equal(array, image)


def test_rows_with_padding(image):
    msg = image_msg(image, 0)
    padded = np.zeros((5, 24), np.uint8)
    padded[:, :21] = image.reshape(5, 21)
    msg.step, msg.data = 24, padded.tobytes()
    assert np.array_equal(image_array(msg)[0], image)


@pytest.mark.parametrize('change, reason', [
    ({'encoding': 'mono8'}, 'unsupported encoding'),
    ({'encoding': 'rgba8'}, 'unsupported encoding'),
    ({'width': 0}, 'empty image'),
    ({'step': 20}, 'bad image step'),
    ({'height': 6}, 'bad image data length'),
])
def test_rejections(image, change, reason):
    msg = image_msg(image, 0)
    for key, value in change.items():
        setattr(msg, key, value)
    with pytest.raises(InputError) as info:
        image_array(msg)
    assert info.value.reason == reason
