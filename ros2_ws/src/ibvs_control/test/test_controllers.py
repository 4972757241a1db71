"""Filters, governor and the three controllers as plain objects (no ROS, no PyBullet)."""

from ibvs_control import youla
from ibvs_control.controllers import (AdaptiveFeedback, check_reachable, Feedforward,
                                      JointLoop)
from ibvs_control.decoupling import decouple
from ibvs_control.filters import RECURRENCE_SAMPLES, StateSpaceFilter
from ibvs_control.governor import ReferenceGovernor
from ibvs_control.transfer_function import TransferFunction
from ibvs_model import (default_model, forward_kinematics, ik_solutions, InvalidInputError,
                        inverse_kinematics, IRB4600, ModelError, paper, pose_error,
                        UnreachablePoseError)
import numpy as np
import pytest
from scipy import signal

TAU = 0.01
DT = 1e-3


# -- filters ---------------------------------------------------------------------------------

def test_filter_matches_scipy_on_vector_channels():
    tf = youla.feedforward(TAU).discretise(DT, 'bilinear')
    filt = StateSpaceFilter(tf, 3)
    inputs = np.random.default_rng(1).normal(size=(50, 3))
    out = np.array([filt.step(u) for u in inputs])
    for ch in range(3):
        _, ref = signal.dlsim((tf.num, tf.den, DT), inputs[:, ch])
        np.testing.assert_allclose(out[:, ch], ref.ravel(), rtol=1e-9, atol=1e-9)


def test_filter_rest_state_holds_its_output():
    filt = StateSpaceFilter(youla.feedforward_discrete(TAU, DT), 6)
    u = np.arange(6.0)
    filt.reset(rest_input=u)
    for _ in range(5):
        np.testing.assert_allclose(filt.step(u), u, atol=1e-9)
    integrator = StateSpaceFilter(youla.outer_controller_discrete(TAU, 10.0, 0.7, 1 / 30), 6)
    with pytest.raises(ValueError, match='integrator'):
        integrator.reset(rest_input=u)


def test_conditioning_makes_the_state_follow_the_applied_output():
    tf = TransferFunction([1.0, -0.5], [1.0, -0.9], DT)
    free = StateSpaceFilter(tf, 1)
    cond = StateSpaceFilter(tf, 1)
    for _ in range(20):
        free.step(np.ones(1))
        y = cond.step(np.ones(1), applied=np.full(1, 0.3))
        assert y[0] == pytest.approx(0.3)
    # the conditioned state is that of a filter driven by the input that gives 0.3
    assert abs(cond.output(np.ones(1))[0]) < abs(free.output(np.ones(1))[0])
    with pytest.raises(ValueError):
        StateSpaceFilter(TransferFunction([1.0], [1.0, -0.9], DT), 1).step(1.0, applied=0.0)


def test_filter_rejects_wrong_shapes():
    filt = StateSpaceFilter(youla.feedforward_discrete(TAU, DT), 6)
    with pytest.raises(ValueError):
        filt.step(np.zeros(5))
    with pytest.raises(ValueError):
        StateSpaceFilter(youla.feedforward(TAU))


# -- governor ---------------------------------------------------------------------------------

def test_governor_respects_limits_and_stops_on_target():
    v_max, a_max = np.full(6, 3.0), np.array([5.0, 10.0, 20.0, 40.0, 80.0, 160.0])
    j_max = a_max / 0.05
    gov = ReferenceGovernor(DT, v_max, a_max, jerk_limits=j_max)
    gov.reset(np.zeros(6))
    target = np.array([2.0, -1.0, 0.5, 0.01, -3.0, 1e-4])
    states = []
    for _ in range(3000):
        gov.step(target)
        states.append(np.array(gov.state))
    states = np.array(states)  # (steps, 3, 6): position, velocity, acceleration
    assert np.all(np.abs(states[:, 1]) <= v_max + 1e-9)
    assert np.all(np.abs(states[:, 2]) <= a_max + 1e-9)
    jerk = np.diff(states[:, 2], axis=0) / DT
    assert np.all(np.abs(jerk) <= j_max * (1 + 1e-6))
    np.testing.assert_allclose(states[-1, 0], target, atol=1e-12)
    # a move from rest to rest passes no joint's target
    overshoot = np.max((states[:, 0] - target) * np.sign(target), axis=0)
    assert np.all(overshoot <= 1e-12)


