"""The local minimum of classic IBVS (local_minimum.py): stationary away from the target."""

import json
from pathlib import Path

from ibvs_analysis import local_minimum
from ibvs_control.closed_loop import LoopConfig, simulate
from ibvs_model import default_model, inverse_kinematics, IRB4600, paper
import numpy as np

DOCS = Path(__file__).resolve().parents[4] / 'docs' / 'vsbench' / 'ibvs_local_minimum.json'
MODEL = default_model('HD720')


def _target():
    q_target = inverse_kinematics(paper.target_pose(), IRB4600)
    return q_target, MODEL.features(q_target)


def test_at_the_target_the_error_and_the_step_are_zero_and_the_path_ends_there():
    q_target, p_target = _target()
    error, step = local_minimum.stationarity(MODEL, q_target[None, :], p_target)
    assert error[0] < 1e-9 and step[0] < 1e-9
    q_from = q_target + np.radians([5.0, -3.0, 4.0, 0.0, 6.0, 0.0])
    s, along = local_minimum.path_profile(MODEL, q_from, q_target, p_target, points=11)
    assert s[0] == 0.0 and s[-1] == 1.0 and along[-1] < 1e-9 and along[0] > 1.0


def test_the_documented_stall_is_a_stationary_point_of_the_law_behind_a_barrier():
    # docs/vsbench/ibvs_local_minimum.json: where scenario 1's classic IBVS run ended. The
    # model loop started there stays there (the law's own fixed point, without the graph),
    # and the straight joint path to the target climbs before it descends.
    numbers = json.loads(DOCS.read_text())
    q_end = np.radians(numbers['end_joints_deg'])
    config = LoopConfig.for_law('ibvs', start_joints=tuple(q_end), lambda_0=6.0)
    result = simulate(config, 1.0, disturbance=np.zeros(6))
    q_target, p_target = _target()
    moved = np.linalg.norm(result.q_true[-1][:5] - q_end[:5])
    assert moved < 0.05  # rad: it stays, 0.9 rad from the target
    assert np.linalg.norm(result.q_true[-1][:5] - q_target[:5]) > 0.5
    error, step = local_minimum.stationarity(MODEL, result.q_true[-1:], p_target)
    assert error[0] < 1.0 and step[0] < 1e-3
    _, along = local_minimum.path_profile(MODEL, result.q_true[-1], q_target, p_target)
    assert along.max() > 10.0 * error[0]
