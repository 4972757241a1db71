"""
The safety envelope by property (no ROS).

- no command leaves the joint range, over random laws and states (seeded);
- the singularity scale halts at the hard stop moving towards, is 1 below the lower
  threshold and falls monotonically between; the collision scale likewise;
- ViSP's joint-limit avoidance opposes a joint driven hard into its critical zone, with
  at least the primary speed (lagadic/visp#1946: it must not switch itself off);
- a law inside the envelope that nothing stops sends the law's own q_feedback.
"""

import math

from ibvs_control.controllers import (FeedbackUpdate, JOINT_LIMIT_MARGIN_RAD,
                                      target_branch)
from ibvs_control.envelope import (collision_scale, EnvelopeConfig, EnvelopedLaw,
                                   Intervention, joint_limit_avoidance,
                                   large_projection_operator,
                                   SCENE_COLLISION_PROXIMITY_THRESHOLD, singularity_scale)
from ibvs_control.servo_laws import make_law, SERVO_LAWS
from ibvs_control.servo_status import ServoStatus
from ibvs_model import default_model, forward_kinematics, inverse_kinematics, IRB4600, paper
from ibvs_model.capsules import Cell
from ibvs_model.ik_branch import arm_branch
import numpy as np
import pytest

Q_MIN, Q_MAX = np.asarray(IRB4600.q_min), np.asarray(IRB4600.q_max)


class RandomLaw:
    """A law whose q_feedback jumps anywhere (up to 4 rad a frame): the worst case."""

    def __init__(self, rng, without_feedforward, model, amplitude=4.0):
        """Keep the random source; the target is the paper's."""
        self.rng = rng
        self.amplitude = amplitude
        self.without_feedforward = without_feedforward
        self.model = model
        self.pose = paper.target_pose()
        self.p_target = model.features(inverse_kinematics(self.pose))
        self.dt = 1.0 / 30.0
        self._q_feedback = np.zeros(6)
        self.q_start = None
        self.last = None

    @property
    def q_feedback(self):
        """Return the integrated value."""
        return self._q_feedback.copy()

    def update(self, p_hat, q_encoder, qdot_encoder=None, measured=True, t=None):
        """Jump anywhere."""
        if self.q_start is None:
            self.q_start = np.asarray(q_encoder, dtype=float).copy()
        self._q_feedback = self._q_feedback + self.rng.uniform(-self.amplitude, self.amplitude, 6)
        self.last = FeedbackUpdate(self.q_feedback, q_encoder, np.ones(6), 6, 1.0, 1.0,
                                   np.zeros(6), False, False)
        return self.last

    def reset(self):
        """Forget."""
        self._q_feedback = np.zeros(6)
        self.q_start = None


@pytest.mark.parametrize('without_feedforward', [True, False])
def test_no_command_leaves_the_joint_range(without_feedforward):
    """q(0) + q_fb (velocity laws) or both ends of the feedforward + q_fb stay in range."""
    rng = np.random.default_rng(38)
    model = default_model()
    margin = EnvelopeConfig().final_margin_rad
    for _ in range(6):
        q0 = inverse_kinematics(paper.scenario_start_pose(int(rng.integers(1, 3))))
        q_target = inverse_kinematics(paper.target_pose(), seed=q0)
        law = EnvelopedLaw(RandomLaw(rng, without_feedforward, model))
        q = q0.copy()
        for _ in range(40):
            update = law.update(law.p_target + rng.normal(0.0, 50.0, 6), q)
            refs = [q0 + update.q_feedback]
            if not without_feedforward:
                refs.append(q_target + update.q_feedback)
            for ref in refs:
                assert np.all(ref >= Q_MIN + margin - 1e-12)
                assert np.all(ref <= Q_MAX - margin + 1e-12)
            # the arm follows part of the way: a new random state
            q = np.clip(q + rng.uniform(0.0, 1.0) * (refs[0] - q), Q_MIN, Q_MAX)
        assert law.counts[Intervention.JOINT_BOUND] > 0


