"""feature_node's typed configuration, without ROS."""

from ibvs_common.params import ParameterError
from ibvs_vision.detector import DetectorConfig
from ibvs_vision.node_params import FeatureConfig
import pytest


def test_defaults_give_the_detectors_defaults_and_the_budget():
    c = FeatureConfig()
    assert c.detector_config() == DetectorConfig()
    assert c.budget_ms == pytest.approx(0.5 * 1e3 / 30.0)
    assert FeatureConfig.make(camera_rate_hz=60, detection_budget_share=1).budget_ms == \
        pytest.approx(1e3 / 60.0)


def test_the_detectors_rule_is_checked_when_the_config_is_built():
    with pytest.raises(ParameterError) as caught:
        FeatureConfig(hough_min_radius_px=40, hough_max_radius_px=40)
    with pytest.raises(ParameterError) as detector:
        DetectorConfig(hough_min_radius_px=40, hough_max_radius_px=40)
    assert str(caught.value) == str(detector.value)
    assert FeatureConfig(hough_min_radius_px=40, hough_max_radius_px=41) \
        .detector_config().hough_max_radius_px == 41


def test_the_stamp_offsets_window_must_fit_in_the_joint_history():
    with pytest.raises(ParameterError, match="parameter 'stamp_offset_window_s' = 1.9 is "
                       'invalid with joint_history_s = 2.0'):
        FeatureConfig(stamp_offset_window_s=1.9)
    assert FeatureConfig(stamp_offset_window_s=1.9, joint_history_s=3.0)
    assert FeatureConfig(stamp_offset_window_s=0.0, joint_history_s=0.1)  # no estimate


def test_the_stamp_offset_is_estimated_free_running_only():
    assert not FeatureConfig().estimates_stamp_offset  # lockstep: stamps name the frames
    free = {'command_interface': 'position'}  # free-running: the interface gives it
    assert FeatureConfig.make(**free).estimates_stamp_offset
    assert not FeatureConfig.make(**free, stamp_offset_window_s=0.0).estimates_stamp_offset
    with pytest.raises(ParameterError, match="parameter 'stamp_offset_initial_s' = 0.03 is "
                       'invalid in lockstep'):
        FeatureConfig(stamp_offset_initial_s=0.03)
    assert FeatureConfig.make(**free, stamp_offset_initial_s=0.03)
