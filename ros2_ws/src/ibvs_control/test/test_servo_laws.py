"""
Servo laws beside the paper's (no ROS): classic IBVS, PBVS, switching, by property.

- classic IBVS: the image error decays at rate lambda for small errors;
- PBVS: the flange moves on the straight line to the target (in {O});
- switching: no jump of the joint reference at the switch; scenarios 2 and 3 overshoot
  at most 5 mm and are within 1 mm after 0.6 s (ideal actuators, model-only loop);
- ibvs and pbvs hold still while the markers are not measured.
"""

from dataclasses import replace

from ibvs_control import controllers, servo_laws
from ibvs_control.closed_loop import LoopConfig, simulate
from ibvs_control.controllers import Feedforward
from ibvs_control.servo_laws import (AdaptiveGain, axis_error, ClassicIBVS, make_law, PBVS,
                                     Switching, tool_from_markers)
from ibvs_model import default_model, forward_kinematics, inverse_kinematics, IRB4600, paper
import numpy as np
import pytest


def flange_path(result):
    """Return the flange positions (N, 3) of the true robot along a model-only run."""
    return np.array([forward_kinematics(q, result.model.params)[:3, 3] for q in result.q_true])


def path_metrics(t, path, target):
    """
    Return overshoot, lateral excursion and time to 1 mm, as ibvs_analysis.metrics does.

    Overshoot: the largest distance past the target along the start-target approach;
    lateral: the largest distance off the start-target line; time to 1 mm: after which
    the error stays within 1 mm (None if it does not).
    """
    step = target - path[0]
    approach = step / np.linalg.norm(step)
    offset = path - path[0]
    lateral = np.linalg.norm(offset - np.outer(offset @ approach, approach), axis=1)
    error = np.linalg.norm(path - target, axis=1)
    outside = np.nonzero(error > 1e-3)[0]
    t_1mm = t[outside[-1] + 1] if outside.size and outside[-1] + 1 < t.size else None
    return max(float(((path - target) @ approach).max()), 0.0), float(lateral.max()), t_1mm


def test_adaptive_gain_is_visps():
    gain = AdaptiveGain(4.0, 0.4, 30.0)
    assert gain(0.0) == pytest.approx(4.0)
    assert gain(1e3) == pytest.approx(0.4)
    h = 1e-7
    assert (gain(h) - gain(0.0)) / h == pytest.approx(-30.0, rel=1e-5)
    assert AdaptiveGain(3.0, 1.0, 0.0)(123.0) == 3.0, 'lambda_slope 0: the constant lambda_0'
    with pytest.raises(ValueError):
        AdaptiveGain(1.0, 2.0, 5.0)
    with pytest.raises(ValueError):
        AdaptiveGain(0.0, 0.0, 0.0)


def test_hold_feedforward_stays_at_the_initial_joints():
    q0 = inverse_kinematics(paper.scenario_start_pose(1))
    ff = Feedforward(paper.target_pose(), paper.TAU_IN, 1e-3, feedforward_method='hold')
    ff.start(q0)
    for _ in range(50):
        np.testing.assert_array_equal(ff.step(), q0)
    # the latched trajectory form (feedforward_node): a short constant one, its last row held
    ff.start(q0)
    rows = ff.trajectory()
    assert 2 <= rows.shape[0] <= 2 + controllers.SETTLED_SAMPLES
    np.testing.assert_array_equal(rows, np.tile(q0, (rows.shape[0], 1)))
    assert servo_laws.ClassicIBVS.feedforward_method('sampled') == 'hold'
    assert servo_laws.Switching.feedforward_method('tustin') == 'tustin'
    assert servo_laws.feedforward_overrides('pbvs') == {'feedforward_method': 'hold'}
    assert servo_laws.feedforward_overrides('paper') == {}
    assert servo_laws.feedforward_overrides('switching') == {
        'feedforward_ratio': servo_laws.SWITCHING_FEEDFORWARD_RATIO}


