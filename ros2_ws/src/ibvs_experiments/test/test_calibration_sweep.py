"""The calibration sweep's camera and its textbook result: a taught target cancels the error."""

from ibvs_experiments.calibration_sweep import (calibrated_camera, noise_sweep, noise_table,
                                                POSITION_ERROR_DIRECTION, run_one, table)
from ibvs_model import default_model
import numpy as np
import pytest


def test_calibrated_camera_moves_and_scales_as_asked():
    true = default_model().camera
    cam = calibrated_camera(true, 0.01, 0.02)
    offset = np.linalg.inv(true.pose_C_O) @ cam.pose_C_O
    np.testing.assert_allclose(offset[:3, 3], 0.01 * POSITION_ERROR_DIRECTION, atol=1e-12)
    np.testing.assert_allclose(offset[:3, :3], np.eye(3), atol=1e-12)
    assert cam.intrinsics.fu == pytest.approx(1.02 * true.intrinsics.fu)
    assert cam.intrinsics.cu == true.intrinsics.cu


def test_ibvs_with_a_taught_target_cancels_the_camera_error_and_a_model_target_does_not():
    model = run_one('ibvs', 'model', position_error_m=0.005, duration_s=2.0)
    taught = run_one('ibvs', 'taught', position_error_m=0.005, duration_s=2.0)
    # the model target is F(q_target) seen by the wrong camera: the tool ends as far off
    assert model.final_position_error_m == pytest.approx(0.005, rel=0.05)
    assert taught.final_position_error_m < 1e-4
    lines = table([model, taught])
    assert len(lines) == 4 and '5.00 mm' in lines[2]


def test_feature_noise_moves_the_tool_and_more_noise_moves_it_more():
    results = noise_sweep(laws=('ibvs',), noise_px=(0.0, 0.1, 0.3), duration_s=3.0)
    quiet, some, more = (results['ibvs', s][0] for s in (0.0, 0.1, 0.3))
    assert quiet < 1e-4 < some < more
    assert noise_table(results)[2].startswith('| ibvs | ')
