"""Capsule distances against hand-computed cases."""

import math

from ibvs_model import inverse_kinematics, paper
from ibvs_model.capsules import (arm_capsules, Capsule, capsule_distance, Cell, clearances,
                                 plane_distance, segment_distance)
import numpy as np
import pytest


@pytest.mark.parametrize('p0, p1, q0, q1, expected', [
    # parallel, 1 apart, overlapping in x
    ((0, 0, 0), (2, 0, 0), (1, 1, 0), (3, 1, 0), 1.0),
    # crossing lines 0.5 apart in z
    ((-1, 0, 0), (1, 0, 0), (0, -1, 0.5), (0, 1, 0.5), 0.5),
    # collinear, end to end 1 apart
    ((0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0), 1.0),
    # skew, closest at the ends: (1, 0, 0) to (2, 1, 1) -> sqrt(3)
    ((0, 0, 0), (1, 0, 0), (2, 1, 1), (2, 3, 1), math.sqrt(3.0)),
    # a point against a segment: distance to its interior
    ((0, 2, 0), (0, 2, 0), (-1, 0, 0), (1, 0, 0), 2.0),
    # two points
    ((0, 0, 0), (0, 0, 0), (3, 4, 0), (3, 4, 0), 5.0),
])
def test_segment_distance(p0, p1, q0, q1, expected):
    """Ericson's closest points give the hand-computed distance, either order."""
    assert segment_distance(p0, p1, q0, q1) == pytest.approx(expected)
    assert segment_distance(q0, q1, p0, p1) == pytest.approx(expected)


def test_capsule_and_plane():
    """Radii come off the segment distance; a plane sees the lower end."""
    a = Capsule('a', (0, 0, 1), (1, 0, 1), 0.1)
    b = Capsule('b', (0, 0, 2), (1, 0, 2), 0.2)
    assert capsule_distance(a, b) == pytest.approx(0.7)
    assert plane_distance(Capsule('c', (0, 0, 0.5), (0, 0, 2), 0.1), 0.0) == pytest.approx(0.4)


def test_arm_capsules_follow_the_chain():
    """Each capsule starts where the previous one ends; the tool ends L_tool past P1."""
    q = inverse_kinematics(paper.target_pose())
    caps = arm_capsules(q)
    for prev, nxt in zip(caps, caps[1:]):
        assert np.allclose(prev.b, nxt.a)
    assert np.allclose(caps[-1].a, paper.TARGET_POSITION)
    assert np.allclose(caps[-1].b, np.array(paper.TARGET_POSITION) + [0, 0, -0.127])


def test_clearances_at_the_target():
    """The target pose: tool 0.17 m above the base plane, far from floor and camera."""
    q = inverse_kinematics(paper.target_pose())
    self_d, scene_d, closest = clearances(q, Cell())
    assert self_d > 0.1 and scene_d > 0.1
    # the floor 0.5 m below the base plane: the tool tip (z 0.173) less its radius
    assert clearances(q, Cell(mount_height_m=0.0))[1] <= 0.173 - 0.025 + 1e-9