@pytest.mark.parametrize('scenario', [1, 2])
def test_feedforward_ratio_keeps_the_joint_line_and_scales_the_speed(scenario):
    """
    Follow one joint-space line at any ratio, with a peak speed that goes as 1 / ratio.

    Before the switch the joints follow q0 + s(t) (q_target - q0), one s for all; the peak
    joint speed is about 0.37 |dq| / (ratio tau_in).
    """
    peaks = {}
    for ratio in (1.0, 2.0):
        r = simulate(LoopConfig.for_law('switching', scenario=scenario, feedforward_ratio=ratio),
                     0.15)
        assert np.all(r.q_feedback == 0.0), 'still before the switch'
        q0, dq = r.q[0], r.q_target - r.q[0]
        big = np.abs(dq) > 0.05
        s = (r.q[:, big] - q0[big]) / dq[big]
        np.testing.assert_allclose(s, np.tile(s[:, :1], (1, big.sum())), atol=1e-9)
        speed = np.abs(np.diff(r.q, axis=0)).max() / (r.t[1] - r.t[0])
        expected = np.exp(-1.0) * np.abs(dq).max() / (ratio * paper.TAU_IN)
        assert speed == pytest.approx(expected, rel=0.1)
        peaks[ratio] = speed
    assert peaks[1.0] / peaks[2.0] == pytest.approx(2.0, rel=0.05)


@pytest.mark.parametrize('lam', [1.0, 3.0])
def test_classic_ibvs_error_decays_at_rate_lambda(lam):
    """Kinematic loop (the joints follow q_ref at once): |e(t)| = |e(0)| exp(-lambda t)."""
    model = default_model()
    pose = paper.target_pose()
    q_target = inverse_kinematics(pose)
    dt = 1e-3
    law = ClassicIBVS(model, pose, dt, AdaptiveGain(lam, lam, 0.0))
    q0 = q_target + np.radians([0.2, -0.1, 0.15, 0.3, -0.2, 0.0])
    errors = []
    for _ in range(int(1.0 / dt)):
        q = q0 + law.q_feedback
        errors.append(np.linalg.norm(model.features(q) - law.p_target))
        law.update(model.features(q), q)
    errors = np.array(errors)
    rate = -np.polyfit(np.arange(errors.size) * dt, np.log(errors), 1)[0]
    assert rate == pytest.approx(lam, rel=0.01)


def test_classic_ibvs_in_the_model_only_loop_decays_at_about_lambda():
    """Through the inner loop (eq. 29) and at 30 Hz: the tail still decays at ~lambda."""
    lam = 4.0
    r = simulate(LoopConfig.for_law('ibvs', lambda_0=lam, lambda_inf=lam, lambda_slope=0.0),
                 3.0)
    e = r.image_error
    tail = (e < 20.0) & (e > 1e-3)
    rate = -np.polyfit(r.frame_t[tail], np.log(e[tail]), 1)[0]
    # per frame the error shrinks by 1 - lambda T (T = 1/30 s): rate -ln(1 - lambda T) / T
    assert rate == pytest.approx(lam, rel=0.1)
    np.testing.assert_array_equal(r.q_feedforward, np.tile(r.q[0], (r.t.size, 1)))


#: Position-based servo at the constant gain 1/s.
PBVS_CONSTANT_GAIN = LoopConfig.for_law('pbvs', lambda_0=1.0, lambda_inf=1.0, lambda_slope=0.0)


