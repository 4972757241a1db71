"""
Acceptance of the detector on frames rendered by the simulator's PyBullet world (ibvs_sim).

- 50 random in-view poses at HD720 (tool pointing down within 35 degrees, both markers
  wholly inside both images): every pair is measured, and against the model projection of
  the true marker centres (eq. 16-22) the median error is at most 0.1 px, the largest at
  most 0.3 px.
- 20 frames where no marker is visible: 10 with both markers out of the field of view
  (the scenario 2/3 start among them), 10 with the markers in the field of view but hidden
  behind the arm (the tool pointing away from the camera). The simulator's own colour masks
  confirm that no marker pixel shows; the detector must report 'not in view' without a
  single candidate.

Rendering is the slow part (the simulator's OpenGL renderer, ibvs_sim.gl_renderer): every
frame is rendered once per module.
"""

from ibvs_model import (fiducial_points, forward_kinematics, ik_position_axis,
                        inverse_kinematics, paper, scene, UnreachablePoseError)
from ibvs_sim import markers
from ibvs_sim.world import DEFAULT_FOCUS_SUPERSAMPLING, DEFAULT_SUPERSAMPLING
from ibvs_vision.detector import Reason, StereoDetector
import numpy as np
import pytest


@pytest.fixture
def any_world(world):
    """Return the module's World (the one renderer)."""
    return world


def _render(world, camera, q):
    world.reset(q)
    return world.render_stereo(camera)


def _no_marker_pixels(left, right):
    return not any(mask.any() for image in (left, right)
                   for mask in markers.colour_masks(image))


@pytest.fixture(scope='module')
def in_view_frames(world, hd_model):
    rng = np.random.default_rng(2024)
    return [(q, _render(world, hd_model.camera, q))
            for q in scene.in_view_poses(hd_model, 50, rng)]


@pytest.fixture(scope='module')
def no_marker_frames(world, hd_model):
    camera = hd_model.camera
    rng = np.random.default_rng(7)
    out_of_view = [inverse_kinematics(paper.scenario_start_pose(2))]
    lo, hi = np.array(hd_model.params.q_min), np.array(hd_model.params.q_max)
    while len(out_of_view) < 10:
        q = rng.uniform(lo, hi)
        if not np.any(camera.in_view(fiducial_points(q))):
            out_of_view.append(q)
    frames = [('out of view', q, _render(world, camera, q)) for q in out_of_view]
    eye = camera.pose_C_O[:3, 3]
    hidden = 0
    for _ in range(200):
        if hidden == 10:
            break
        pos = rng.uniform([-1.2, -0.3, 0.25], [1.4, 0.35, 1.2])
        if np.hypot(pos[0], pos[1]) < 0.6:
            continue
        away = (pos - eye) / np.linalg.norm(pos - eye) + rng.normal(0.0, 0.1, 3)
        try:
            q = ik_position_axis(pos, away, rng.uniform(-np.pi, np.pi))
        except UnreachablePoseError:
            continue
        if not np.all(camera.in_view(fiducial_points(q), margin_px=20.0)):
            continue
        images = _render(world, camera, q)
        if _no_marker_pixels(*images):
            frames.append(('hidden by the arm', q, images))
            hidden += 1
    return frames


def test_fifty_rendered_pairs_within_a_tenth_of_a_pixel(in_view_frames, hd_model):
    camera = hd_model.camera
    detector = StereoDetector(camera.intrinsics)
    assert len(in_view_frames) == 50
    errors = []
    for q, (left, right) in in_view_frames:
        result = detector.detect(left, right)
        assert result.ok, (result.reason, result.detail)
        errors.append(result.features - camera.project(fiducial_points(q)).reshape(6))
    errors = np.abs(errors)
    assert np.median(errors) <= 0.1, np.median(errors)
    assert errors.max() <= 0.3, errors.max()


def test_twenty_frames_without_a_visible_marker_give_no_detection(no_marker_frames, hd_model):
    detector = StereoDetector(hd_model.camera.intrinsics)
    kinds = [kind for kind, _, _ in no_marker_frames]
    assert kinds.count('out of view') == 10 and kinds.count('hidden by the arm') == 10
    for kind, q, (left, right) in no_marker_frames:
        assert _no_marker_pixels(left, right), kind
        if kind == 'hidden by the arm':
            assert np.all(hd_model.camera.in_view(fiducial_points(q)))
        result = detector.detect(left, right)
        assert result.reason is Reason.NOT_IN_VIEW, (kind, result.detail)
        for side in (result.left, result.right):
            assert side.blobs == ((), ()) and side.rejected == {}, kind


