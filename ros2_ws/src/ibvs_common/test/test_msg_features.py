"""/ibvs/features and /ibvs/feature_status written and read, and features in the image."""

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from ibvs_common import contract, conversions
from ibvs_common.conversions import FeatureStatus, InputError
from ibvs_model import default_camera
import numpy as np
import pytest


def _reason(call, *args):
    with pytest.raises(InputError) as caught:
        call(*args)
    return caught.value.reason


def test_features_round_trip_and_rejection():
    p = np.array([600.25, 560.5, 300.125, 610.0, 570.75, 320.5])
    np.testing.assert_array_equal(conversions.read_features(conversions.features_msg(p, 7)), p)
    msg = conversions.features_msg(p, 7)
    msg.polygon.points = msg.polygon.points[:1]
    with pytest.raises(InputError, match='wrong feature count'):
        conversions.read_features(msg)
    msg = conversions.features_msg(p, 7)
    msg.polygon.points[0].x = float('nan')
    with pytest.raises(InputError, match='non-finite'):
        conversions.read_features(msg)


def test_features_are_read_back_as_the_float32_values_point32_carries():
    rng = np.random.default_rng(61)
    for _ in range(500):
        p = rng.uniform(-100.0, 2300.0, size=6)
        msg = conversions.features_msg(p, 34_000_000, frame_id='lens')
        assert conversions.stamp_ns(msg.header.stamp) == 34_000_000
        assert msg.header.frame_id == 'lens'
        # one point per marker: x = u_l, y = u_r, z = v
        assert [(q.x, q.y, q.z) for q in msg.polygon.points] == \
            [tuple(row) for row in p.astype(np.float32).astype(float).reshape(2, 3).tolist()]
        back = conversions.read_features(msg)
        assert back.dtype == np.float64
        assert back.tobytes() == p.astype(np.float32).astype(np.float64).tobytes()
        # read and written again, a value stays what it is
        assert conversions.read_features(conversions.features_msg(back, 0)).tobytes() == \
            back.tobytes()


def test_features_in_image():
    k = default_camera('VGA').intrinsics
    inside = [10.0, 5.0, 100.0, k.width - 0.5, k.width - 10.0, k.height + 0.5]
    conversions.check_features_in_image(inside, k)
    for index, value in ((0, -2.0), (1, k.width + 1.5), (2, 1e6), (5, -1e6)):
        bad = list(inside)
        bad[index] = value
        assert _reason(conversions.check_features_in_image, bad, k) == 'features off the image'


def test_features_on_the_margin_are_in_the_image_and_past_it_are_not():
    k = default_camera('HD720').intrinsics
    margin = conversions.IMAGE_MARGIN_PX
    for index, side in ((0, k.width), (1, k.width), (2, k.height)):
        for edge, past in ((-margin, np.nextafter(-margin, -np.inf)),
                           (side + margin, np.nextafter(side + margin, np.inf))):
            p = np.full(6, 10.0)
            p[index] = edge
            conversions.check_features_in_image(p, k)
            p[index] = past
            assert _reason(conversions.check_features_in_image, p, k) == \
                'features off the image'
    conversions.check_features_in_image(np.full(6, -5.0), k, 5.0)  # a margin of its own


def test_feature_status_round_trip_and_rejection():
    """The writer and the reader of /ibvs/feature_status agree; bad statuses are refused."""
    for mode in contract.FEATURE_MODES:
        for reason in (contract.FEATURE_MEASURED, 'not in view: marker 1 left'):
            status = FeatureStatus(mode, contract.FEATURE_ESTIMATED, reason, 0.25, 'roi')
            msg = conversions.feature_status_msg(status, 34_000_000, name='n: features')
            assert conversions.stamp_ns(msg.header.stamp) == 34_000_000
            assert [kv.key for kv in msg.status[0].values] == list(contract.FEATURE_STATUS_KEYS)
            back = conversions.read_feature_status(msg)
            assert back == status and back.measured == (reason == contract.FEATURE_MEASURED)
    # the weight travels with 6 significant digits
    status = FeatureStatus(contract.FEATURE_BLENDING, contract.FEATURE_MEASURED,
                           contract.FEATURE_MEASURED, 1.0 / 3.0, 'full')
    back = conversions.read_feature_status(conversions.feature_status_msg(status, 0))
    assert back.blend_weight == 0.333333
    assert back._replace(blend_weight=status.blend_weight) == status
    with pytest.raises(InputError, match='no status'):
        conversions.read_feature_status(DiagnosticArray())
    for key, value, match in (('mode', 'guessed', 'mode'), ('blend_weight', 'nan', 'blend'),
                              ('blend_weight', 'x', 'blend'), ('search', None, 'no search')):
        msg = conversions.feature_status_msg(status, 0)
        values = msg.status[0].values
        if value is None:
            msg.status[0].values = [kv for kv in values if kv.key != key]
        else:
            next(kv for kv in values if kv.key == key).value = value
        with pytest.raises(InputError, match=match) as caught:
            conversions.read_feature_status(msg)
        assert caught.value.reason == 'malformed feature status'


def test_a_feature_status_is_read_back_with_its_weight_to_six_significant_digits():
    rng = np.random.default_rng(62)
    for _ in range(500):
        status = FeatureStatus(str(rng.choice(contract.FEATURE_MODES)),
                               str(rng.choice([contract.FEATURE_MEASURED,
                                               contract.FEATURE_ESTIMATED])),
                               str(rng.choice([contract.FEATURE_MEASURED, 'lost: marker 2'])),
                               float(rng.uniform(0.0, 1.0)), str(rng.choice(['roi', 'full'])))
        msg = conversions.feature_status_msg(status, 7, name='n', hardware_id='h',
                                             frame_id='lens')
        (diag,) = msg.status
        assert (diag.level, diag.name, diag.hardware_id, diag.message) == \
            (DiagnosticStatus.OK, 'n', 'h', status.mode)
        assert msg.header.frame_id == 'lens' and conversions.stamp_ns(msg.header.stamp) == 7
        back = conversions.read_feature_status(msg)
        assert back == status._replace(blend_weight=float(f'{status.blend_weight:.6g}'))
        # read and written again, the status stays what it is
        assert conversions.read_feature_status(conversions.feature_status_msg(back, 7)) == back