def test_pbvs_moves_the_flange_on_a_straight_line_unless_a_joint_limit_is_in_the_way():
    target = paper.target_pose()[:3, 3]
    # that line from scenario 1 takes joint 2 to -90.5 deg, past its -90 deg limit: with
    # the limits out of the way the flange follows it ...
    wide = replace(IRB4600, q_min=(-7.0,) * 6, q_max=(7.0,) * 6)
    r = simulate(PBVS_CONSTANT_GAIN, 5.0, model=default_model(params=wide))
    path = flange_path(r)
    travelled = np.linalg.norm(target - path[0])
    _, lateral, _ = path_metrics(r.t, path, target)
    assert np.linalg.norm(path[-1] - target) < 0.02 * travelled
    assert lateral < 0.005 * travelled, f'{lateral * 1e3:.1f} mm off the line'
    low = IRB4600.q_min[1] + servo_laws.JOINT_LIMIT_MARGIN_RAD
    assert r.q_true[:, 1].min() < low
    # ... with the IRB 4600's, the reference stops joint 2 at its limit (less the margin)
    # and the path bends round it, still to the target
    limited = simulate(PBVS_CONSTANT_GAIN, 5.0)
    bent = flange_path(limited)
    assert np.linalg.norm(bent[-1] - target) < 0.02 * travelled
    assert path_metrics(limited.t, bent, target)[1] > 0.05 * travelled
    assert (limited.q_feedforward + limited.q_feedback)[:, 1].min() >= low - 1e-12
    # the paper's law, for contrast, moves in joint space: far off the line
    paper_path = flange_path(simulate(LoopConfig(), 0.5))
    assert path_metrics(r.t[:paper_path.shape[0]], paper_path, target)[1] > 0.1 * travelled


def test_taught_target_features_set_the_vision_only_targets():
    model = default_model()
    pose = paper.target_pose()
    taught = make_law('ibvs', model, pose, 1 / 30)
    shifted = taught.p_target + [2.0, 2.0, -1.0, 0.5, 0.5, 1.0]
    ibvs = make_law('ibvs', model, pose, 1 / 30, p_target=shifted)
    np.testing.assert_array_equal(ibvs.p_target, shifted)
    pbvs = make_law('pbvs', model, pose, 1 / 30, p_target=shifted)
    position, axis = tool_from_markers(model.camera, shifted)
    np.testing.assert_array_equal(pbvs.t_target, position)
    np.testing.assert_allclose(pbvs.pose_error(shifted), 0.0, atol=1e-12)
    assert np.linalg.norm(position - pose[:3, 3]) > 1e-3, 'the taught target moved it'
    with pytest.raises(ValueError, match='p_target'):
        ClassicIBVS(model, pose, 1 / 30, p_target=[1.0, 2.0])


def test_pbvs_pose_error_of_the_target_is_zero():
    model = default_model()
    pose = paper.target_pose()
    law = PBVS(model, pose, 1 / 30)
    np.testing.assert_allclose(law.pose_error(law.p_target), 0.0, atol=1e-9)
    position, axis = tool_from_markers(model.camera, law.p_target)
    np.testing.assert_allclose(position, pose[:3, 3], atol=1e-9)
    np.testing.assert_allclose(axis, pose[:3, 2], atol=1e-9)
    # theta u turns a onto a*: rotating a by it gives a*
    a, b = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.6, 0.8])
    tu = axis_error(a, b)
    theta = np.linalg.norm(tu)
    u = tu / theta
    rotated = (a * np.cos(theta) + np.cross(u, a) * np.sin(theta)
               + u * (u @ a) * (1 - np.cos(theta)))
    np.testing.assert_allclose(rotated, b, atol=1e-12)


@pytest.mark.parametrize('law', ['ibvs', 'pbvs'])
def test_vision_only_laws_hold_still_out_of_view_with_fallback_hold(law):
    r = simulate(LoopConfig.for_law(law, scenario=2, feature_fallback='hold'), 0.3)
    assert not np.any(r.measured)
    assert np.all(r.q_feedback == 0.0)
    np.testing.assert_allclose(r.q, np.tile(r.q[0], (r.t.size, 1)), atol=1e-12)
    # 'estimate' (the default): the model-estimated features move them, as the paper's law
    moved = simulate(LoopConfig.for_law(law, scenario=2), 0.3)
    assert not moved.measured[0]
    assert np.abs(moved.q[-1] - moved.q[0]).max() > 0.1


