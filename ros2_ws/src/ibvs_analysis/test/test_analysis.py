"""
Metrics of a run, on responses whose settling time and overshoot are known in closed form.

And the joint series of a bag (:func:`ibvs_analysis.analysis.load_joints`), recorded by
the recorder as a run records them.
"""

import math

from ibvs_analysis import analysis, metrics
from ibvs_bringup import scenario
from ibvs_testing.fixtures import spin_until
import numpy as np
import pytest


def second_order_step(t, zeta, wn):
    """Return the unit step response of wn^2 / (s^2 + 2 zeta wn s + wn^2), zeta < 1."""
    wd = wn * math.sqrt(1 - zeta ** 2)
    return 1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta ** 2)
                                         * np.sin(wd * t))


def make_run(y, t, start, target):
    """Tool positions moving from ``start`` to ``target`` along the unit response ``y``."""
    position = start + np.outer(y, target - start)
    rotation = np.repeat(np.eye(3)[None], len(t), axis=0)
    tf = np.eye(4)
    tf[:3, 3] = target
    return position, rotation, tf


def test_butterworth_step_overshoot_and_settling():
    zeta, wn = 1 / math.sqrt(2), 10.0
    t = np.arange(0.0, 3.0, 1e-4)
    start, target = np.array([1.0, 0.2, 1.0]), np.array([-1.0, 0.2, 0.3])
    position, rotation, tf = make_run(second_order_step(t, zeta, wn), t, start, target)
    m = metrics.compute_metrics(t, position, rotation, tf)
    step = np.abs(target - start)
    expected_overshoot = math.exp(-math.pi * zeta / math.sqrt(1 - zeta ** 2)) * step.max()
    assert m['max_overshoot_m'] == pytest.approx(
        expected_overshoot / step.max() * np.linalg.norm(step), rel=1e-3)
    assert m['overshoot_xyz_m'][0] == pytest.approx(expected_overshoot, rel=1e-3)
    assert m['overshoot_xyz_m'][1] == 0.0  # y does not move
    assert m['max_lateral_excursion_m'] < 1e-12  # a straight-line response
    # z comes down from 1.0 to 0.3 m and overshoots below the target by the same share
    assert m['lowest_tool_z_m'] == pytest.approx(0.3 - expected_overshoot * 0.7 / 2.0,
                                                 rel=1e-3)
    # The 2 % band is left for the last time at the settling time, and never again.
    error = np.linalg.norm(position - target, axis=1)
    ts = m['settling_time_2pct_s']
    assert np.all(error[t >= ts] <= 0.02 * error[0])
    assert error[np.searchsorted(t, ts) - 1] > 0.02 * error[0]
    assert 0.3 < ts < 0.7  # about 4 / (zeta wn) = 0.57 s for this damping
    assert m['time_to_1mm_s'] > ts
    assert m['final_position_error_m'] < 1e-6
    assert m['final_tool_axis_error_deg'] == 0.0


def test_monotone_approach_has_no_overshoot_and_never_settling_is_none():
    t = np.linspace(0.0, 1.0, 1001)
    y = 1 - np.exp(-5 * t)
    position, rotation, tf = make_run(y, t, np.zeros(3), np.array([0.0, 0.0, 1.0]))
    m = metrics.compute_metrics(t, position, rotation, tf)
    assert m['max_overshoot_m'] == 0.0
    assert m['time_to_1mm_s'] is None
    # A sideways swing is not an overshoot: it is the lateral excursion.
    swing = position + np.outer(np.sin(np.pi * t), [0.3, 0.0, 0.0])
    m = metrics.compute_metrics(t, swing, rotation, tf)
    assert m['max_overshoot_m'] == 0.0
    assert m['max_lateral_excursion_m'] == pytest.approx(0.3, rel=1e-6)
    assert m['overshoot_xyz_m'][0] == pytest.approx(0.3, rel=1e-6)  # e(1 s) = exp(-5) m = 6.7 mm
    assert m['final_position_error_m'] == pytest.approx(math.exp(-5), rel=1e-9)


def test_tool_axis_error_is_accurate_for_small_angles():
    target = np.eye(3)
    for angle in (1e-9, 1e-5, 0.1, 3.0):
        c, s = math.cos(angle), math.sin(angle)
        rot = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])[None]
        assert metrics.axis_angle_deg(rot, target)[0] == pytest.approx(math.degrees(angle),
                                                                       rel=1e-6)


