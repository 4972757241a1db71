"""The shared parameter groups: flat ROS names, nested records, derived times computed once."""

from dataclasses import dataclass

from ibvs_common.params import group_field, param_field, ParamConfig, ParameterError
from ibvs_common.shared_params import (CAMERA_POSE, Plant, Target, TargetSource, taught,
                                       Timing)
from ibvs_common.timing import period_ns, seconds_to_ns, stamp_lead_ns
from ibvs_model import IRB4600
import numpy as np
import pytest


@dataclass(frozen=True)
class _Config(ParamConfig):
    camera_pose: tuple = param_field(CAMERA_POSE)
    timing: Timing = group_field(Timing)
    target: Target = group_field(Target)


def test_a_group_declares_its_parameters_flat_under_their_own_names_in_field_order():
    names = [spec.name for spec in _Config.params()]
    assert names == ['camera_pose', 'camera_rate_hz', 'physics_rate_hz', 'stale_timeout_s',
                     'feedback_latency_s', 'target_position', 'target_rotation',
                     'target_features_source']


def test_values_and_from_values_round_trip_through_the_groups():
    config = _Config.make(camera_rate_hz=60.0, target_features_source='taught')
    assert config.timing.camera_rate_hz == 60.0 and config.target.taught
    again = _Config.from_values(config.values())
    assert again == config and again.values() == config.values()


def test_make_refuses_a_name_that_is_no_parameter_of_the_config():
    with pytest.raises(TypeError, match='no parameter camera_rate'):
        _Config.make(camera_rate=60.0)


def test_a_group_field_holds_only_its_group():
    with pytest.raises(TypeError, match='must be a Timing'):
        _Config(timing={'camera_rate_hz': 60.0})


@pytest.mark.parametrize('rate_hz, stale_s', [(30.0, 0.5), (60.0, 0.05), (15.0, 2.0)])
def test_the_timing_derives_each_period_and_stamp_lead_by_the_one_rule(rate_hz, stale_s):
    timing = Timing.make(camera_rate_hz=rate_hz, stale_timeout_s=stale_s,
                         feedback_latency_s=0.1)
    assert timing.camera_period_ns == period_ns(rate_hz)
    assert timing.step_ns == period_ns(timing.physics_rate_hz)
    assert timing.frame_lead_ns == stamp_lead_ns(stale_s, period_ns(rate_hz))
    assert timing.step_lead_ns == stamp_lead_ns(stale_s, timing.step_ns)
    assert timing.latency_ns == seconds_to_ns(0.1)
    assert timing.stale_timeout_ns == seconds_to_ns(stale_s)


def test_the_target_source_is_an_enum_and_every_reader_asks_it_alike():
    assert Target().source is TargetSource.MODEL and not Target().taught
    assert Target.make(target_features_source='taught').source is TargetSource.TAUGHT
    assert taught({'target_features_source': 'taught'}) and not taught({})
    with pytest.raises(ParameterError, match='target_features_source'):
        Target.make(target_features_source='camera')


def test_the_target_pose_is_a_new_array_each_time():
    target = Target()
    pose = target.pose
    pose[0, 3] += 1.0
    assert target.pose[0, 3] == pytest.approx(pose[0, 3] - 1.0)


def test_the_plant_is_the_scaled_robot_with_its_disturbance_in_radians():
    plant = Plant.make(disturbance_deg=[1.0, 0, 0, 0, 0, -2.0], l2_scale=1.05)
    assert plant.robot == IRB4600.scaled(1.05, 1.0)
    np.testing.assert_array_equal(plant.d_q, np.radians([1.0, 0, 0, 0, 0, -2.0]))
