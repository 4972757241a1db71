"""The position interface's pure parts: joint order, shaper, feedback hold (no rclpy)."""

from ibvs_control.position_interface import FeedbackHold, joint_permutation, PositionShaper
from ibvs_model import IRB4600
from ibvs_model.drive import ACCELERATION_LIMITS, SPEED_LIMITS
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
    # and the cap is reached: it limits, not something else
    assert np.all(speed.max(axis=0) >= 0.99 * shaper.speed_limits)


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
