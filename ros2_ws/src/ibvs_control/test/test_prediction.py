"""
The camera's latency in the Youla design (ibvs_control.prediction), by property, no ROS.

The prediction is the identity without latency; with the true delay and a perfect model it
gives the undelayed features; it is the Smith predictor, i.e. the Youla controller of the
delayed plant whose closed loop is the designed one delayed; and in the model-only loop it
keeps the designed response at latencies where the paper's law as published rings or fails,
and degrades boundedly when its stamps are off.
"""

from ibvs_common.timing import feedback_action_ns, feedback_frame_ns
from ibvs_control import youla
from ibvs_control.closed_loop import LoopConfig, simulate
from ibvs_control.prediction import predicted_features
from ibvs_control.transfer_function import TransferFunction
from ibvs_model import default_model, forward_kinematics, inverse_kinematics, paper, pose_error
import numpy as np
import pytest

#: The model loop's 'limited' actuators: the benchmark's acceleration limits (rad/s^2).
ACCELERATIONS = (57.0, 24.0, 120.0, 14000.0, 56000.0, 1.0e6)


def _q_start(scenario=1):
    return inverse_kinematics(paper.scenario_start_pose(scenario))


def test_without_latency_the_prediction_is_the_identity_to_the_bit():
    model = default_model()
    q = _q_start()
    p_hat = model.features(q) + np.array([0.3, -0.1, 0.2, 1e-9, 5.0, -7.0])
    out = predicted_features(model, p_hat, q, q.copy())
    assert out.tobytes() == p_hat.tobytes()
    assert out is not p_hat  # a copy: the caller's array is never aliased


def test_with_the_true_delay_and_a_perfect_model_it_gives_the_undelayed_features():
    model = default_model()
    rng = np.random.default_rng(3)
    q_e = _q_start()
    d_q = np.radians([0.1, 0.5, 0.2, 0.3, -0.1, 0.3])
    for _ in range(10):
        q_a = q_e + rng.normal(0.0, 0.2, 6)
        # the camera sees the true robot (encoders + d_q) at the exposure; the true
        # features at the action time are those of the true robot then
        p_exposure = model.features(q_e + d_q)
        predicted = predicted_features(model, p_exposure, q_e, q_a)
        # what stays delayed is the mismatch F(q + d_q) - F(q) at the exposure only
        mismatch_change = (model.features(q_a + d_q) - model.features(q_a)) \
            - (p_exposure - model.features(q_e))
        np.testing.assert_allclose(predicted + mismatch_change, model.features(q_a + d_q),
                                   atol=1e-9)
        # and with no mismatch (d_q = 0) the prediction is exact
        np.testing.assert_allclose(
            predicted_features(model, model.features(q_e), q_e, q_a), model.features(q_a),
            atol=1e-9)


def test_the_smith_form_is_the_youla_controller_of_the_delayed_plant():
    # C = k / (1 + k P_d (1 - z^-d)) with k = M_T / (P_d (1 - M_T)) makes T = M_T z^-d.
    dt, tau, wn, zeta = 1.0 / 30.0, 0.01, 10.0, 0.5 ** 0.5
    plant = youla.inner_closed_loop(tau).discretise(dt, 'zoh')
    target = youla.butterworth(wn, zeta).discretise(dt, 'zoh')
    k = youla.outer_controller_discrete(tau, wn, zeta, dt)
    for d in (1, 3, 6):
        delay = TransferFunction([1.0], [1.0] + [0.0] * d, dt)
        controller = k / (1.0 + k * plant * (1.0 - delay))
        loop = controller * plant * delay / (1.0 + controller * plant * delay)
        want = target * delay
        z = np.exp(1j * np.linspace(0.05, 3.0, 25))
        np.testing.assert_allclose(loop(z), want(z), rtol=1e-6, atol=1e-9)