@pytest.mark.parametrize('scenario', [1, 2, 3])
def test_switching_is_bumpless(scenario):
    r = simulate(LoopConfig.for_law('switching', scenario=scenario), 1.0)
    moving = np.nonzero(np.any(r.q_feedback != 0.0, axis=1))[0]
    assert moving.size, 'the feedback switched on'
    k = moving[0]
    assert r.t[k] >= servo_laws.SWITCH_SETTLE_S
    # before the switch the reference is the feedforward's alone
    assert np.all(r.q_feedback[:k] == 0.0)
    # at the switch the feedback adds to q_ref = q_ff + q_fb no more than at a later frame
    # of the running feedback (k_d's direct feedthrough D ~ 3e-3 times the correction),
    # and far less than the paper's feedback, running since t = 0, holds by then. (q_ff
    # itself still moves then, smoothly: T_forward has a pole at the inner loop's zero
    # -1 / (3 tau), invisible in q.)
    jump = np.abs(r.q_feedback[k] - r.q_feedback[k - 1]).max()
    later = np.abs(np.diff(r.q_feedback[k:], axis=0)).max()
    assert jump <= later
    assert jump < 1e-3
    held_by_paper = np.abs(simulate(LoopConfig(scenario=scenario),
                                    r.t[k] + 1e-3).q_feedback[k]).max()
    assert jump < 0.1 * held_by_paper


@pytest.mark.parametrize('scenario', [2, 3])
def test_switching_overshoots_little_and_is_fast(scenario):
    r = simulate(LoopConfig.for_law('switching', scenario=scenario), 1.0)
    overshoot, _, t_1mm = path_metrics(r.t, flange_path(r), paper.target_pose()[:3, 3])
    assert overshoot <= 5e-3
    assert t_1mm is not None and t_1mm <= 0.6


def test_switching_waits_for_measured_features_and_for_the_settle_time():
    model = default_model()
    pose = paper.target_pose()
    law = make_law('switching', model, pose, 1 / 30, tau_in=paper.TAU_IN,
                   omega_n=paper.OMEGA_N, zeta=paper.ZETA, switch_settle_s=0.1)
    assert isinstance(law, Switching)
    q = inverse_kinematics(pose) + np.radians([0.3, 0.0, 0.0, 0.0, 0.0, 0.0])
    p = model.features(q)
    law.update(p, q, np.zeros(6), measured=True, t=0.0)
    law.update(p, q, np.zeros(6), measured=False, t=0.2)
    assert law.switched_at is None and np.all(law.q_feedback == 0.0)
    law.update(p, q, np.full(6, 10.0), measured=True, t=0.2)
    assert law.switched_at is None, 'the arm still slews'
    law.update(p, q, np.zeros(6), measured=True, t=0.25)
    assert law.switched_at == 0.25 and np.any(law.q_feedback != 0.0)


def test_paper_law_is_unchanged_by_the_new_signature():
    a = simulate(LoopConfig(), 0.3)
    b = simulate(LoopConfig.for_law('paper'), 0.3)
    np.testing.assert_array_equal(a.q, b.q)
    with pytest.raises(ValueError, match='servo_law'):
        LoopConfig.for_law('nope')


def test_parameters_of_the_laws_are_checked_at_start():
    from ibvs_common.params import ParameterError
    from ibvs_control.node_params import check_servo_law
    values = {'servo_law': 'ibvs', 'feedforward_method': 'hold', 'lambda_0': 12.0,
              'lambda_inf': 3.0, 'lambda_slope': 0.09}
    assert check_servo_law(values)(0.0) == 12.0
    with pytest.raises(ParameterError, match="'feedforward_method' = 'sampled'.*'hold'"):
        check_servo_law(dict(values, feedforward_method='sampled'))
    with pytest.raises(ParameterError, match="'feedforward_method' = 'hold'.*'paper'"):
        check_servo_law(dict(values, servo_law='paper'))
    with pytest.raises(ParameterError, match="'lambda_inf' = 20.0"):
        check_servo_law(dict(values, lambda_inf=20.0))
    assert check_servo_law(dict(values, lambda_inf=20.0, lambda_slope=0.0))(1e3) == 12.0


