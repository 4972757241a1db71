"""The position interface's pure parts: joint order, shaper, feedback hold (no rclpy)."""

from ibvs_control.position_interface import FeedbackHold, joint_permutation, PositionShaper
from ibvs_model import IRB4600
from ibvs_model.drive import ACCELERATION_LIMITS, JERK_LIMITS, SPEED_LIMITS
import numpy as np
import pytest

NAMES = [f'joint_{i}' for i in range(1, 7)]


def test_joint_permutation_orders_values_as_the_controller_lists_its_joints():
    joints = ['joint_3', 'joint_1', 'joint_2', 'joint_6', 'joint_5', 'joint_4']
    values = np.arange(6.0)  # value i belongs to joint_{i+1}
    assert values[joint_permutation(joints, NAMES)].tolist() == [2, 0, 1, 5, 4, 3]


@pytest.mark.parametrize('joints', [NAMES[:5], NAMES[:5] + ['joint_1'],
                                    NAMES[:5] + ['wrist'], NAMES + ['joint_7']])
def test_joint_permutation_refuses_what_is_not_each_joint_once(joints):
    with pytest.raises(ValueError, match='exactly once'):
        joint_permutation(joints, NAMES)


def shaped(shaper, target, steps, dt=None):
    return np.array([shaper.step(target, dt) for _ in range(steps)])


def test_shaper_respects_speed_and_acceleration_limits_and_arrives():
    shaper = PositionShaper(250.0)
    q0 = np.zeros(6)
    shaper.start(q0)
    target = np.array([2.0, 0.5, -1.0, 1.5, -1.0, 2.0])
    path = np.vstack([q0, shaped(shaper, target, 500)])
    speed = np.diff(path, axis=0) * 250.0
    accel = np.diff(speed, axis=0) * 250.0
    assert np.all(np.abs(speed) <= np.asarray(SPEED_LIMITS) + 1e-9)
    assert np.all(np.abs(accel) <= np.asarray(ACCELERATION_LIMITS) + 1e-6)
    np.testing.assert_allclose(path[-1], target, atol=1e-9)
    # joint 1 needs the speed limit: 2 rad at <= 3.05 rad/s takes longer than 0.65 s
    assert np.abs(path[int(0.65 * 250)] - target)[0] > 1e-3


@pytest.mark.parametrize('cap_deg_s', [20.0, 5.0, 200.0])
def test_no_joint_reference_moves_faster_than_the_cap(cap_deg_s):
    # max_joint_speed_deg_s: per joint the smaller of the cap and the arm's own limit
    cap = np.radians(cap_deg_s)
    shaper = PositionShaper(250.0, max_speed=cap)
    np.testing.assert_allclose(shaper.speed_limits, np.minimum(SPEED_LIMITS, cap))
    rng = np.random.default_rng(7)
    q = rng.uniform(-0.5, 0.5, 6)
    shaper.start(q)
    path, times, t = [q], [0.0], 0.0
    target = q
    for k in range(3000):  # targets that jump far and back; ticks that come late or early
        if k % 200 == 0:
            target = rng.uniform(-2.0, 2.0, 6)
        dt = float(rng.choice([0.004, 0.004, 0.002, 0.008, 0.02]))
        path.append(shaper.step(target, dt))
        t += dt
        times.append(t)
    speed = np.abs(np.diff(path, axis=0)) / np.diff(times)[:, None]
    assert np.all(speed <= shaper.speed_limits * (1 + 1e-12))
    # and the cap is reached: it limits, not something else (the joints of one move are
    # synchronised: the one that takes longest runs at its limit, the others slower)
    assert np.any(speed.max(axis=0) >= 0.99 * shaper.speed_limits)


@pytest.mark.parametrize('cap', [0.0, -1.0, float('nan')])
def test_shaper_refuses_a_cap_that_is_no_speed(cap):
    with pytest.raises(ValueError, match='max_speed'):
        PositionShaper(250.0, max_speed=cap)


def test_shaper_keeps_pace_with_time_not_with_ticks():
    every_tick, skipping = PositionShaper(250.0), PositionShaper(250.0)
    for s in (every_tick, skipping):
        s.start(np.zeros(6))
    target = np.full(6, 0.5)
    a = shaped(every_tick, target, 100)[-1]
    b = shaped(skipping, target, 50, dt=0.008)[-1]  # half the ticks, twice as long each
    np.testing.assert_allclose(a, b, atol=0.02)
    assert np.all(np.abs(b) > 0.2)


def test_shaper_stays_inside_the_joint_ranges():
    shaper = PositionShaper(250.0)
    shaper.start(np.zeros(6))
    beyond = np.asarray(IRB4600.q_max) + 1.0
    last = shaped(shaper, beyond, 2000)[-1]
    assert np.all(last <= np.asarray(IRB4600.q_max) - 0.02 + 1e-12)


def test_shaper_must_start_from_the_measured_joints():
    with pytest.raises(RuntimeError, match='start'):
        PositionShaper(250.0).step(np.zeros(6))