def test_singularity_halts_at_the_hard_stop():
    """Towards and kappa >= 30: scale 0, HALT_FOR_SINGULARITY (MoveIt Servo's code 2)."""
    for kappa in (30.0, 31.0, 1e6, math.inf):
        scale, code = singularity_scale(kappa, towards=True)
        assert scale == 0.0 and code == Intervention.HALT_FOR_SINGULARITY
    assert Intervention.HALT_FOR_SINGULARITY == ServoStatus.HALT_FOR_SINGULARITY == 2
    assert singularity_scale(16.9, towards=True) == (1.0, None)


@pytest.mark.parametrize('towards', [True, False])
def test_singularity_scale_falls_monotonically(towards):
    """Between the thresholds the scale never rises with kappa; it stays in [0, 1]."""
    kappas = np.linspace(1.0, 60.0, 400)
    scales = [singularity_scale(k, towards)[0] for k in kappas]
    assert all(0.0 <= s <= 1.0 for s in scales)
    assert np.all(np.diff(scales) <= 0.0)
    assert scales[0] == 1.0 and scales[-1] < 0.5
    # MoveIt's linear rule: half way between 17 and 30, moving towards, scale 0.5
    assert singularity_scale(23.5, True)[0] == pytest.approx(0.5)
    assert singularity_scale(23.5, False)[0] == pytest.approx(0.75)


def test_collision_scale():
    """1 beyond the threshold, 0.001 just above contact, 0 at contact, monotone between."""
    assert collision_scale(0.05, 0.02) == 1.0
    assert collision_scale(0.02, 0.02) == 1.0
    assert collision_scale(1e-12, 0.02) == pytest.approx(0.001)
    assert collision_scale(0.0, 0.02) == 0.0
    d = np.linspace(0.0, 0.03, 100)
    assert np.all(np.diff([collision_scale(x, 0.02) for x in d]) >= 0.0)


def test_avoidance_does_not_switch_itself_off():
    """A joint driven hard into its critical zone is pushed back at least as fast (#1946)."""
    q = np.zeros(6)
    span = Q_MAX[0] - Q_MIN[0]
    q[0] = Q_MAX[0] - 0.1 * span * 0.5  # past q_l1: 0.1 * 0.3 of the range inside q_l0
    for speed in (0.01, 1.0, 100.0):     # b from small to >> 1 (ViSP switched off at b >= 1)
        qdot1 = np.zeros(6)
        qdot1[0] = speed
        qdot2 = joint_limit_avoidance(q, qdot1, np.eye(6), Q_MIN, Q_MAX)
        assert qdot2[0] <= -speed
        assert qdot1[0] + qdot2[0] < 0.0
    # inside the safe range nothing is added
    assert np.all(joint_limit_avoidance(np.zeros(6), np.ones(6), np.eye(6), Q_MIN, Q_MAX)
                  == 0.0)


def test_large_projection_operator_limits():
    """Small error: I - W^+ W (the null space of J); large error: P_|e| leaves J^T e out."""
    rng = np.random.default_rng(3)
    jac = rng.normal(size=(6, 6))
    jac[:, 5] = 0.0
    small = large_projection_operator(jac, np.full(6, 1e-3))
    assert np.allclose(small, np.diag([0, 0, 0, 0, 0, 1.0]), atol=1e-9)
    error = rng.normal(size=6) * 1e3
    big = large_projection_operator(jac, error)
    assert np.allclose(big @ (jac.T @ error), 0.0, atol=1e-6)