def test_target_pose_measurement_does_not_depend_on_joint_6(any_world, hd_model):
    """
    At the target, turning joint 6 (which moves no marker centre) moves no measured feature.

    This is what the end-to-end accuracy rests on: the feedback drives the measured
    features onto F(q_target), so a measurement bias becomes a pose error; at 2.4 m one
    hundredth of a pixel of disparity is 0.7 mm of depth, and 0.004 px of vertical
    separation between the markers is 0.1 deg of tool axis (the weakest direction of C1).
    Rendered as the simulator does (fine icosphere, 8 x 8 samples per pixel around the
    markers), the features spread by at most 0.006 px over 8 angles of joint 6 and are
    within 0.015 px of the model (measured); PyBullet's sphere primitive spread them by up
    to 0.3 px.
    """
    camera = hd_model.camera
    detector = StereoDetector(camera.intrinsics)
    q_target = inverse_kinematics(paper.target_pose())
    errors = []
    for q6 in np.linspace(-np.pi, np.pi, 8, endpoint=False):
        q = q_target.copy()
        q[5] = q6
        errors.append(_simulator_error(any_world, camera, detector, q))
    errors = np.array(errors)
    assert np.ptp(errors, axis=0).max() <= 0.015, np.ptp(errors, axis=0)
    assert np.abs(errors).max() <= 0.025, errors


def _simulator_error(world, camera, detector, q):
    """Return the measured p_I minus the model's, rendered as the simulator does."""
    world.reset(q)
    result = detector.detect(*world.render_stereo(
        camera, DEFAULT_SUPERSAMPLING, world.marker_spheres(), DEFAULT_FOCUS_SUPERSAMPLING))
    assert result.ok, (result.reason, result.detail)
    return result.features - camera.project(fiducial_points(q)).reshape(6)


def test_near_the_target_the_rods_across_the_markers_cost_no_accuracy(any_world, hd_model):
    """
    Near the target the tool axis is within 0.05 deg and the flange within 0.5 mm, to first order.

    20 poses within a few millimetres of the target: the pose that the measured features
    imply (q - pinv(C1) e, the loop's fixed point to first order) is compared with the true
    one, and no coordinate is biased by more than 0.002 px over the 20. The quill and the
    shaft lie on the tool axis: they cut a notch into the top of each marker and darken the
    background behind its bottom rim. Without filling the notches (area centroid alone) the
    vertical centres were 0.07 and 0.09 px low and the implied axis 0.16 deg off (rms);
    filling them from the other side, 0.06 deg rms with PyBullet's images, but with the
    'opengl' renderer's marker 1's v stayed 0.009 px low (0.088 deg rms): the bottom rim
    it was mirrored from is itself wrong. Leaving out a band along the axis through both
    markers (refine.axis_band_centre): biases within 0.001 px and 0.03 deg rms (measured).
    """
    camera = hd_model.camera
    detector = StereoDetector(camera.intrinsics)
    q_target = inverse_kinematics(paper.target_pose())
    rng = np.random.default_rng(1)
    position, axis, errors = [], [], []
    for _ in range(20):
        q = q_target + rng.normal(0.0, 0.003, 6)
        e = _simulator_error(any_world, camera, detector, q)
        errors.append(e)
        q_fixed = q - np.linalg.pinv(hd_model.jacobian(q), rcond=1e-6) @ e
        t_true, t_fixed = forward_kinematics(q), forward_kinematics(q_fixed)
        position.append(np.linalg.norm(t_fixed[:3, 3] - t_true[:3, 3]))
        axis.append(np.degrees(np.arccos(np.clip(t_true[:3, 2] @ t_fixed[:3, 2], -1.0, 1.0))))
    assert np.abs(np.mean(errors, axis=0)).max() <= 0.002, np.mean(errors, axis=0)
    assert np.sqrt(np.mean(np.square(axis))) <= 0.05, axis
    assert np.sqrt(np.mean(np.square(position))) <= 0.5e-3, position
