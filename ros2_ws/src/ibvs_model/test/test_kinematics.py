"""Forward and inverse kinematics of the IRB 4600 (eq. 4-10, 43), checked by property."""

import math

from ibvs_model import (fiducial_points, forward_kinematics, geometric_jacobian,
                        ik_position_axis, ik_solutions, InvalidInputError, inverse_kinematics,
                        IRB4600, nearest_rotation, point_jacobian, pose_error, pose_from,
                        RobotParams, UnreachablePoseError)
from ibvs_model import paper
import numpy as np
import pytest

N_RANDOM = 200


def random_configurations(n, seed, params=IRB4600, margin=0.05):
    """Return n joint vectors uniformly inside the limits, away from the range ends."""
    rng = np.random.default_rng(seed)
    lo = np.asarray(params.q_min) + margin
    hi = np.asarray(params.q_max) - margin
    return rng.uniform(lo, hi, size=(n, 6))


def test_zero_pose_matches_design():
    tf = forward_kinematics(np.zeros(6))
    np.testing.assert_allclose(tf[:3, 3], [1.27, 0.0, 1.57], atol=1e-12)
    np.testing.assert_allclose(tf[:3, :3], [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=1e-12)


def test_fiducials_lie_on_tool_axis():
    for q in random_configurations(20, 1):
        tf = forward_kinematics(q)
        p1, p2 = fiducial_points(q)
        np.testing.assert_allclose(p1, tf[:3, 3], atol=1e-12)
        np.testing.assert_allclose(p2 - p1, IRB4600.L_tool / 2 * tf[:3, 2], atol=1e-12)


def test_ik_of_fk_reproduces_pose_and_q_on_random_configurations():
    worst_pos = worst_rot = worst_q = 0.0
    for q in random_configurations(N_RANDOM, 2):
        pose = forward_kinematics(q)
        solutions = ik_solutions(pose, seed=q)
        assert solutions, 'a pose produced by FK must have an IK solution'
        for sol in solutions:
            assert IRB4600.within_limits(sol)
            dpos, drot = pose_error(forward_kinematics(sol), pose)
            worst_pos, worst_rot = max(worst_pos, dpos), max(worst_rot, drot)
        best = inverse_kinematics(pose, seed=q)
        worst_q = max(worst_q, float(np.max(np.abs(best - q))))
    assert worst_pos < 1e-9
    assert worst_rot < 1e-9
    assert worst_q < 1e-9


def test_branches_are_distinct_and_up_to_eight():
    q = np.radians([10.0, 20.0, -30.0, 40.0, 50.0, 60.0])
    solutions = ik_solutions(forward_kinematics(q), seed=q)
    assert 1 <= len(solutions) <= 8
    for i, a in enumerate(solutions):
        for b in solutions[i + 1:]:
            assert np.max(np.abs(a - b)) > 1e-6


def test_nearest_seed_picks_the_wrist_flip_when_seeded_there():
    q = np.radians([10.0, 20.0, -30.0, 40.0, 50.0, 60.0])
    pose = forward_kinematics(q)
    flipped = [s for s in ik_solutions(pose, seed=q)
               if np.allclose(s[:3], q[:3]) and s[4] < 0.0]
    assert flipped, 'the wrist-flip branch (q5 < 0) exists here'
    chosen = inverse_kinematics(pose, seed=flipped[0])
    np.testing.assert_allclose(chosen, flipped[0], atol=1e-12)


def test_joint_six_wraps_to_the_seed_within_its_400_degree_range():
    q = np.radians([5.0, 10.0, 10.0, 20.0, 30.0, 350.0])
    sol = inverse_kinematics(forward_kinematics(q), seed=q)
    assert sol[5] == pytest.approx(q[5], abs=1e-9)
    sol0 = inverse_kinematics(forward_kinematics(q), seed=np.zeros(6))
    assert sol0[5] == pytest.approx(q[5] - 2 * math.pi, abs=1e-9)


def test_position_axis_inverse_recovers_q_with_q6_given():
    for q in random_configurations(N_RANDOM, 3):
        pose = forward_kinematics(q)
        sol = ik_position_axis(pose[:3, 3], pose[:3, 2], q[5], seed=q)
        np.testing.assert_allclose(sol, q, atol=1e-9)


def test_point_jacobian_matches_finite_differences():
    point = np.array([0.0, 0.0, IRB4600.L_tool / 2])
    h = 1e-6
    for q in random_configurations(20, 4):
        jac = point_jacobian(q, point)
        fd = np.empty((3, 6))
        for i in range(6):
            dq = np.zeros(6)
            dq[i] = h
            fd[:, i] = (fiducial_points(q + dq)[1] - fiducial_points(q - dq)[1]) / (2 * h)
        np.testing.assert_allclose(jac, fd, atol=1e-8)
        np.testing.assert_allclose(geometric_jacobian(q)[:3], point_jacobian(q, np.zeros(3)),
                                   atol=1e-12)


@pytest.mark.parametrize('name,pose', [
    ('target', paper.target_pose()),
    ('scenario 1 start', paper.scenario_start_pose(1)),
    ('scenario 2/3 start', paper.scenario_start_pose(2)),
])
def test_paper_poses_are_reached(name, pose):
    q = inverse_kinematics(pose)
    assert IRB4600.within_limits(q)
    dpos, drot = pose_error(forward_kinematics(q), pose)
    assert dpos < 1e-9, name
    assert drot < 1e-9, name


def test_paper_poses_report_their_residuals():
    # The printed scenario 1 rotation has four digits: it is 1e-4 from orthonormal.
    printed = np.array(paper.SCENARIO1_ROTATION_PRINTED)
    residual = np.max(np.abs(printed.T @ printed - np.eye(3)))
    assert 1e-6 < residual < 1e-3
    assert np.max(np.abs(nearest_rotation(printed) - printed)) < 1e-3
    # The scenario 2/3 start is 1.5 cm from FK(0) (docs/design.md §5), not FK(0) itself.
    start = paper.scenario_start_pose(2)
    offset = np.linalg.norm(start[:3, 3] - forward_kinematics(np.zeros(6))[:3, 3])
    assert offset == pytest.approx(0.015, abs=1e-12)


def test_scaled_params_change_only_l2_and_l4():
    scaled = IRB4600.scaled(0.5, 1.1)
    assert scaled.L2 == pytest.approx(0.45) and scaled.L4 == pytest.approx(1.056)
    assert (scaled.a1, scaled.L1, scaled.L3, scaled.Lt) == \
        (IRB4600.a1, IRB4600.L1, IRB4600.L3, IRB4600.Lt)
    q = random_configurations(1, 5)[0]
    sol = inverse_kinematics(forward_kinematics(q, scaled), scaled, seed=q)
    np.testing.assert_allclose(sol, q, atol=1e-9)


def test_unreachable_pose_raises_with_reason():
    far = pose_from([3.0, 0.0, 1.0], np.eye(3))
    with pytest.raises(UnreachablePoseError, match='out of reach'):
        inverse_kinematics(far)


def test_pose_excluded_by_joint_limits_raises_with_joints():
    # Reachable geometrically, but only with q2 beyond its -90 deg limit on every branch.
    narrow = RobotParams(q_min=tuple(np.radians([-180, -10, -180, -400, -125, -400])),
                         q_max=tuple(np.radians([180, 10, 75, 400, 120, 400])))
    pose = forward_kinematics(np.radians([0.0, 60.0, 0.0, 0.0, 30.0, 0.0]))
    with pytest.raises(UnreachablePoseError, match='joint limits'):
        inverse_kinematics(pose, narrow)


@pytest.mark.parametrize('bad,match', [
    (np.zeros(5), 'shape'),
    (np.array([0, 0, np.nan, 0, 0, 0]), 'NaN or inf'),
    (np.array([0, 0, np.inf, 0, 0, 0]), 'NaN or inf'),
    ('abc', 'numeric'),
])
def test_fk_rejects_bad_q(bad, match):
    with pytest.raises(InvalidInputError, match=match):
        forward_kinematics(bad)


def test_ik_rejects_non_rotation_and_bad_shape():
    skewed = np.eye(4)
    skewed[0, 1] = 0.1
    with pytest.raises(InvalidInputError, match='not a rotation'):
        inverse_kinematics(skewed)
    with pytest.raises(InvalidInputError, match='shape'):
        inverse_kinematics(np.eye(3))
    with pytest.raises(InvalidInputError, match='seed'):
        inverse_kinematics(forward_kinematics(np.zeros(6)), seed=np.zeros(3))


def test_bad_robot_params_are_rejected():
    with pytest.raises(InvalidInputError, match='L2'):
        RobotParams(L2=-1.0)
    with pytest.raises(InvalidInputError, match='q_min'):
        RobotParams(q_min=(0.0,) * 6, q_max=(0.0,) * 6)