def test_estimated_time_holds_each_mode_until_the_next_frame():
    assert metrics.estimated_time(np.array([0.0, 0.1, 0.2]),
                                  ['estimated', 'blending', 'measured'], 0.5) \
        == pytest.approx(0.2)
    assert metrics.estimated_time(np.array([0.0]), ['estimated'], 1.5) == pytest.approx(1.5)
    assert metrics.estimated_time(np.zeros(0), [], 1.0) == 0.0


def test_too_short_run_is_rejected():
    with pytest.raises(ValueError, match='two tool poses'):
        metrics.compute_metrics([0.0], np.zeros((1, 3)), np.eye(3)[None], np.eye(4))


def test_scenario_overrides_and_parameter_files(tmp_path):
    assert scenario.parse_override('l2_scale:=0.5') == ('l2_scale', 0.5)
    assert scenario.parse_override('actuators:=limited') == ('actuators', 'limited')
    assert scenario.parse_override('disturbance_deg:=[0.1, 0, 0, 0, 0, 0]')[1][0] == 0.1
    with pytest.raises(scenario.ScenarioError, match='name:=value'):
        scenario.parse_override('l2_scale=0.5')
    path = scenario.write_parameters({'scenario': 2}, tmp_path / 'p.yaml')
    assert scenario.load_parameters(path) == {'scenario': 2}
    with pytest.raises(scenario.ScenarioError, match='unknown scenario'):
        scenario.load_parameters('scenario42')
    bad = tmp_path / 'bad.yaml'
    bad.write_text('node: {}\n')
    with pytest.raises(scenario.ScenarioError, match='ros__parameters'):
        scenario.load_parameters(bad)


def test_mean_and_max_error_over_the_last_half_second():
    """A tool that ends oscillating around the target: the last 0.5 s, not its last sample."""
    t = np.arange(0.0, 2.0 + 1e-9, 1e-3)
    target = np.eye(4)
    # 10 mm before 1.5 s, then up to 3 mm in the last 0.5 s, whose last sample is 0
    error = np.where(t < 1.5, 0.01, 0.003 * np.abs(np.sin(2 * np.pi * (t - 2.0))))
    position = np.outer(error, [1.0, 0.0, 0.0])
    # the tool axis tilted by 0.2 deg before and 0.05 deg in the last 0.5 s
    tilt = np.radians(np.where(t < 1.5, 0.2, 0.05))
    c, s = np.cos(tilt), np.sin(tilt)
    rotation = np.zeros((t.size, 3, 3))
    rotation[:, 0, 0] = 1.0
    rotation[:, 1, 1], rotation[:, 1, 2], rotation[:, 2, 1], rotation[:, 2, 2] = c, -s, s, c
    m = metrics.compute_metrics(t, position, rotation, target)
    last = t >= t[-1] - 0.5
    assert m['final_position_error_m'] == pytest.approx(0.0, abs=1e-15)
    assert m['max_position_error_last_0_5s_m'] == pytest.approx(0.003, rel=1e-6)
    assert m['mean_position_error_last_0_5s_m'] == pytest.approx(error[last].mean(), rel=1e-12)
    # |sin| over a whole number of half periods has the mean 2 / pi
    assert m['mean_position_error_last_0_5s_m'] == pytest.approx(0.003 * 2 / np.pi, rel=1e-2)
    assert m['mean_tool_axis_error_last_0_5s_deg'] == pytest.approx(0.05, rel=1e-6)
    assert m['max_tool_axis_error_last_0_5s_deg'] == pytest.approx(0.05, rel=1e-6)
    # the ripple: from the sine's zero to its peak
    assert m['position_error_ripple_last_0_5s_m'] == pytest.approx(0.003, rel=1e-6)
    # a run shorter than the window: the whole run
    short = metrics.compute_metrics(t[:100], position[:100], rotation[:100], target)
    assert short['max_position_error_last_0_5s_m'] == pytest.approx(0.01)


