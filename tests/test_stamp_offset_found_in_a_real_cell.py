"""
A camera that stamps its frames off their exposure: the feature node finds the offset.

`ibvs run real_cell` with 100 ms from exposure to message and every image stamped a
constant off its exposure (the simulator's image_stamp_offset_s: a ZED wrapper stamps on
receipt, after it): the feature node's estimate from the 250 Hz encoders
(ibvs_vision.stamp_offset), on /diagnostics and so in the run's metrics, is within 3 ms of
it once the arm has moved in view.
"""

import json

from ibvs_experiments import cli
import pytest


@pytest.mark.slow
@pytest.mark.parametrize('offset_ms', [33, -20])
def test_the_feature_node_finds_the_cameras_stamp_offset(installed_workspace, tmp_path,
                                                         offset_ms):
    out = tmp_path / 'run'
    code = cli.main(['run', 'real_cell', '--duration', '4.5', '--no-figures', '-o', str(out),
                     '-p', 'feedback_latency_s:=0.1', '-p', 'max_joint_speed_deg_s:=60',
                     '-p', f'image_stamp_offset_s:={offset_ms * 1e-3}',
                     '-p', 'stamp_offset_initial_s:=0.0'])  # a first run: nothing known
    assert code == 0
    metrics = json.loads((out / 'metrics.json').read_text())
    assert abs(metrics['stamp_offset_ms'] - offset_ms) < 3.0
    assert metrics['stamp_offset_applied_ms'] == metrics['stamp_offset_ms']
    assert 0.0 < metrics['stamp_offset_sd_ms'] < 3.0