@pytest.mark.parametrize('law', SERVO_LAWS)
def test_nothing_near_a_limit_is_bit_identical(law):
    """
    Far from limits, singularities and obstacles the envelope sends the law's own array.

    The target q = (0.3, 0.3, 0.2, 0.4, 0.8, 0.2) rad: every joint outside ViSP's
    activation zone, kappa 5.1, clearances above 0.7 m. (The paper's target is not such a
    place: its q1 = 168.7 deg lies in ViSP's critical zone of joint 1.)
    """
    model = default_model()
    q_goal = np.array([0.3, 0.3, 0.2, 0.4, 0.8, 0.2])
    pose = forward_kinematics(q_goal)
    settings = {'tau_in': paper.TAU_IN, 'omega_n': paper.OMEGA_N, 'zeta': paper.ZETA,
                'switch_settle_s': 0.0}
    plain = make_law(law, model, pose, 1.0 / 30.0, **settings)
    wrapped = make_law(law, model, pose, 1.0 / 30.0, safety_envelope=True, **settings)
    assert isinstance(wrapped, EnvelopedLaw)
    q = q_goal + np.radians([1.0, -0.5, 0.5, 0.3, -0.5, 0.0])
    for k in range(8):
        p_hat = model.features(q)
        a = plain.update(p_hat, q, np.zeros(6), True, k / 30.0)
        b = wrapped.update(p_hat, q, np.zeros(6), True, k / 30.0)
        assert np.array_equal(a.q_feedback, b.q_feedback)
        assert wrapped.codes == ()
        q = q + 1e-4


def test_avoidance_stays_in_the_null_space_near_the_goal():
    """
    At the paper's target (q1 in joint 1's critical zone) ibvs's avoidance is confined.

    Small error: P = I - W^+ W, the task's null space, so what the avoidance adds moves
    the markers by nothing the image sees (below 1e-9 px per frame).
    """
    model = default_model()
    pose = paper.target_pose()
    law = make_law('ibvs', model, pose, 1.0 / 30.0, safety_envelope=True)
    q = inverse_kinematics(pose) + np.radians([0.2, -0.1, 0.1, 0.0, 0.1, 0.0])
    plain = make_law('ibvs', model, pose, 1.0 / 30.0)
    a = plain.update(model.features(q), q)
    b = law.update(model.features(q), q)
    assert Intervention.JOINT_LIMIT_AVOIDANCE in law.codes
    seen = model.jacobian(q) @ (b.q_feedback - a.q_feedback)
    assert np.max(np.abs(seen)) < 1e-9


@pytest.mark.parametrize('gap, expected', [
    (-0.001, Intervention.HALT_FOR_COLLISION),
    (0.005, Intervention.DECELERATE_FOR_COLLISION),
])
def test_a_table_under_the_tool_slows_or_halts(gap, expected):
    """A table ``gap`` below the tool's capsule: MoveIt's scale on the step, 0 in contact."""
    model = default_model()
    q = inverse_kinematics(paper.target_pose())
    tip_z = paper.TARGET_POSITION[2] - IRB4600.L_tool
    cell = Cell(table_height_m=tip_z - 0.025 - gap)
    law = EnvelopedLaw(RandomLaw(np.random.default_rng(1), True, model, amplitude=0.01),
                       EnvelopeConfig(cell=cell, joint_limit_avoidance=False,
                                      singularity_scaling=False))
    wanted = np.random.default_rng(1).uniform(-0.01, 0.01, 6)
    update = law.update(law.p_target, q)
    assert law.codes == (expected,)
    scale = collision_scale(gap, SCENE_COLLISION_PROXIMITY_THRESHOLD)
    assert np.allclose(update.q_feedback, scale * wanted, rtol=1e-12, atol=0.0)
    assert (scale == 0.0) == (expected == Intervention.HALT_FOR_COLLISION)


def test_feedforward_target_keeps_the_start_arm():
    """From each scenario's start: q_target on q(0)'s arm, the former nearest branch."""
    target = paper.target_pose()
    for scenario in (1, 2, 3):
        q0 = inverse_kinematics(paper.scenario_start_pose(scenario))
        q_target = target_branch(target, q0)
        assert arm_branch(q_target) == arm_branch(q0) == (1, 1)
        assert np.array_equal(q_target, inverse_kinematics(target, seed=q0))
        assert np.all(q_target >= Q_MIN + JOINT_LIMIT_MARGIN_RAD)
        assert np.all(q_target <= Q_MAX - JOINT_LIMIT_MARGIN_RAD)