def test_governor_moves_every_joint_along_the_straight_line_from_rest():
    """Time-synchronised: every joint arrives at once, on the line from start to target."""
    gov = ReferenceGovernor(DT, np.full(6, 2.0), np.full(6, 10.0), jerk_rise_s=0.05)
    start, target = np.zeros(6), np.array([1.0, -0.5, 0.25, 0.1, -2.0, 0.05])
    gov.reset(start)
    rs = np.array([gov.step(target) for _ in range(3000)])
    share = (rs - start) / (target - start)
    np.testing.assert_allclose(share, share[:, :1] * np.ones((1, 6)), atol=1e-9)


def test_governor_plans_each_target_under_the_limits_given_with_it():
    """'limited' actuators: the acceleration limit is what the torque buys when planned."""
    gov = ReferenceGovernor(DT, np.full(6, 3.0), jerk_rise_s=0.02)
    gov.reset(np.zeros(6))
    for k in range(2000):
        target = np.full(6, 0.5 + 0.001 * (k // 100))  # a new target every 0.1 s
        limits = np.full(6, 20.0 + 10.0 * np.sin(k * DT * 7.0))
        gov.step(target, limits)
        assert np.all(np.abs(gov.state[2]) <= 30.0 + 1e-9)
    np.testing.assert_allclose(gov.r, target, atol=1e-9)
    with pytest.raises(ValueError):
        gov.step(target + 0.1)  # a new plan, and no limits given at construction nor now
    with pytest.raises(ValueError):
        ReferenceGovernor(DT, np.full(6, 3.0))  # neither jerk limits nor a rise time


def test_an_unsynchronised_governor_moves_each_joint_on_its_own_time_optimal_profile():
    """A velocity law's corrections: each joint as fast as it can, not tied to the slowest."""
    start, target = np.zeros(6), np.array([1.0, 0.1, 0.1, 0.1, 0.1, 0.1])
    arrivals = {}
    for synchronised in (True, False):
        gov = ReferenceGovernor(DT, np.full(6, 2.0), np.full(6, 10.0), jerk_rise_s=0.05,
                                synchronised=synchronised)
        gov.reset(start)
        path = np.array([gov.step(target) for _ in range(3000)])
        arrivals[synchronised] = np.argmax(np.abs(path - target) < 1e-9, axis=0)
    assert np.ptp(arrivals[True]) <= 1  # together
    assert np.all(arrivals[False][1:] < arrivals[True][1:] // 2)  # the short ones far sooner
    assert arrivals[False][0] == arrivals[True][0]  # the longest is the time-optimal one


# -- joint loop -------------------------------------------------------------------------------

def run_joint(loop, q_ref, steps, accel_limit=None):
    q, qd = np.zeros(6), np.zeros(6)
    qs, qds = [], []
    for _ in range(steps):
        acc = loop.step(q_ref, q, qd)
        if accel_limit is not None:
            assert np.all(np.abs(acc) <= accel_limit + 1e-9)
        q, qd = q + qd * DT + 0.5 * acc * DT * DT, qd + acc * DT
        qs.append(q)
        qds.append(qd)
    return np.array(qs), np.array(qds)


def test_ideal_joint_loop_is_linear_and_decoupled():
    loop = JointLoop(TAU, DT)
    ref = np.array([1.0, 0.0, 0.0, 0.0, 0.0, -2.0])
    qs, _ = run_joint(loop, ref, 300)
    np.testing.assert_allclose(qs[:, 5], -2.0 * qs[:, 0], rtol=1e-12)
    np.testing.assert_allclose(qs[:, 1:5], 0.0)
    assert qs[-1, 0] == pytest.approx(1.0, abs=1e-6)
    # with M and h, u = M v + h (eq. 26)
    mass = np.diag([2.0, 3.0, 4.0, 5.0, 6.0, 7.0]) + 0.1
    bias = np.arange(6.0)
    a, b = JointLoop(TAU, DT), JointLoop(TAU, DT)
    v = a.step(ref, np.zeros(6), np.zeros(6))
    np.testing.assert_allclose(b.step(ref, np.zeros(6), np.zeros(6), mass, bias),
                               mass @ v + bias)


def test_limited_joint_loop_respects_speed_and_torque_and_settles():
    accel = np.full(6, 30.0)
    loop = JointLoop(TAU, DT, 'limited', IRB4600.qd_max, accel)
    ref = np.array([2.5, -0.5, 1.0, 0.3, -0.2, 3.0])
    qs, qds = run_joint(loop, ref, 4000, accel_limit=accel)
    assert np.all(np.abs(qds) <= np.array(IRB4600.qd_max) + 1e-9)
    np.testing.assert_allclose(qs[-1], ref, atol=1e-6)
    # no limit cycle: the last second is quiet
    assert np.max(np.abs(qds[-1000:])) < 1e-6


def test_limited_mode_needs_limits():
    with pytest.raises(ValueError, match='torque'):
        JointLoop(TAU, DT, 'limited')
    with pytest.raises(ValueError, match='actuators'):
        JointLoop(TAU, DT, 'turbo')


# -- feedforward ------------------------------------------------------------------------------

def test_feedforward_ik_reproduces_the_target_pose():
    pose = paper.target_pose()
    for scenario in (1, 2):
        ff = Feedforward(pose, TAU, DT)
        q0 = inverse_kinematics(paper.scenario_start_pose(scenario))
        q_target = ff.start(q0)
        dpos, drot = pose_error(forward_kinematics(q_target), pose)
        assert dpos < 1e-9 and drot < 1e-9
        # branch nearest the current joints
        branches = ik_solutions(pose, seed=q0)
        assert len(branches) > 1
        assert min(np.sum((q - q0) ** 2) for q in branches) == pytest.approx(
            np.sum((q_target - q0) ** 2))


def test_feedforward_starts_at_rest_and_reaches_the_target():
    ff = Feedforward(paper.target_pose(), TAU, DT)
    q0 = inverse_kinematics(paper.scenario_start_pose(1))
    q_target = ff.start(q0)
    # q_ff itself settles with the pole of T_forward at -1/(3 tau) (30 ms), which the
    # inner loop's zero cancels: the joints settle in ~10 ms (test_youla)
    out = np.array([ff.step() for _ in range(1000)])
    np.testing.assert_allclose(out[0], q0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(out[-1], q_target, atol=1e-9)
    # biproper: the first answer to the step is many times the step (docs/design.md §5)
    assert np.max(np.abs(out[1] - q0) / np.maximum(np.abs(q_target - q0), 1e-9)) > 10


def test_unreachable_target_is_refused():
    with pytest.raises(UnreachablePoseError):
        Feedforward(paper.target_pose([3.0, 0.0, 0.3], paper.TARGET_ROTATION), TAU, DT)
    with pytest.raises(UnreachablePoseError):
        check_reachable(paper.target_pose([0.0, 0.0, -2.5], paper.TARGET_ROTATION))
    with pytest.raises(ValueError, match='rotation'):
        paper.target_pose([-1.0, 0.2, 0.3], np.ones(9))


def test_target_rotation_printed_with_four_digits_is_accepted():
    pose = paper.target_pose(paper.SCENARIO1_POSITION, paper.SCENARIO1_ROTATION_PRINTED)
    np.testing.assert_allclose(pose[:3, :3].T @ pose[:3, :3], np.eye(3), atol=1e-12)


# -- adaptive feedback ------------------------------------------------------------------------

@pytest.fixture(scope='module')
def feedback_setup():
    model = default_model()
    pose = paper.target_pose()
    q_target = inverse_kinematics(pose)
    return model, pose, q_target


def make_feedback(setup, **kwargs):
    model, pose, _ = setup
    return AdaptiveFeedback(model, pose, TAU, 10.0, 1 / np.sqrt(2), 1 / 30, **kwargs)


def test_target_features_are_F_of_the_target_joints(feedback_setup):
    model, _, q_target = feedback_setup
    fb = make_feedback(feedback_setup)
    np.testing.assert_allclose(fb.p_target, model.features(q_target), atol=1e-9)


def test_no_error_no_feedback_and_estimate_is_F_inverse(feedback_setup):
    model, _, q_target = feedback_setup
    fb = make_feedback(feedback_setup)
    up = fb.update(fb.p_target, q_target)
    np.testing.assert_allclose(up.q_feedback, 0.0, atol=1e-12)
    np.testing.assert_allclose(up.q_estimate, q_target, atol=1e-8)
    assert up.rank == 5 and up.error_norm == pytest.approx(0.0, abs=1e-9)


def test_feedback_removes_a_joint_offset(feedback_setup):
    """Closed around q_true = q_fb + d (T_inner = 1): q_fb -> -d on joints 1-5."""
    model, _, q_target = feedback_setup
    fb = make_feedback(feedback_setup)
    d = np.radians(paper.DISTURBANCE_DEG)
    q_fb = np.zeros(6)
    for _ in range(60):
        q_fb = fb.update(model.features(q_target + d + q_fb), q_target).q_feedback
    np.testing.assert_allclose(q_fb[:5], -d[:5], atol=1e-6)
    assert abs(q_fb[5]) < 1e-12


def test_trust_region_clips_each_channel_alone_and_hold(feedback_setup):
    model, _, q_target = feedback_setup
    q_far = inverse_kinematics(paper.scenario_start_pose(1))
    free = make_feedback(feedback_setup, max_correction_rad=np.inf)
    up_free = free.update(model.features(q_far), q_far)
    assert not up_free.clipped
    dec = decouple(model.jacobian(q_far), free.svd_rcond, free.svd_damping)
    wanted = dec.channels(free.p_target - model.features(q_far))
    assert np.sum(np.abs(wanted) > 0.05) >= 1 and np.sum(np.abs(wanted) <= 0.05) >= 1
    fb = make_feedback(feedback_setup, max_correction_rad=0.05)
    up = fb.update(model.features(q_far), q_far)
    assert up.clipped
    got = dec.Vt @ up.correction
    # the channels that asked for less than the bound keep what they asked for
    small = np.abs(wanted) <= 0.05
    np.testing.assert_allclose(got[small], wanted[small], atol=1e-12)
    np.testing.assert_allclose(np.abs(got[~small]), 0.05, rtol=1e-12)
    np.testing.assert_array_equal(np.sign(got[~small]), np.sign(wanted[~small]))
    held = make_feedback(feedback_setup, hold_speed_fraction=0.2)
    up = held.update(model.features(q_far), q_far, qdot_encoder=np.full(6, 2.0))
    assert up.held and np.all(up.q_feedback == 0.0) and held.filter.steps == 0
    up = held.update(model.features(q_far), q_far, qdot_encoder=np.zeros(6))
    assert not up.held and held.filter.steps == 1


def test_a_law_that_leaves_the_move_to_the_joint_controller_holds_the_moves_own_error(
        feedback_setup):
    """At rest at the start the whole error is the planned move's; near its end it is not."""
    model, _, q_target = feedback_setup
    q_far = inverse_kinematics(paper.scenario_start_pose(1))
    at_rest = np.zeros(6)
    published = make_feedback(feedback_setup)
    assert not published.update(model.features(q_far), q_far, qdot_encoder=at_rest).held
    fb = make_feedback(feedback_setup, own_move=True)
    for _ in range(3):
        up = fb.update(model.features(q_far), q_far, qdot_encoder=at_rest)
        assert up.held and np.all(up.q_feedback == 0.0) and fb.filter.steps == 0
    np.testing.assert_allclose(fb.goal, q_target, atol=1e-9)
    d = np.radians(paper.DISTURBANCE_DEG)
    up = fb.update(model.features(q_target + d), q_target, qdot_encoder=at_rest)
    assert not up.held and fb.filter.steps == 1
    # the goal moves with the correction: an arm that follows q_target + q_feedback is at it
    near = q_target + up.q_feedback + 0.9 * fb.max_correction_rad * np.eye(6)[0]
    assert not fb.update(model.features(near), near, qdot_encoder=at_rest).held
    fb.reset()
    assert fb.goal is None


def test_linearisation_point_encoders_or_features(feedback_setup):
    """C1 at the encoder angles (default) or at F^-1(p_hat) (eq. 42): same with a true model."""
    model, _, q_target = feedback_setup
    d = np.radians([1.0, -2.0, 1.5, 3.0, -2.0, 0.0])
    p_hat = model.features(q_target + d)
    at_features = make_feedback(feedback_setup, linearise_at='features')
    at_encoders = make_feedback(feedback_setup)
    assert at_encoders.linearise_at == 'encoders'
    # encoders that read the true angles: both points coincide
    a = at_features.update(p_hat, q_target + d).correction
    b = at_encoders.update(p_hat, q_target + d).correction
    np.testing.assert_allclose(a, b, atol=1e-9)
    # encoders that read other angles than F^-1(p_hat): the two linearisations differ
    q_enc = q_target + np.radians([5.0, 5.0, -5.0, 10.0, 10.0, 0.0])
    pinv_enc = decouple(model.jacobian(q_enc), at_encoders.svd_rcond, at_encoders.svd_damping).pinv
    c = make_feedback(feedback_setup, max_correction_rad=np.inf).update(p_hat, q_enc)
    np.testing.assert_allclose(c.correction, pinv_enc @ (at_encoders.p_target - p_hat),
                               atol=1e-12)
    np.testing.assert_allclose(c.q_estimate, q_target + d, atol=1e-8)
    with pytest.raises(ValueError, match='linearise_at'):
        make_feedback(feedback_setup, linearise_at='model')


def test_bad_features_raise_and_leave_the_state(feedback_setup):
    _, _, q_target = feedback_setup
    fb = make_feedback(feedback_setup)
    fb.update(fb.p_target + 1.0, q_target)
    before = fb.filter.x.copy()
    for bad in (np.full(6, np.nan), np.zeros(5)):
        with pytest.raises(InvalidInputError):
            fb.update(bad, q_target)
    bad_disparity = fb.p_target.copy()
    bad_disparity[1] = bad_disparity[0] + 5.0  # u_r > u_l: behind the cameras
    with pytest.raises(ModelError):
        fb.update(bad_disparity, q_target)
    np.testing.assert_array_equal(fb.filter.x, before)


def test_feedback_refuses_gains_against_the_bandwidth_rule(feedback_setup):
    model, pose, _ = feedback_setup
    with pytest.raises(ValueError, match='tau_in'):
        AdaptiveFeedback(model, pose, 0.01, 150.0, 0.7, 1 / 30)


@pytest.mark.parametrize('tau_in, dt', [(0.01, 1e-3), (0.02, 2e-3)])
def test_feedforward_trajectory_is_the_filter_output_then_held_exactly(tau_in, dt):
    q0 = inverse_kinematics(paper.scenario_start_pose(2))
    ref = Feedforward(paper.target_pose(), tau_in, dt)
    ref.start(q0)
    ff = Feedforward(paper.target_pose(), tau_in, dt)
    ff.start(q0)
    rows = ff.trajectory()
    stepped = np.array([ref.step() for _ in range(len(rows) + 1000)])
    np.testing.assert_array_equal(rows, stepped[:len(rows)])
    # settled: every later sample is the last row to within rounding, and that is the target
    np.testing.assert_allclose(stepped[len(rows):], np.tile(rows[-1], (1000, 1)), rtol=0,
                               atol=1e-14)
    np.testing.assert_allclose(rows[-1], ff.q_target, atol=1e-9)
    # a cap ends it early, the transient still running
    capped = Feedforward(paper.target_pose(), tau_in, dt)
    capped.start(q0)
    np.testing.assert_array_equal(capped.trajectory(max_samples=50), rows[:50])


def test_feedforward_trajectory_of_a_slow_inner_loop_is_the_filter_output_to_within_rounding():
    q0 = inverse_kinematics(paper.scenario_start_pose(2))
    ref = Feedforward(paper.target_pose(), 0.5, 1e-3)
    ff = Feedforward(paper.target_pose(), 0.5, 1e-3)
    ref.start(q0)
    ff.start(q0)
    rows = ff.trajectory()
    assert len(rows) > RECURRENCE_SAMPLES
    stepped = np.array([ref.step() for _ in range(len(rows))])
    np.testing.assert_array_equal(rows[:RECURRENCE_SAMPLES], stepped[:RECURRENCE_SAMPLES])
    np.testing.assert_allclose(rows, stepped, rtol=0, atol=1e-6)
    np.testing.assert_allclose(rows[-1], ff.q_target, atol=1e-3)
