"""The workspace task sampler: reachable, in view, margins kept, seeded; and scene.discs_apart."""

import math

from ibvs_model import paper, task_sampler
from ibvs_model.robot import (fiducial_points, forward_kinematics, inverse_kinematics,
                              IRB4600, pose_error, pose_from)
from ibvs_model.scene import discs_apart, MARKER_RADIUS_M, wrist_clear
import numpy as np
import pytest

MODEL = task_sampler.default_model()
MARGINS = task_sampler.Margins()


@pytest.fixture(scope='module')
def tasks():
    return task_sampler.tasks(40, 11)


def test_every_target_is_reachable_within_the_joint_margins(tasks):
    lo = np.asarray(IRB4600.q_min) + MARGINS.joint_margin_rad
    hi = np.asarray(IRB4600.q_max) - MARGINS.joint_margin_rad
    for task in tasks:
        pose = pose_from(task['target_position'],
                         np.reshape(task['target_rotation'], (3, 3)))
        assert np.allclose(np.reshape(task['target_rotation'], (3, 3)) @
                           np.reshape(task['target_rotation'], (3, 3)).T, np.eye(3),
                           atol=1e-9)
        q = np.asarray(task['target_joints'])
        assert max(pose_error(forward_kinematics(q, IRB4600), pose)) < 1e-9
        assert np.all(q >= lo) and np.all(q <= hi)
        # The simulator's own IK (no seed) reaches the target too.
        assert pose_error(forward_kinematics(inverse_kinematics(pose, IRB4600), IRB4600),
                          pose)[0] < 1e-6
        start = np.asarray(task['start_joints'])
        assert np.all(start >= lo) and np.all(start <= hi)
        assert np.all(np.abs(start - q) <= MARGINS.start_offset_rad + 1e-12)


def test_both_markers_are_in_view_of_both_lenses_with_the_margin(tasks):
    camera = MODEL.camera
    for task in tasks:
        points = fiducial_points(task['target_joints'], IRB4600)
        depth = camera.to_camera(points)[:, 2]
        assert depth.min() >= MARGINS.min_depth_m
        uv = camera.project(points)  # (u_l, u_r, v) per marker
        radius = camera.intrinsics.fu * MARKER_RADIUS_M / depth.min()
        margin = radius + MARGINS.image_margin_px
        k = camera.intrinsics
        assert np.all(uv[:, :2] >= margin - 0.5) and np.all(uv[:, :2] <= k.width - 0.5 - margin)
        assert np.all(uv[:, 2] >= margin - 0.5) and np.all(uv[:, 2] <= k.height - 0.5 - margin)
        assert discs_apart(camera, points) and wrist_clear(camera, points)


def test_targets_and_starts_are_clear_of_pedestal_floor_and_camera(tasks):
    eye = np.asarray(paper.CAMERA_EYE)
    for task in tasks:
        for q, name in ((task['target_joints'], 'target'), (task['start_joints'], 'start')):
            points = np.vstack([fiducial_points(q, IRB4600),
                                forward_kinematics(q, IRB4600)[:3, 3]])
            radial = np.hypot(points[:, 0], points[:, 1])
            low = points[:, 2] < MARGINS.pedestal_top_m + MARGINS.pedestal_clearance_m
            assert np.all(radial[low] >= MARGINS.pedestal_radius_m +
                          MARGINS.pedestal_clearance_m), name
            assert np.all(points[:, 2] > -MARGINS.mount_height_m + MARGINS.floor_clearance_m)
        markers = fiducial_points(task['target_joints'], IRB4600)
        assert np.linalg.norm(markers - eye, axis=1).min() >= MARGINS.camera_clearance_m


def test_tasks_are_deterministic_by_seed_and_a_prefix_of_a_longer_set(tasks):
    assert task_sampler.tasks(40, 11) == tasks
    assert task_sampler.tasks(5, 11) == tasks[:5]
    other = task_sampler.tasks(5, 12)
    assert [t['target_position'] for t in other] != [t['target_position'] for t in tasks[:5]]
    assert [t['id'] for t in tasks[:2]] == [
        f'{task_sampler.VERSION}/11/0', f'{task_sampler.VERSION}/11/1']
    # The targets spread over the workspace: not one corner of the box.
    xyz = np.array([t['target_position'] for t in tasks])
    assert np.ptp(xyz[:, 0]) > 1.0 and np.ptp(xyz[:, 2]) > 0.3


