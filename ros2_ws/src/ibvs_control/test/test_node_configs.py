"""The typed configurations of the feedback and feedforward nodes, without ROS."""

from ibvs_common.params import ParameterError
from ibvs_control import node_params
from ibvs_control.node_params import AdaptiveFeedbackConfig, FeedforwardConfig, LAW_PARAMS
from ibvs_model import IRB4600
import numpy as np
import pytest


def test_the_feedback_config_holds_every_setting_of_the_servo_law():
    params = AdaptiveFeedbackConfig.params()
    assert all(any(spec is p for p in params) for spec in LAW_PARAMS)
    c = AdaptiveFeedbackConfig(omega_n=2, svd_damping=0.5)
    settings = c.law_settings()
    assert list(settings) == [spec.name for spec in LAW_PARAMS] + ['speed_limits', 'own_move']
    # the joint controller makes its own move through the position interface or when limited
    assert not settings['own_move']
    assert AdaptiveFeedbackConfig.make(actuators='limited').law_settings()['own_move']
    # the speeds the arm is allowed: rated with the effort interface, capped with position
    np.testing.assert_allclose(settings['speed_limits'], IRB4600.qd_max)
    capped = AdaptiveFeedbackConfig.make(command_interface='position',
                                         max_joint_speed_deg_s=20.0).law_settings()
    np.testing.assert_allclose(capped['speed_limits'],
                               np.minimum(IRB4600.qd_max, np.radians(20.0)))
    assert capped['own_move']
    assert settings['omega_n'] == 2.0 and isinstance(settings['omega_n'], float)
    assert settings['svd_damping'] == 0.5


def test_a_value_out_of_range_is_refused_naming_it():
    with pytest.raises(ParameterError, match="'feedforward_ratio'"):
        FeedforwardConfig(feedforward_ratio=0.0)
    with pytest.raises(ParameterError, match="'servo_law'"):
        AdaptiveFeedbackConfig(servo_law='nope')


def test_the_configs_rules_are_the_modules_functions():
    # The node runs them at start (kit.config) and ibvs run before any node starts.
    assert AdaptiveFeedbackConfig.RULES[:3] == (node_params.check_gains,
                                                node_params.check_servo_law,
                                                node_params.target_from)
    assert FeedforwardConfig.RULES == (node_params.target_from,)
    with pytest.raises(ParameterError, match='feedforward_method'):
        node_params.check_servo_law(AdaptiveFeedbackConfig(servo_law='ibvs').values())
