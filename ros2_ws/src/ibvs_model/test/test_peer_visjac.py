"""
Peer test: our image Jacobians against Corke's machinevision-toolbox-python.

Corke's ``CentralCamera.visjac_p(uv, Z)`` is the classic interaction matrix L (2 x 6) of a
point for a MOVING camera with spatial velocity (v, omega) in its own frame (Hutchinson,
Hager & Corke 1996; Corke, Robotics, Vision and Control, 15.2.1). Our camera is fixed and
the point moves (eye-to-hand): a point moving with velocity pdot^C looks like a camera
moving with -pdot^C and no rotation, so d(u, v)/dP^C = -L[:, :3]. Each lens of the ZED 2
is one CentralCamera (left at x = -b/2 of {C}, right at +b/2, ROS convention), and our
stereo C1 = dF/dq (eq. 31) must be their rows (u_l, u_r, v) stacked for both markers,
times the robot's point Jacobians dP^O/dq.
"""

from ibvs_model import CameraRobotModel, default_model, inverse_kinematics, paper
from ibvs_model.robot import point_jacobian
import numpy as np
import pytest

mvt = pytest.importorskip(
    'machinevisiontoolbox',
    reason="Corke's machinevision-toolbox-python is not installed (it is pinned in "
           'requirements-test.txt; the Docker image does not carry it)')
SE3 = pytest.importorskip('spatialmath').SE3


def corke_cameras(camera):
    """Return Corke's left and right CentralCamera of our stereo model, placed in {O}."""
    k = camera.intrinsics
    cams = []
    for side in (-1.0, 1.0):
        lens = camera.pose_C_O @ np.array([[1, 0, 0, side * k.baseline / 2.0],
                                           [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        cams.append(mvt.CentralCamera(f=1.0, rho=(1.0 / k.fu, 1.0 / k.fv), pp=(k.cu, k.cv),
                                      imagesize=(k.width, k.height), pose=SE3(lens)))
    return cams


def corke_c1(model, q):
    """Return C1 (6, 6) assembled from Corke's per-lens image Jacobians."""
    left, right = corke_cameras(model.camera)
    rot_C_O = model.camera.pose_C_O[:3, :3]
    rows = []
    for point_E, point_O in zip(model.params.fiducials_E, model.markers(q)):
        depth = model.camera.to_camera(point_O[None])[0, 2]
        d_dpc = []
        for cam in (left, right):
            uv = cam.project_point(point_O.reshape(3, 1)).ravel()
            d_dpc.append(-cam.visjac_p(uv, depth)[:, :3] @ rot_C_O.T)
        # rectified pair: both lenses give the same v row
        np.testing.assert_allclose(d_dpc[0][1], d_dpc[1][1], rtol=1e-12, atol=1e-9)
        d_dp = np.vstack([d_dpc[0][0], d_dpc[1][0], d_dpc[0][1]])
        rows.append(d_dp @ point_jacobian(q, point_E, model.params))
    return np.vstack(rows)


@pytest.fixture(scope='module')
def model():
    return default_model()


def test_projection_agrees_with_corke(model):
    left, right = corke_cameras(model.camera)
    points = model.markers(inverse_kinematics(paper.target_pose()))
    ours = model.camera.project(points)
    for cam, column in ((left, 0), (right, 1)):
        uv = cam.project_point(points.T)
        np.testing.assert_allclose(uv[0], ours[:, column], rtol=0, atol=1e-9)
        np.testing.assert_allclose(uv[1], ours[:, 2], rtol=0, atol=1e-9)


@pytest.mark.parametrize('scenario', [1, 2])
def test_point_jacobian_of_each_lens_agrees_with_corke(model, scenario):
    q = inverse_kinematics(paper.scenario_start_pose(scenario))
    camera = model.camera
    for point_O in model.markers(q):
        ours = camera.projection_jacobian(point_O)
        depth = camera.to_camera(point_O[None])[0, 2]
        for cam, row in zip(corke_cameras(camera), (0, 1)):
            uv = cam.project_point(point_O.reshape(3, 1)).ravel()
            theirs = -cam.visjac_p(uv, depth)[:, :3] @ camera.pose_C_O[:3, :3].T
            np.testing.assert_allclose(ours[row], theirs[0], rtol=1e-10, atol=1e-9)
            np.testing.assert_allclose(ours[2], theirs[1], rtol=1e-10, atol=1e-9)


@pytest.mark.parametrize('where', ['target', 'scenario1', 'random'])
def test_stereo_c1_is_built_from_corkes_image_jacobians(model, where):
    if where == 'target':
        q = inverse_kinematics(paper.target_pose())
    elif where == 'scenario1':
        q = inverse_kinematics(paper.scenario_start_pose(1))
    else:
        q = inverse_kinematics(paper.target_pose()) + np.random.default_rng(15).normal(0, 0.05, 6)
    ours = CameraRobotModel(model.camera, model.params).jacobian(q)
    np.testing.assert_allclose(ours, corke_c1(model, q), rtol=1e-9, atol=1e-7)
