"""Stamps and durations <-> integer nanoseconds, the one stamp rule and the stamp order."""

from builtin_interfaces.msg import Duration, Time
from ibvs_common import conversions
from ibvs_common.conversions import InputError, StampOrder
from ibvs_common.timing import NS_PER_S
import numpy as np
import pytest


def _reason(call, *args):
    with pytest.raises(InputError) as caught:
        call(*args)
    return caught.value.reason


def test_stamp_round_trip_is_exact():
    for ns in (0, 1, 999_999_999, 1_000_000_000, 123_456_789_012):
        assert conversions.stamp_ns(conversions.ns_stamp(ns)) == ns


def test_ns_stamp_is_a_well_formed_stamp_that_stamp_ns_reads_back_exactly():
    rng = np.random.default_rng(11)
    for ns in rng.integers(0, 2 ** 31 * NS_PER_S, size=2000, dtype=np.int64):
        stamp = conversions.ns_stamp(ns)
        assert 0 <= stamp.nanosec < NS_PER_S and stamp.sec == ns // NS_PER_S
        assert conversions.stamp_ns(stamp) == ns
        assert conversions.read_stamp(stamp) == ns


def test_a_duration_is_read_by_the_rule_of_a_stamp():
    rng = np.random.default_rng(12)
    for sec, nanosec in zip(rng.integers(-2 ** 31, 2 ** 31, size=500),
                            rng.integers(0, 2 ** 32, size=500)):
        duration = Duration(sec=int(sec), nanosec=int(nanosec))
        assert conversions.duration_ns(duration) == int(sec) * NS_PER_S + int(nanosec)
        assert conversions.duration_ns(duration) == \
            conversions.stamp_ns(Time(sec=int(sec), nanosec=int(nanosec)))


@pytest.mark.parametrize('sec,nanosec,reason', [
    (-1, 0, 'negative time'),
    (-2 ** 31, 999_999_999, 'negative time'),
    (0, 1_000_000_000, 'malformed stamp'),
    (3, 4_000_000_000, 'malformed stamp'),
])
def test_read_stamp_rejects_what_stamp_ns_would_misread(sec, nanosec, reason):
    stamp = Time(sec=sec, nanosec=nanosec)
    with pytest.raises(InputError) as info:
        conversions.read_stamp(stamp)
    assert info.value.reason == reason


def test_read_stamp_is_stamp_ns_on_good_stamps():
    for ns in (0, 1, 999_999_999, 1_000_000_000, 2 ** 31 * 1_000_000_000 - 1):
        assert conversions.read_stamp(conversions.ns_stamp(ns)) == ns


def test_the_one_stamp_rule_refuses_future_and_off_grid_stamps():
    ms, cam = 1_000_000, 33_333_333
    # one input period and the clock's lag margin (a stale timeout shorter than it: that)
    lead = conversions.stamp_lead_ns(0.5, cam)
    assert lead == conversions.STAMP_LEAD_MARGIN_NS + cam
    assert conversions.stamp_lead_ns(0.05, cam) == 50 * ms + cam
    # Time unknown (None) counts as 0, the start of sim time: 2^31 s is in the future.
    with pytest.raises(InputError, match='stamp in the future'):
        conversions.read_stamp(Time(sec=2 ** 31 - 1), None, lead)
    assert conversions.read_stamp(Time(sec=0, nanosec=lead), None, lead) == lead
    with pytest.raises(InputError, match='stamp in the future'):
        conversions.read_stamp(Time(sec=0, nanosec=lead + 1), None, lead)
    assert conversions.read_stamp(Time(sec=10), 9_900 * ms, lead) == 10_000 * ms
    with pytest.raises(InputError, match='stamp in the future'):  # 0.4 s ahead: refused
        conversions.read_stamp(Time(sec=10), 9_600 * ms, lead)
    frames = (cam, ms)
    assert conversions.read_stamp(Time(sec=0, nanosec=34 * ms), 0, lead, frames) == 34 * ms
    for off_grid in (33 * ms, 33_333_333, 35 * ms):
        with pytest.raises(InputError, match='off the frame grid'):
            conversions.read_stamp(Time(sec=0, nanosec=off_grid), 0, lead, frames)


def test_stamp_order_counts_duplicates_and_stamps_going_back_per_source():
    order = StampOrder()
    order.check('/a', 5)
    order.take('/a', 5)
    assert _reason(order.check, '/a', 5) == 'duplicate stamp'
    assert _reason(order.check, '/a', 4) == 'stamp went back'
    order.check('/b', 4)  # another source has its own order
    order.check('/a', 6)  # checked, not taken: 6 stays free
    order.check('/a', 6)
    assert order.newest('/a') == 5 and order.newest('/b') is None


def test_a_stamp_order_that_forgets_takes_any_stamp_again():
    order = StampOrder()
    for source, t_ns in (('/a', 9), ('/b', 3)):
        order.take(source, t_ns)
    order.forget()
    assert order.newest('/a') is None and order.newest('/b') is None
    order.check('/a', 1)  # the clock jumped back: a new time line starts
    order.check('/b', 3)
