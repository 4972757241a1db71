"""
ABB's link frames (ibvs_model.abb_urdf) against ABB's numbers, a URDF parser and eq. (7).

ABB's tool0 is the paper's flange {E} with the same joint angles and no constant transform
on either side; each link frame is the DH-framed link of ibvs_model.urdf times a constant.
"""

import io
import math

from ibvs_model import abb_urdf, forward_kinematics, IRB4600
from ibvs_model.urdf import joint_origins as dh_origins
import numpy as np
import pytest

#: Four configurations: the zero pose, and three with every joint away from zero.
CONFIGS = np.array([[0.0] * 6,
                    [0.3, -0.4, 0.5, 1.2, -0.8, 2.0],
                    [-2.5, 1.0, -1.5, -5.0, 1.9, 6.5],
                    [1.7, 2.2, 1.2, 3.1, -2.0, -3.3]])
PARAMS = (IRB4600, IRB4600.scaled(0.8, 1.15))


def _random_q(n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(IRB4600.q_min, IRB4600.q_max, size=(n, 6))


def test_the_nominal_arm_has_abbs_numbers():
    for (name, _, _, xyz, _, lower, upper, speed), ours, lo, hi, qd in zip(
            abb_urdf.ABB_JOINTS, abb_urdf.joint_origins(IRB4600), IRB4600.q_min,
            IRB4600.q_max, IRB4600.qd_max):
        assert ours == pytest.approx(xyz, abs=1e-15), name
        # ABB's file rounds the same limits (and speeds) down to 1 mrad.
        assert 0.0 <= lower - lo < 1e-3 and 0.0 <= hi - upper < 1e-3, name
        assert 0.0 <= qd - speed < 1e-3, name


@pytest.mark.parametrize('params', PARAMS)
def test_tool0_is_the_papers_flange_with_the_same_angles(params):
    """T_tool0^base_link(q) = T_E^O(q) (eq. 7): no joint offset, no sign, no fixed transform."""
    for q in np.vstack([CONFIGS, _random_q(2000, 7)]):
        np.testing.assert_allclose(abb_urdf.tool0_pose(q, params),
                                   forward_kinematics(q, params), atol=1e-12)


def test_a_sign_or_zero_change_would_be_seen():
    q = CONFIGS[1]
    for i in range(6):
        flipped = q.copy()
        flipped[i] = -flipped[i]
        assert np.abs(abb_urdf.tool0_pose(flipped) - forward_kinematics(q)).max() > 1e-3
        shifted = q.copy()
        shifted[i] += 1e-3
        assert np.abs(abb_urdf.tool0_pose(shifted) - forward_kinematics(q)).max() > 1e-4


def test_link_frames_at_four_configurations_by_hand_and_by_a_urdf_parser():
    yourdfpy = pytest.importorskip('yourdfpy')
    urdf = yourdfpy.URDF.load(io.StringIO(abb_urdf.robot_description()),
                              build_scene_graph=True, load_meshes=False)
    assert list(urdf.actuated_joint_names) == list(abb_urdf.JOINT_NAMES)
    for q in CONFIGS:
        poses = abb_urdf.link_poses(q)
        urdf.update_cfg(q)
        for frame in abb_urdf.LINK_NAMES + ('base', 'flange', 'tool0'):
            np.testing.assert_allclose(poses[frame], urdf.get_transform(frame, 'base_link'),
                                       atol=1e-12, err_msg=frame)
    # By hand at the zero pose: every link frame is parallel to base_link, on the arm.
    zero = abb_urdf.link_poses(np.zeros(6))
    for frame, xyz in (('link_1', (0, 0, 0.495)), ('link_2', (0.175, 0, 0.495)),
                       ('link_3', (0.175, 0, 1.395)), ('link_4', (0.175, 0, 1.57)),
                       ('link_5', (1.135, 0, 1.57)), ('link_6', (1.27, 0, 1.57))):
        np.testing.assert_allclose(zero[frame][:3, :3], np.eye(3), atol=1e-15)
        np.testing.assert_allclose(zero[frame][:3, 3], xyz, atol=1e-15)
    # Joint 2 at +90 deg lays the upper arm forward: link_3 at x = a1 + L2.
    forward = abb_urdf.link_poses([0.0, math.pi / 2, 0, 0, 0, 0])
    np.testing.assert_allclose(forward['link_3'][:3, 3], (1.075, 0.0, 0.495), atol=1e-15)


@pytest.mark.parametrize('params', PARAMS)
def test_each_link_is_the_dh_link_times_a_constant(params):
    offsets = abb_urdf.dh_link_offsets(params)
    origins = dh_origins(params)
    for q in np.vstack([CONFIGS, _random_q(50, 3)]):
        abb = abb_urdf.link_poses(q, params)
        dh = np.eye(4)
        for i in range(6):
            c, s = math.cos(q[i]), math.sin(q[i])
            turn = np.eye(4)
            turn[:2, :2] = [[c, -s], [s, c]]
            dh = dh @ origins[i] @ turn
            np.testing.assert_allclose(abb[f'link_{i + 1}'] @ offsets[i], dh, atol=1e-12)


def test_the_description_is_abbs_tree_without_our_tool():
    text = abb_urdf.robot_description()
    assert 'filename' not in text and 'screwdriver' not in text and 'marker' not in text
    for name, parent, child, *_ in abb_urdf.ABB_JOINTS + abb_urdf.ABB_FIXED_JOINTS:
        assert f'<joint name="{name}"' in text
        assert f'<parent link="{parent}"/>\n    <child link="{child}"/>' in text


def test_bad_angles_are_refused():
    with pytest.raises(ValueError, match='q'):
        abb_urdf.link_poses([0.0] * 5)
