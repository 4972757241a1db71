"""Pose, PoseStamped, TFMessage and Path <-> 4x4 transforms, and the camera's pose read."""

from ibvs_common import contract, conversions
from ibvs_common.conversions import InputError
from ibvs_model import default_model, forward_kinematics
import numpy as np
import pytest
from scipy.spatial.transform import Rotation


def _transforms(rng, n):
    """Return ``n`` random rigid transforms (N, 4, 4), positions within 20 m."""
    tfs = np.tile(np.eye(4), (n, 1, 1))
    tfs[:, :3, :3] = Rotation.random(n, random_state=rng).as_matrix()
    tfs[:, :3, 3] = rng.uniform(-20.0, 20.0, size=(n, 3))
    return tfs


def _reason(call, *args):
    with pytest.raises(InputError) as caught:
        call(*args)
    return caught.value.reason


def test_pose_round_trip():
    tf = forward_kinematics(np.radians([10, 20, 30, 40, 50, 60]))
    back = conversions.pose_matrix(conversions.matrix_pose(tf))
    np.testing.assert_allclose(back, tf, atol=1e-12)
    bad = conversions.matrix_pose(tf)
    bad.orientation.w = 5.0
    with pytest.raises(InputError, match='quaternion'):
        conversions.pose_matrix(bad)


def test_pose_matrix_inverts_matrix_pose_on_random_transforms():
    rng = np.random.default_rng(41)
    for tf in _transforms(rng, 500):
        pose = conversions.matrix_pose(tf)
        # the position travels as it is; the rotation through a unit quaternion
        assert [pose.position.x, pose.position.y, pose.position.z] == tf[:3, 3].tolist()
        np.testing.assert_allclose(conversions.pose_matrix(pose), tf, rtol=0, atol=1e-12)


def test_a_batch_of_poses_is_each_transforms_own_pose():
    tfs = _transforms(np.random.default_rng(42), 20)
    for pose, tf in zip(conversions.matrix_poses(tfs), tfs):
        assert pose == conversions.matrix_pose(tf)


def test_a_non_finite_pose_is_refused():
    for attr in ('position', 'orientation'):
        for bad in (np.nan, np.inf):
            pose = conversions.matrix_pose(np.eye(4))
            getattr(pose, attr).x = float(bad)
            assert _reason(conversions.pose_matrix, pose) == 'non-finite pose'


def test_transforms_msg_stamps_each_transform_in_its_frames():
    tfs = _transforms(np.random.default_rng(43), 3)
    stamp = conversions.ns_stamp(34_000_000)
    triples = [('base', 'a', tfs[0]), ('a', 'b', tfs[1]), ('base', 'c', tfs[2])]
    msg = conversions.transforms_msg(triples, stamp)
    assert [(t.header.frame_id, t.child_frame_id) for t in msg.transforms] == \
        [(parent, child) for parent, child, _ in triples]
    for t, tf in zip(msg.transforms, tfs):
        assert t.header.stamp == stamp
        pose = conversions.matrix_pose(tf)
        assert t.transform.rotation == pose.orientation
        assert [t.transform.translation.x, t.transform.translation.y,
                t.transform.translation.z] == tf[:3, 3].tolist()


def test_pose_stamped_and_path_read_back_as_their_transforms():
    tfs = _transforms(np.random.default_rng(44), 4)
    msg = conversions.pose_stamped(tfs[0], 7, 'camera')
    assert conversions.stamp_ns(msg.header.stamp) == 7 and msg.header.frame_id == 'camera'
    np.testing.assert_allclose(conversions.pose_matrix(msg.pose), tfs[0], atol=1e-12)
    stamps = [10, 20, 30, 40]
    path = conversions.path_msg(list(zip(stamps, tfs)))
    assert path.header.frame_id == contract.BASE_FRAME
    assert path.header.stamp == path.poses[-1].header.stamp  # stamped with the last pose
    assert [conversions.stamp_ns(p.header.stamp) for p in path.poses] == stamps
    for pose, tf in zip(path.poses, tfs):
        assert pose.header.frame_id == contract.BASE_FRAME
        np.testing.assert_allclose(conversions.pose_matrix(pose.pose), tf, atol=1e-12)
    empty = conversions.path_msg([])
    assert not empty.poses and conversions.stamp_ns(empty.header.stamp) == 0


def test_a_camera_pose_far_from_the_robot_or_looking_away_is_refused():
    tf = default_model().camera.pose_C_O
    for msg in (conversions.pose_stamped(tf, 0), conversions.matrix_pose(tf)):
        np.testing.assert_allclose(conversions.read_camera_pose(msg), tf, atol=1e-12)
    far = tf.copy()
    far[:3, 3] *= conversions.MAX_CAMERA_DISTANCE_M / np.linalg.norm(tf[:3, 3]) * 1.01
    assert _reason(conversions.read_camera_pose, conversions.matrix_pose(far)) == \
        'camera too far from the robot'
    away = tf @ np.diag([1.0, -1.0, -1.0, 1.0])  # turned about its x axis: the base behind
    assert _reason(conversions.read_camera_pose, conversions.matrix_pose(away)) == \
        'camera looks away from the robot'
