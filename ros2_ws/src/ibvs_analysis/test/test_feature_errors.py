"""analysis.feature_errors: measured features against the true projection."""

from ibvs_analysis.analysis import feature_errors, RunData
from ibvs_model import (forward_kinematics, inverse_kinematics, IRB4600, look_at, paper,
                        StereoCamera, StereoIntrinsics)
import numpy as np
import pytest


def _run(modes, offsets, camera):
    """Return a RunData of three frames at the target pose, features = truth + offsets."""
    q = inverse_kinematics(paper.target_pose())
    tf = forward_kinematics(q)
    t = np.array([0.0, 0.001, 0.034, 0.067])
    truth = camera.project(IRB4600.fiducials_E @ tf[:3, :3].T + tf[:3, 3]).reshape(6)
    frames = t[[0, 2, 3]]
    return RunData(params={}, run_info={}, t=t, position=np.tile(tf[:3, 3], (4, 1)),
                   rotation=np.tile(tf[:3, :3], (4, 1, 1)), target=tf,
                   feature_t=frames, features=truth + np.asarray(offsets, float),
                   mode_t=frames, modes=list(modes), camera=camera)


def test_only_measured_frames_count_and_the_error_is_what_was_added():
    camera = StereoCamera(StereoIntrinsics.zed2('HD720'),
                          look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT))
    offsets = [[0.01, -0.02, 0.0, 0.0, 0.03, 0.0], [5.0] * 6, [0.0, 0.0, -0.04, 0.0, 0.0, 0.0]]
    errors = feature_errors(_run(['measured', 'estimated', 'measured'], offsets, camera))
    assert errors.shape == (2, 6)
    assert np.allclose(errors, [offsets[0], offsets[2]], atol=1e-9)
    none = feature_errors(_run(['estimated', 'blending', 'estimated'], offsets, camera))
    assert none.shape == (0, 6)


def test_a_run_without_camera_is_refused():
    camera = StereoCamera(StereoIntrinsics.zed2('VGA'),
                          look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT))
    run = _run(['measured'] * 3, np.zeros((3, 6)), camera)
    run.camera = None
    with pytest.raises(ValueError, match='camera'):
        feature_errors(run)
