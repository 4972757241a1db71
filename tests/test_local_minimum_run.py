"""
Classic IBVS held in scenario 1's local minimum of the image error: reported, not a success.

docs/servo_laws.md's run (limited actuators, 0.067 s latency the law does not know of,
lambda_0 6): the law comes to rest centimetres and tens of degrees from the target with a
few tenths of a pixel of image error. The feedback node reports the minimum on
/ibvs/feedback_status and its /diagnostics, the joint controller relays it on
/ibvs/servo_status (its /diagnostics' ``servo_status``, in the bag), and the run's metrics
miss with the reason 'local minimum'.
"""

from ibvs_analysis import study_table
from ibvs_control import minimum_watch
from ibvs_experiments import runner
import pytest

#: docs/servo_laws.md: ``ibvs run scenario1 --duration 6 -p servo_law:=ibvs ...``.
OVERRIDES = runner.with_servo_law({'servo_law': 'ibvs', 'actuators': 'limited',
                                   'feedback_latency_s': 0.067, 'lambda_0': 6.0,
                                   'latency_compensation': 'none'})  # as ibvs run sets them
DURATION_S = 6.0


@pytest.mark.slow
def test_a_run_held_in_the_local_minimum_reports_it_and_is_no_success(installed_workspace,
                                                                      tmp_path):
    result = runner.run_scenario('scenario1', tmp_path / 'run', overrides=OVERRIDES,
                                 duration_s=DURATION_S, figures=False)
    metrics = result.metrics
    assert not metrics['success'] and not result.converged
    assert metrics['final_position_error_m'] > minimum_watch.FAR_POSITION_M \
        or metrics['final_tool_axis_error_deg'] > minimum_watch.FAR_AXIS_DEG, metrics
    assert minimum_watch.IMAGE_FLOOR_PX < metrics['final_image_error_px'] \
        <= minimum_watch.IMAGE_NEAR_PX
    assert metrics['miss_reason'].startswith('local minimum of the image error'), \
        metrics['miss_reason']
    assert study_table.reason_category(metrics['miss_reason'], failed=False) == 'local minimum'
    # the status the joint controller published last, as its /diagnostics in the bag say
    assert metrics['final_servo_status'] == 'LOCAL_MINIMUM'
    logs = '\n'.join(p.read_text() for p in (tmp_path / 'run' / 'logs').glob('*'))
    assert 'LOCAL_MINIMUM at ' in logs