def test_feedback_hold_reports_each_frame_once_and_refuses_older_ones():
    hold = FeedbackHold(np.zeros(6))
    q, first = hold.use()
    assert first is None and not q.any()
    assert hold.offer(100, np.ones(6)) is None
    q, first = hold.use()
    assert first == 100 and np.all(q == 1.0)
    assert hold.use()[1] is None  # the same frame again: not a first use
    assert hold.offer(100, 2 * np.ones(6))[0] == 'out of order'
    assert hold.offer(50, 2 * np.ones(6))[0] == 'out of order'
    assert np.all(hold.use()[0] == 1.0)


@pytest.mark.parametrize('seed', range(6))
def test_every_reference_obeys_speed_acceleration_jerk_and_ranges_whatever_the_target(seed):
    # random starts, targets that jump (the feedforward's target plus a correction that
    # moves every frame), a cap or none, ticks late or early: the reference's own state
    # (Ruckig's position, velocity and acceleration) stays within every limit
    rng = np.random.default_rng(seed)
    cap = float(rng.choice([np.radians(20.0), np.radians(60.0), np.inf]))
    shaper = PositionShaper(250.0, max_speed=cap)
    low, high = shaper.low, shaper.high
    q = rng.uniform(low, high)
    shaper.start(q)
    goal = rng.uniform(low - 0.5, high + 0.5)  # beyond the ranges too: clipped
    jerk = np.asarray(JERK_LIMITS)
    previous_a, t = np.zeros(6), 0.0
    for k in range(1500):
        if k % 300 == 0:
            goal = rng.uniform(low - 0.5, high + 0.5)
        correction = rng.normal(0.0, 0.01, 6)  # the feedback's q_feedback of each frame
        dt = float(rng.choice([0.004, 0.004, 0.002, 0.008, 0.02]))
        position = shaper.step(goal + correction, dt)
        _, velocity, acceleration = shaper.state
        # within the joint ranges (the shaper's range_margin takes what a correction that
        # moves while the reference brakes onto a clipped target adds)
        assert np.all(position >= IRB4600.q_min) and np.all(position <= IRB4600.q_max)
        assert np.all(np.abs(velocity) <= shaper.speed_limits * (1 + 1e-9) + 1e-12)
        assert np.all(np.abs(acceleration) <= np.asarray(ACCELERATION_LIMITS) * (1 + 1e-9))
        assert np.all(np.abs(acceleration - previous_a) <= jerk * dt * (1 + 1e-6) + 1e-9)
        previous_a, t = acceleration, t + dt


def test_the_reference_is_the_time_optimal_move_and_arrives_at_rest():
    # scenario 1's joint-space move at 20 deg/s: Ruckig's duration, then at rest on target
    shaper = PositionShaper(250.0, max_speed=np.radians(20.0))
    q0 = np.zeros(6)
    target = np.radians([159.7, 16.3, 38.5, -9.5, 8.2, 70.2])
    shaper.start(q0)
    duration = shaper.duration(target)
    # no faster than joint 1 at the cap, and not slower than that plus its ramps
    assert np.radians(159.7) / np.radians(20.0) < duration < np.radians(159.7) / np.radians(
        20.0) + 0.2
    path = shaped(shaper, target, int(np.ceil(duration * 250)) + 2)
    np.testing.assert_allclose(path[-1], target, atol=1e-9)
    np.testing.assert_allclose(shaper.state[1], 0.0, atol=1e-9)
    # synchronised: every joint arrives at the same time, none before
    arrived = np.argmax(np.abs(path - target) < 1e-9, axis=0)  # first sample there
    assert arrived.max() - arrived.min() <= 1


def test_the_bound_is_the_arms_own_move_plus_the_drives_dead_time():
    from ibvs_control.position_interface import shaper_for, time_optimal_s
    from ibvs_model.drive import EGM_DELAY_S
    q0 = np.zeros(6)
    target = np.radians([159.7, 16.3, 38.5, -9.5, 8.2, 70.2])
    bounds = []
    for cap in (20.0, 60.0, 300.0):
        values = {'max_joint_speed_deg_s': cap, 'command_rate_hz': 250.0, 'speed_margin': 0.9,
                  'drive_acceleration_margin': 0.7}
        bound = time_optimal_s(q0, target, values)
        # the arm's limits, not the controller's margins inside them
        arm = PositionShaper(250.0, max_speed=np.radians(cap))
        arm.start(q0)
        assert bound == pytest.approx(arm.duration(target) + EGM_DELAY_S, abs=1e-12)
        planned = shaper_for(values)
        planned.start(q0)
        assert planned.duration(target) + EGM_DELAY_S > bound
        # no joint covers its distance faster than at its speed limit from the start
        speed = np.minimum(np.asarray(SPEED_LIMITS), np.radians(cap))
        assert bound > np.max(np.abs(target) / speed) + EGM_DELAY_S
        bounds.append(bound)
    assert bounds[0] > bounds[1] > bounds[2]  # a higher cap, a shorter move
