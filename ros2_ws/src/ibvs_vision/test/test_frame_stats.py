"""The feature node's timings and counts (ibvs_vision.frame_stats), without ROS."""

from ibvs_vision.frame_stats import FrameStats
import pytest


def test_detection_times_roll_over_the_window_and_compare_cpu_with_the_budget():
    stats = FrameStats(budget_ms=10.0, window=3)
    first = stats.detection(4.0, 2.0, 1.0)
    assert first == {'detection_ms_last': 4.0, 'detection_ms_mean': 4.0,
                     'detection_ms_max': 4.0, 'detection_cpu_ms_mean': 2.0,
                     'detection_cpu_ms_max': 2.0, 'detection_cost_ms_max': 1.0,
                     'detection_within_budget': True}
    stats.detection(8.0, 12.0, 3.0)
    stats.detection(6.0, 4.0, 2.0)
    rolled = stats.detection(2.0, 1.0, 0.5)  # the first falls out of the window of 3
    assert rolled['detection_ms_mean'] == pytest.approx((8.0 + 6.0 + 2.0) / 3)
    assert rolled['detection_ms_max'] == 8.0 and rolled['detection_cost_ms_max'] == 3.0
    assert rolled['detection_within_budget'] is False  # 12 ms of CPU is still in the window
    assert list(rolled) == list(first)  # the order /diagnostics shows them in


def test_processing_times_and_the_reasons_frames_were_estimated():
    stats = FrameStats(budget_ms=1.0)
    assert stats.processing(3.0) == {'processing_ms_last': 3.0, 'processing_ms_median': 3.0,
                                     'processing_ms_max': 3.0}
    assert stats.processing(1.0)['processing_ms_median'] == 2.0
    assert stats.estimated() == {}
    stats.estimated('marker missing')
    stats.estimated('over budget')
    assert stats.estimated('marker missing') == {'estimated_because[marker missing]': 2,
                                                 'estimated_because[over budget]': 1}
    assert stats.estimated() == stats.estimated(None)  # a measured frame counts nothing
