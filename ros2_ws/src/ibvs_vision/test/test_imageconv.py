"""sensor_msgs/Image <-> numpy without cv_bridge: round trips and the rejections."""

from array import array as Array

from ibvs_common.conversions import image_msg, InputError, stamp_ns
from ibvs_vision.imageconv import image_array, image_view, rgb_pixels
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Image


@pytest.fixture
def image():
    return np.random.default_rng(0).integers(0, 256, (5, 7, 3), dtype=np.uint8)


@pytest.mark.parametrize('encoding', ['rgb8', 'bgr8'])
def test_round_trip(image, encoding):
    msg = image_msg(image, 1_500_000_123, encoding, 'left')
    assert stamp_ns(msg.header.stamp) == 1_500_000_123 and msg.step == 21
    array, got = image_array(msg)
    assert got == encoding and np.array_equal(array, image)


@pytest.mark.parametrize('encoding', ['rgb8', 'bgra8'])
def test_an_image_message_holds_what_dds_carries(image, encoding):
    # image_msg hands its pixel buffer to the message without the setter's copy: the
    # message must still be a well-formed one, equal to its DDS round trip.
    msg = image_msg(image, 42, encoding, 'left')
    assert isinstance(msg.data, Array) and msg.data.typecode == 'B'
    assert len(msg.data) == msg.step * msg.height
    assert deserialize_message(serialize_message(msg), Image) == msg


def test_bgra8_of_the_zed_wrapper_reads_as_bgr8(image):
    msg = image_msg(image, 7, 'bgra8', 'zed_left_camera_frame_optical')
    assert msg.step == 28 and msg.encoding == 'bgra8'
    assert np.all(np.frombuffer(msg.data, np.uint8).reshape(5, 7, 4)[:, :, 3] == 255)
    array, got = image_array(msg)
    assert got == 'bgr8' and np.array_equal(array, image[:, :, ::-1])


def test_bgra8_rows_with_padding(image):
    # A driver may pad each row (step > 4 * width): the alpha and the padding both go.
    msg = image_msg(image, 0, 'bgra8')
    padded = np.full((5, 32), 77, np.uint8)
    padded[:, :28] = np.frombuffer(msg.data, np.uint8).reshape(5, 28)
    msg.step, msg.data = 32, padded.tobytes()
    array, got = image_array(msg)
    assert got == 'bgr8' and array.shape == (5, 7, 3)
    assert np.array_equal(array, image[:, :, ::-1])


def test_mono8_reads_as_three_equal_channels(image):
    msg = image_msg(image, 0)
    msg.encoding, msg.step, msg.data = 'mono8', 7, image[:, :, 0].tobytes()
    array, got = image_array(msg)
    assert got == 'rgb8' and array.shape == (5, 7, 3)
    assert all(np.array_equal(array[:, :, c], image[:, :, 0]) for c in range(3))


def test_a_bgra8_step_too_short_for_four_channels_is_refused(image):
    msg = image_msg(image, 0, 'bgra8')
    msg.step = 21
    with pytest.raises(InputError) as info:
        image_array(msg)
    assert info.value.reason == 'bad image step'


def test_rows_with_padding(image):
    msg = image_msg(image, 0)
    padded = np.zeros((5, 24), np.uint8)
    padded[:, :21] = image.reshape(5, 21)
    msg.step, msg.data = 24, padded.tobytes()
    assert np.array_equal(image_array(msg)[0], image)


@pytest.mark.parametrize('change, reason', [
    ({'encoding': 'yuv422'}, 'unsupported encoding'),
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


def test_a_bgra8_view_is_the_message_s_own_pixels_and_its_colours_the_copy_s(image):
    # What the feature node reads: no copy of the ZED wrapper's image before the detector.
    msg = image_msg(image, 0, 'bgra8')
    msg.step += 8  # padded rows, as the wrapper may send them
    msg.data = Array('B', np.pad(np.frombuffer(msg.data, np.uint8).reshape(msg.height, -1),
                                 ((0, 0), (0, 8))).tobytes())
    view, encoding = image_view(msg)
    copy, copy_encoding = image_array(msg)
    assert encoding == 'bgra8' and view.shape == image.shape[:2] + (4,)
    assert np.shares_memory(view, np.frombuffer(msg.data, np.uint8))
    assert np.array_equal(rgb_pixels(view, encoding), rgb_pixels(copy, copy_encoding))
    assert np.array_equal(rgb_pixels(view, encoding), image)
    for encoding in ('rgb8', 'bgr8', 'mono8'):
        pixels = image if encoding != 'mono8' else image[:, :, :1]
        msg = image_msg(np.ascontiguousarray(pixels if encoding != 'bgr8' else image),
                        0, encoding) if encoding != 'mono8' else _mono(image[:, :, 0])
        assert all(np.array_equal(a, b) for a, b in zip(image_view(msg), image_array(msg)))


def _mono(plane):
    return Image(height=plane.shape[0], width=plane.shape[1], encoding='mono8',
                 step=plane.shape[1], data=plane.tobytes())
