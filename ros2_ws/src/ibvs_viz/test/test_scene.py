"""The frames the viewers' node adds (tool, camera) give ibvs_model's eq. (8-10) and camera."""

import json
from pathlib import Path
import re

from ibvs_common import contract
from ibvs_model import abb_urdf, default_camera, forward_kinematics, IRB4600
from ibvs_model.robot import fiducial_points
from ibvs_viz import scene
import numpy as np
import pytest

#: Joint angles across the ranges (rad), the zero pose among them.
ANGLES = np.array([[0.0] * 6,
                   [0.3, -0.4, 0.5, 1.2, -0.8, 2.0],
                   [-2.5, 1.0, -1.5, -5.0, 1.9, 6.5],
                   [1.7, 2.2, 1.2, 3.1, -2.0, -3.3]])
PARAMS = (IRB4600, IRB4600.scaled(0.8, 1.15))


@pytest.mark.parametrize('params', PARAMS)
def test_the_tool_on_abbs_tool0_gives_the_markers(params):
    for q in ANGLES:
        tool0 = abb_urdf.tool0_pose(q, params)
        poses = {child: tool0 @ tf for parent, child, tf in scene.tool_transforms(params)
                 if parent == 'tool0'}
        assert set(poses) == set(scene.TOOL_FRAMES)
        np.testing.assert_allclose(poses['screwdriver'], forward_kinematics(q, params),
                                   atol=1e-12)
        markers = np.array([poses['marker_1'][:3, 3], poses['marker_2'][:3, 3]])
        np.testing.assert_allclose(markers, fiducial_points(q, params), atol=1e-12)


def test_the_tool_solids_sit_in_the_tool_frames():
    solids = scene.tool_solids()
    assert {frame for frame, _ in solids} == set(scene.TOOL_FRAMES)
    shaft = [s for frame, s in solids if frame == 'screwdriver'][0]
    assert shaft.kind == 'cylinder' and shaft.size[1] == IRB4600.L_tool


def test_lens_frames_are_where_the_projection_puts_the_lenses():
    camera = default_camera('VGA')
    b = camera.intrinsics.baseline
    frames = {child: (parent, tf) for parent, child, tf in
              scene.camera_transforms(camera.pose_C_O, b)}
    left = camera.pose_C_O @ frames[contract.LEFT_CAMERA_FRAME][1]
    # A point on the left lens's optical axis projects to the left principal point.
    point = left[:3, :3] @ [0.0, 0.0, 2.0] + left[:3, 3]
    u_l, u_r, v = camera.project(point[None])[0]
    k = camera.intrinsics
    assert u_l == pytest.approx(k.cu, abs=1e-9)
    assert v == pytest.approx(k.cv, abs=1e-9)
    assert u_l - u_r == pytest.approx(k.fu * b / 2.0, rel=1e-9)


def test_frustum_reaches_the_image_corners():
    camera = default_camera('VGA')
    k = camera.intrinsics
    lines = scene.frustum_lines(k, 2.0)
    assert lines.shape == (16, 3)
    far = lines[1::4]
    u = k.fu * far[:, 0] / far[:, 2] + k.cu
    v = k.fv * far[:, 1] / far[:, 2] + k.cv
    np.testing.assert_allclose(sorted(set(np.round(u, 9))), [-0.5, k.width - 0.5])
    np.testing.assert_allclose(sorted(set(np.round(v, 9))), [-0.5, k.height - 0.5])


def test_foxglove_layout_shows_the_graphs_topics():
    """Every topic the shipped layout names is one the graph publishes (contract names)."""
    layout = json.loads((Path(__file__).resolve().parents[1] / 'config'
                         / 'foxglove_layout.json').read_text())
    names = set(re.findall(r'"(/[a-z_/]+)', json.dumps(layout['configById'])))
    published = {getattr(contract, n) for n in dir(contract)
                 if isinstance(getattr(contract, n), str) and getattr(contract, n).startswith('/')}
    assert names and names <= published
    panels = set(re.findall(r'"([A-Za-z0-9]+![a-z0-9]+)"', json.dumps(layout['layout'])))
    assert panels == set(layout['configById'])