def test_the_action_time_is_the_inverse_of_which_frame_acts():
    cam, step = 33_333_333, 1_000_000
    for latency in (0, 67_000_000, 100_000_000, 133_333_333):
        for n in range(1, 40):
            stamp = -(-n * cam // step) * step
            act = feedback_action_ns(stamp, latency, step)
            assert feedback_frame_ns(act, cam, latency, step) == stamp
            assert feedback_frame_ns(act - step, cam, latency, step) != stamp
    assert feedback_action_ns(34_000_000, 0, step) == 34_000_000


def _time_to_1mm(result, pose=None):
    pose = paper.target_pose() if pose is None else pose
    errors = np.array([pose_error(forward_kinematics(q, result.model.params), pose)[0]
                       for q in result.q_true[::10]])
    above = np.nonzero(errors > 1e-3)[0]
    t = result.t[::10]
    return 0.0 if not len(above) else t[above[-1] + 1] if above[-1] + 1 < len(t) else np.inf


def _ripple_last_half_second(result):
    pose = paper.target_pose()
    tail = result.q_true[result.t >= result.t[-1] - 0.5]
    errors = [pose_error(forward_kinematics(q, result.model.params), pose)[0] for q in tail]
    return max(errors) - min(errors)


@pytest.mark.parametrize('law', ['paper', 'switching'])
def test_limited_actuators_keep_their_response_up_to_three_frames_of_latency(law):
    times = {}
    for latency in (0.0, 0.133, 0.3):
        r = simulate(LoopConfig.for_law(law, actuators='limited', torque_limits=ACCELERATIONS,
                                        feedback_latency_s=latency), 4.0)
        times[latency] = _time_to_1mm(r)
        assert _ripple_last_half_second(r) < 1e-5
    assert times[0.133] <= 1.1 * times[0.0]
    assert times[0.3] <= 1.2 * times[0.0]


def test_the_paper_law_as_published_rings_where_the_predictor_does_not():
    base = {'actuators': 'limited', 'torque_limits': ACCELERATIONS, 'feedback_latency_s': 0.2}
    published = simulate(LoopConfig.for_law('paper', latency_compensation='none', **base), 4.0)
    predicted = simulate(LoopConfig.for_law('paper', **base), 4.0)
    assert _ripple_last_half_second(published) > 1e-3
    assert _ripple_last_half_second(predicted) < 1e-5


def test_ideal_actuators_with_latency_stay_near_the_undelayed_response():
    undelayed = _time_to_1mm(simulate(LoopConfig(), 2.0))
    delayed = simulate(LoopConfig(feedback_latency_s=0.1), 3.0)
    assert _time_to_1mm(delayed) <= undelayed + 0.15
    assert _ripple_last_half_second(delayed) < 1e-4


@pytest.mark.parametrize('stamp_error_s', [0.02, -0.02])
def test_stamps_off_by_20_ms_still_converge_boundedly_slower(stamp_error_s):
    base = {'actuators': 'limited', 'torque_limits': ACCELERATIONS,
            'feedback_latency_s': 0.133}
    exact = _time_to_1mm(simulate(LoopConfig.for_law('paper', **base), 4.0))
    off = simulate(LoopConfig.for_law('paper', **base), 4.0, stamp_error_s=stamp_error_s)
    assert _time_to_1mm(off) <= exact + 0.75
    assert _ripple_last_half_second(off) < 1e-4


def test_without_latency_the_compensation_changes_nothing_to_the_bit():
    on = simulate(LoopConfig(actuators='limited', torque_limits=ACCELERATIONS), 1.0)
    off = simulate(LoopConfig(actuators='limited', torque_limits=ACCELERATIONS,
                              latency_compensation='none'), 1.0)
    assert on.q.tobytes() == off.q.tobytes()
    assert on.q_feedback.tobytes() == off.q_feedback.tobytes()


def test_the_internal_model_integrates_through_the_slew_at_any_latency():
    # predicted to the rest pose, the feedback never holds (nothing of the planned motion is
    # in its error) and its response does not depend on the latency
    base = {'actuators': 'limited', 'torque_limits': ACCELERATIONS,
            'latency_compensation': 'internal_model'}
    times = []
    for latency in (0.0, 0.2):
        law = LoopConfig.for_law('paper', feedback_latency_s=latency, **base)
        r = simulate(law, 4.0)
        times.append(_time_to_1mm(r))
        assert _ripple_last_half_second(r) < 1e-5
        # integrating from the first frame on: q_feedback moves while the arm slews
        slewing = r.t < 0.5
        assert np.abs(r.q_feedback[slewing]).max() > 1e-4
    assert times[1] <= times[0] + 0.25


def _internal_model(still_speeds=None, transport='joints'):
    from ibvs_control.controllers import target_branch
    from ibvs_control.prediction import Predictor
    model = default_model()
    pose = paper.target_pose()
    q_e = _q_start()
    return model, Predictor('internal_model', model, pose, still_speeds, transport), q_e, \
        target_branch(pose, q_e)


@pytest.mark.parametrize('transport', ['image', 'joints'])
def test_the_internal_model_predicts_to_the_rest_pose_the_references_head_for(transport):
    model, predictor, q_e, q_target = _internal_model(transport=transport)
    q_fb = np.radians([0.1, -0.2, 0.05, 0.0, 0.1, 0.0])
    p_hat = model.features(q_e) + 0.5  # a mismatch the model does not explain
    features, q, qd = predictor.inputs(q_fb, p_hat, q_e, np.ones(6))
    np.testing.assert_allclose(q, q_target + q_fb)
    assert qd is None  # nothing to hold for
    if transport == 'image':
        np.testing.assert_allclose(features, model.features(q_target + q_fb) + 0.5, atol=1e-9)
    # at the frame's own pose the prediction is the frame itself
    at_frame, _, _ = predictor.inputs(q_e - q_target, p_hat, q_e, np.ones(6))
    np.testing.assert_allclose(at_frame, p_hat, atol=1e-9)


def test_an_encoder_offset_seen_at_the_start_is_carried_to_the_rest_pose():
    # the arm is d_q off its encoders: the frame at the start shows F(q_e + d_q); predicted
    # to the target it is F(q_rest + d_q) to first order, where carrying the image error
    # unchanged (eq. P) is wrong by the two poses' Jacobians' difference
    model, predictor, q_e, q_target = _internal_model()
    d_q = np.radians([0.2, -0.5, 0.3, 0.4, -0.3, 0.0])
    q_fb = np.zeros(6)
    p_hat = model.features(q_e + d_q)
    features, _, _ = predictor.inputs(q_fb, p_hat, q_e, np.zeros(6))
    truth = model.features(q_target + q_fb + d_q)
    in_the_image = predicted_features(model, p_hat, q_e, q_target + q_fb)
    error = np.abs(features - truth).max()
    assert error < 0.1 * np.abs(in_the_image - truth).max()
    assert error < 0.5  # px


def test_the_joint_offset_is_held_through_frames_that_do_not_show_the_arm_still():
    still = np.full(6, 0.1)
    model, predictor, q_e, q_target = _internal_model(still)
    d_q = np.radians([0.2, -0.5, 0.3, 0.0, 0.0, 0.0])
    predictor.inputs(np.zeros(6), model.features(q_e + d_q), q_e, np.zeros(6))
    held = predictor.joint_offset.copy(), predictor.rest.copy()
    q_fast = q_e + np.radians([5.0, 1.0, 1.0, 0.0, 0.0, 0.0])
    other = model.features(q_fast) + 3.0  # what a late stamp or an estimate shows
    for qd, measured in ((np.zeros(6), False), (np.full(6, 0.2), True)):
        predictor.inputs(np.zeros(6), other, q_fast, qd, measured=measured)
        np.testing.assert_array_equal(predictor.joint_offset, held[0])
        np.testing.assert_array_equal(predictor.rest, held[1])
    # a measured frame with the arm still takes them anew
    predictor.inputs(np.zeros(6), other, q_fast, np.full(6, 0.05))
    assert not np.array_equal(predictor.joint_offset, held[0])