def test_guard_keeps_the_reference_within_reach_and_inside_the_joint_limits():
    q = np.zeros(6)
    lead = np.asarray(IRB4600.qd_max) * 0.1
    ref, cut = servo_laws.guard_reference(q + 10.0, q, IRB4600, 0.1, 0.05)
    assert cut
    np.testing.assert_allclose(ref, q + lead)
    near = np.asarray(IRB4600.q_max) - 0.01
    ref, cut = servo_laws.guard_reference(near + 0.2, near, IRB4600, 0.1, 0.05)
    np.testing.assert_allclose(ref, np.asarray(IRB4600.q_max) - 0.05)
    ref, cut = servo_laws.guard_reference(q + 0.01, q, IRB4600, 0.1, 0.05)
    assert not cut and np.all(ref == q + 0.01)


@pytest.mark.parametrize('law', [ClassicIBVS, PBVS])
def test_velocity_laws_do_not_wind_up_past_what_the_arm_can_follow(law):
    """A frame far from the target with a huge gain: q_ref = q(0) + q_feedback stays in reach."""
    model = default_model()
    pose = paper.target_pose()
    servo = law(model, pose, 1 / 30, AdaptiveGain(500.0, 500.0, 0.0), windup_horizon_s=0.1)
    q = inverse_kinematics(paper.scenario_start_pose(1))
    for _ in range(5):  # the arm does not move: the reference must not run away
        update = servo.update(model.features(q), q)
    lead = np.asarray(model.params.qd_max) * 0.1
    assert update.clipped
    assert np.all(np.abs(servo.q_feedback) <= lead + 1e-12)
    assert law.needs_measured({'feature_fallback': 'hold'})
    assert not law.needs_measured({'feature_fallback': 'estimate'})


def test_the_registry_is_the_one_place_that_knows_the_laws():
    assert servo_laws.SERVO_LAWS == tuple(law.name for law in servo_laws.LAWS)
    assert servo_laws.SERVO_LAWS[0] == 'paper', 'the default first'
    assert len(set(servo_laws.SERVO_LAWS)) == len(servo_laws.LAWS)
    for law in servo_laws.LAWS:
        assert issubclass(law, servo_laws.ServoLaw)
        assert servo_laws.law_class(law.name) is law
        assert law.feedforward_problem(law.feedforward_method('sampled')) is None
        assert law.feedforward_problem('hold' if not law.without_feedforward else 'zoh')
    with pytest.raises(ValueError, match="servo_law must be one of .* got 'nope'"):
        servo_laws.law_class('nope')
    # every law is made from the same settings, each taking what it declares
    model = default_model()
    settings = {'tau_in': paper.TAU_IN, 'omega_n': paper.OMEGA_N, 'zeta': paper.ZETA,
                'svd_rcond': 1e-6, 'svd_damping': 0.1, 'feature_fallback': 'estimate'}
    q = inverse_kinematics(paper.target_pose()) + np.radians([0.3, 0.0, 0.2, 0.0, 0.1, 0.0])
    for name in servo_laws.SERVO_LAWS:
        law = make_law(name, model, paper.target_pose(), 1 / 30, **settings)
        assert isinstance(law, servo_laws.law_class(name))
        update = law.update(model.features(q), q, np.zeros(6), measured=True, t=0.0)
        # e = s - s*, one sign for all: the same error norm whatever the law
        if name != 'pbvs':
            assert update.error_norm == pytest.approx(
                np.linalg.norm(model.features(q) - law.p_target))