@pytest.fixture
def write_bag(context, executor_of):
    """Return write(path, [(topic, rclpy message)]): a bag recorded as a run's recorder does."""
    from ibvs_bringup.recorder import KNOWN_TOPICS, message_class, Recorder
    from ibvs_common import contract
    from rclpy.node import Node

    def write(path, messages):
        recorder = Recorder(path, context=context, include_per_step=True)
        talker = Node(f'talker_{path.name}', context=context)
        executor = executor_of(recorder, talker)
        pubs = {topic: talker.create_publisher(message_class(KNOWN_TOPICS[topic]), topic,
                                               contract.RELIABLE)
                for topic in {t for t, _ in messages}}
        spin_until(executor, lambda: all(p.get_subscription_count() for p in pubs.values()),
                   what='discovery')
        for topic, msg in messages:
            pubs[topic].publish(msg)
        # Its own topics only: a /diagnostics of an earlier test's nodes, still shutting
        # down on this process's domain, must not end the wait early.
        topics = {t for t, _ in messages}
        spin_until(executor, lambda: sum(recorder.counts[t] for t in topics) == len(messages),
                   what='messages')
        recorder.close()
    return write


def test_load_joints_reads_the_batches_of_a_run_and_the_states_of_a_cell(tmp_path, write_bag):
    from ibvs_common import contract
    from ibvs_common.conversions import joint_path, joint_state
    rng = np.random.default_rng(3)
    period, steps = 1_000_000, 25
    commands = [joint_state(k * period, effort=rng.normal(size=6)) for k in range(steps)]
    # Each state reports the torque of the step before it: the command of that step.
    states = [joint_state(k * period, rng.normal(size=6), rng.normal(size=6),
                          commands[k - 1].effort if k else np.zeros(6)) for k in range(steps)]
    # A real cell's bag: the per-step messages.
    per_step = [m for pair in zip(states, commands) for m in (
        (contract.JOINT_STATES, pair[0]), (contract.EFFORT_COMMANDS, pair[1]))]
    write_bag(tmp_path / 'cell', per_step)
    # A run's: the batches of 10 steps (the last one partial); with the per-step states
    # too, as a recorder asked for them records them, which must not count twice.
    batches = [(contract.JOINT_PATH, joint_path(states[i:i + 10]))
               for i in range(0, steps, 10)]
    write_bag(tmp_path / 'run', batches)
    write_bag(tmp_path / 'both', [m for m in per_step if m[0] == contract.JOINT_STATES]
              + batches)
    cell, run, both = (analysis.load_joints(tmp_path / name) for name in ('cell', 'run', 'both'))
    assert len(cell[0]) == len(run[0]) == len(both[0]) == steps
    for got_cell, got_run, got_both in zip(cell[:3], run[:3], both[:3]):  # the same float64s
        assert got_cell.tobytes() == got_run.tobytes() == got_both.tobytes()
    assert run[1].tobytes() == np.array([m.position for m in states]).tobytes()
    assert run[0].tolist() == [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
                               for m in states]
    # The torques: the commands, or those the states report applied, at the commands' stamps
    # (all but the last command, which no state of the bag reports yet).
    assert len(cell[3]) == steps and len(run[3]) == len(both[3]) == steps - 1
    for k in (3, 4):
        assert cell[k][:-1].tobytes() == run[k].tobytes() == both[k].tobytes()
    # The end of the run: the samples stamped before it, from either.
    for name in ('cell', 'run'):
        t, q, qd, tau_t, tau = analysis.load_joints(tmp_path / name, end_s=0.012)
        assert len(t) == len(q) == len(qd) == len(tau_t) == len(tau) == 12
    # A free-running run's: the position drive models no torque.
    write_bag(tmp_path / 'free', [(contract.JOINT_PATH, joint_path(
        [joint_state(m.header.stamp, m.position, m.velocity) for m in states]))])
    free = analysis.load_joints(tmp_path / 'free')
    assert free[1].tobytes() == run[1].tobytes() and free[3].shape == (0,)


def test_the_final_image_error_is_the_last_frames_against_the_controllers_target():
    from ibvs_model import default_model, inverse_kinematics, paper
    model = default_model('HD720')
    target = paper.target_pose()
    p_bar = model.features(inverse_kinematics(target))
    off = p_bar + np.array([0.3, 0.0, 0.0, 0.0, 0.0, 0.4])  # 0.5 px off
    features = np.vstack([p_bar + 10.0, off])  # the last frame counts
    # the model's target: the fiducials at the target pose through the run's camera
    assert metrics.final_image_error(features, None, model.camera, target) == \
        pytest.approx(0.5, abs=1e-6)
    # a taught target: the features the feature node measured on the teach pair
    assert metrics.final_image_error(features, off, model.camera, target) == 0.0
    assert metrics.final_image_error(features, None, None, target) is None
    assert metrics.final_image_error(np.zeros((0, 6)), off, model.camera, target) is None
