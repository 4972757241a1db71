"""
The IK branch nearest the present configuration inside the reach cone, by property.

- along a straight line of poses the tracked branch moves in small steps, never flips;
- the paper's start poses and target: the cone keeps the branch inverse_kinematics takes;
- a seed on the over-the-head arm still gets the arm in front.
"""

import math

from ibvs_model import ik_solutions, inverse_kinematics, paper, pose_from, UnreachablePoseError
from ibvs_model.ik_branch import (arm_branch, BranchTracker, in_cone, nearest_branch_ik,
                                  ReachCone)
import numpy as np
import pytest


def test_branch_is_continuous_along_a_line():
    """Poses 1 cm apart on a 1.6 m line: joint steps below 3 deg, one arm branch."""
    rot = np.array(paper.TARGET_ROTATION, dtype=float)
    start, end = np.array([1.2, -0.4, 0.4]), np.array([0.6, 1.0, 0.9])
    tracker = BranchTracker()
    q0 = nearest_branch_ik(pose_from(start, rot), np.zeros(6))
    previous = tracker.solve(pose_from(start, rot), q0)
    branch = arm_branch(previous)
    for s in np.linspace(0.0, 1.0, 161)[1:]:
        q = tracker.solve(pose_from(start + s * (end - start), rot))
        assert np.max(np.abs(q - previous)) < math.radians(3.0)
        assert arm_branch(q) == branch
        previous = q


@pytest.mark.parametrize('scenario', [1, 2, 3])
def test_paper_poses_keep_their_branch(scenario):
    """The nearest branch is already in the cone: the same array as inverse_kinematics."""
    pose = paper.scenario_start_pose(scenario)
    q0 = inverse_kinematics(pose)
    assert np.array_equal(nearest_branch_ik(pose, np.zeros(6)), q0)
    assert in_cone(q0)
    target = paper.target_pose()
    assert np.array_equal(nearest_branch_ik(target, q0, same_arm_as=q0),
                          inverse_kinematics(target, seed=q0))


def test_over_the_head_seed_gets_the_front_arm():
    """Seeded on the shoulder-flipped arm, the cone still answers with the arm in front."""
    pose = paper.scenario_start_pose(2)
    flipped = [q for q in ik_solutions(pose) if arm_branch(q) == (-1, -1)]
    assert flipped, 'scenario 2 has an over-the-head branch'
    assert inverse_kinematics(pose, seed=flipped[0]) is not None
    assert arm_branch(inverse_kinematics(pose, seed=flipped[0])) == (-1, -1)
    q = nearest_branch_ik(pose, flipped[0])
    assert arm_branch(q) == (1, 1) and in_cone(q)


def test_no_branch_in_the_cone_raises():
    """A cone no branch satisfies: UnreachablePoseError, never a silent other branch."""
    with pytest.raises(UnreachablePoseError):
        nearest_branch_ik(paper.target_pose(), np.zeros(6), cone=ReachCone(
            max_elevation_deg=-89.0))