def test_observability_is_the_feature_motion_of_the_worst_tilt_no_translation_explains():
    q = inverse_kinematics(paper.target_pose(), IRB4600)
    # By finite differences: tilt the tool about P1 through small angles about each
    # direction perpendicular to the axis and take the feature change left over after the
    # best translation of the whole tool.
    p1, p2 = fiducial_points(q, IRB4600)
    axis = (p2 - p1) / np.linalg.norm(p2 - p1)
    h = 1e-6

    def features(a, b):
        return MODEL.camera.project(np.vstack([a, b])).reshape(6)

    base = features(p1, p2)
    trans = np.column_stack([(features(p1 + h * e, p2 + h * e) - base) / h
                             for e in np.eye(3)])
    worst = math.inf
    for angle in np.linspace(0.0, math.pi, 181):
        w = np.cross(axis, [1.0, 0.0, 0.0])
        w /= np.linalg.norm(w)
        w = math.cos(angle) * w + math.sin(angle) * np.cross(axis, w)
        col = (features(p1, p2 + h * np.cross(w, p2 - p1)) - base) / h
        resid = col - trans @ np.linalg.lstsq(trans, col, rcond=None)[0]
        worst = min(worst, np.linalg.norm(resid))
    assert task_sampler.axis_observability(MODEL, q) == pytest.approx(worst, rel=1e-3)
    # The paper's target is a task the sampler accepts.
    assert task_sampler.target_check(MODEL, q) is None


def test_discs_apart_takes_each_disc_at_its_own_depth_in_both_images():
    q = inverse_kinematics(paper.target_pose(), IRB4600)
    points = fiducial_points(q, IRB4600)
    uv = MODEL.camera.project(points)
    depth = MODEL.camera.to_camera(points)[:, 2]
    radii = MODEL.camera.intrinsics.fu * MARKER_RADIUS_M / depth
    left = math.hypot(uv[0, 0] - uv[1, 0], uv[0, 2] - uv[1, 2])
    right = math.hypot(uv[0, 1] - uv[1, 1], uv[0, 2] - uv[1, 2])
    gap = min(left, right) - radii.sum()  # edge to edge, the closer image
    assert discs_apart(MODEL.camera, points, gap_px=gap - 1e-6)
    assert not discs_apart(MODEL.camera, points, gap_px=gap + 1e-6)
    # The paper's target, refused before (19.9 px between the centres against 20.1 px).
    assert discs_apart(MODEL.camera, points) and wrist_clear(MODEL.camera, points)


def test_wrist_clear_is_the_angle_of_each_lens_from_behind_the_wrist():
    q = inverse_kinematics(paper.target_pose(), IRB4600)
    p1, p2 = fiducial_points(q, IRB4600)
    back = (p1 - p2) / np.linalg.norm(p1 - p2)
    half_b = MODEL.camera.intrinsics.baseline / 2.0  # the lenses at -b/2 and +b/2 on x_C
    lenses = MODEL.camera.to_base(np.array([[-half_b, 0.0, 0.0], [half_b, 0.0, 0.0]]))
    angles = [math.degrees(math.acos((lens - p1) @ back / np.linalg.norm(lens - p1)))
              for lens in lenses]
    assert wrist_clear(MODEL.camera, np.vstack([p1, p2]), min(angles) - 1e-6)
    assert not wrist_clear(MODEL.camera, np.vstack([p1, p2]), min(angles) + 1e-6)
    # The tool turned to point straight away from the camera: the wrist hides P1.
    toward = (lenses[0] - p1) / np.linalg.norm(lenses[0] - p1)
    assert not wrist_clear(MODEL.camera, np.vstack([p1, p1 - 0.1 * toward]))


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match='n:'):
        task_sampler.tasks(-1, 0)
    with pytest.raises(ValueError, match='seed:'):
        task_sampler.tasks(1, -2)
    with pytest.raises(RuntimeError, match='margins'):
        task_sampler.tasks(1, 0, margins=task_sampler.Margins(min_depth_m=50.0),
                           max_tries=200)
