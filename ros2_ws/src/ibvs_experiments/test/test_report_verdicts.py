"""The report's verdicts on the paper's claims, read from the scenarios' metrics."""

from ibvs_experiments.report import claims


def test_report_verdicts_follow_the_papers_words():
    good = {'time_to_1mm_s': 0.25, 'settling_time_2pct_s': 0.2, 'max_overshoot_m': 0.002,
            'final_position_error_m': 2e-4, 'final_tool_axis_error_deg': 0.05,
            'time_estimated_s': 0.3, 'initial_position_error_m': 2.5,
            'peak_joint_speed_ratio': 32.74, 'peak_joint_torque_ratio': 6.3e3}
    worst = {'link': 'L2', 'scale': 0.5, 'final_position_error_m': 3e-4,
             'metrics': {'initial_position_error_m': 2.5}}
    rows = claims(good, good, good, worst)
    assert all(row[-1].startswith('met') for row in rows)
    # each claim names its actuators and how hard they were driven
    assert rows[0][3] == ('ideal (unlimited): peak joint speed 32.7x rated, torque 6.3e+03x '
                          'the estimated limit')
    assert "not run with the IRB 4600's limits" in rows[0][-1]
    bad = dict(good, max_overshoot_m=0.045, time_to_1mm_s=None, settling_time_2pct_s=0.5)
    verdicts = [row[-1] for row in claims(bad, bad, good, dict(
        worst, final_position_error_m=0.03))]
    assert [v.split(' (')[0].split(';')[0] for v in verdicts] == [
        'not met', 'not met', 'met', 'not met', 'met', 'not met']
    # met with ideal actuators only: the verdict says so, with the limited run's numbers
    slow = dict(good, time_to_1mm_s=1.9, settling_time_2pct_s=0.9, max_overshoot_m=0.001,
                final_tool_axis_error_deg=0.6, peak_joint_speed_ratio=1.0)
    rows = claims(good, good, good, worst, {'scenario1': slow, 'scenario2': good})
    assert rows[0][-1] == ("met with ideal actuators (2 % settling); with the IRB 4600's "
                           'limits: not met (2 % settling 0.900 s, within 1 mm from 1.900 s)')
    assert "IRB 4600's limits, 0.067 s latency: peak joint speed 1x rated" in rows[0][3]
    assert rows[1][-1].startswith('met (at most 5 mm read as small), with ideal actuators '
                                  "and with the IRB 4600's limits")
    assert rows[2][-1].startswith('met with ideal actuators (within 1 mm and 0.5 deg); with '
                                  "the IRB 4600's limits: not met")
    assert rows[3][-1].startswith('met (within 1 mm in under 1 s), with ideal')
    assert "not run with the IRB 4600's limits" in rows[4][-1]
