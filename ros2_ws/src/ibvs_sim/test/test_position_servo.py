"""The simulated position drive (no rclpy): dead time, bandwidth, limits, hold."""

import math

from ibvs_model.drive import (ACCELERATION_LIMITS, EGM_BANDWIDTH_HZ, EGM_DELAY_S,
                              SPEED_LIMITS)
from ibvs_sim.position_servo import PositionServo
import numpy as np
import pytest

DT = 1e-3


def run(servo, steps):
    return np.array([servo.step()[0] for _ in range(steps)])


def test_dead_time_then_first_order_response_at_the_bandwidth():
    servo = PositionServo(DT, np.zeros(6), bandwidth_hz=20.0, delay_s=0.02)
    step = 1e-5  # small: neither speed nor acceleration limit (omega^2 step << a_max)
    servo.command(np.full(6, step))
    path = run(servo, 200)
    assert np.all(path[:20] == 0.0)  # nothing moves for the 20 ms dead time
    assert np.all(path[21] > 0.0)
    tau_steps = 1.0 / (2 * math.pi * 20.0) / DT  # about 8 steps
    # one time constant after the dead time: 1 - 1/e of the step (first order, up to the
    # acceleration limit at the very start and the sampling)
    assert path[20 + int(round(tau_steps)), 0] == pytest.approx((1 - math.exp(-1)) * step,
                                                                rel=0.15)
    np.testing.assert_allclose(path[-1], step, rtol=1e-4)


def test_large_step_obeys_speed_and_acceleration_limits_without_overshoot():
    servo = PositionServo(DT, np.zeros(6), delay_s=0.0)
    target = np.array([3.0, 1.0, -1.0, 2.0, -2.0, 3.0])
    servo.command(target)
    path = np.vstack([np.zeros(6), run(servo, 3000)])
    speed = np.diff(path, axis=0) / DT
    accel = np.diff(speed, axis=0) / DT
    assert np.all(np.abs(speed) <= np.asarray(SPEED_LIMITS) + 1e-9)
    assert np.all(np.abs(accel) <= np.asarray(ACCELERATION_LIMITS) + 1e-6)
    assert np.all(np.abs(path) <= np.abs(target) + 1e-5)  # no overshoot (beyond sampling)
    np.testing.assert_allclose(path[-1], target, atol=1e-6)


def test_hold_stops_the_arm_within_its_braking_distance_and_holds():
    servo = PositionServo(DT, np.zeros(6), delay_s=0.0)
    servo.command(np.full(6, 5.0))
    run(servo, 500)  # moving fast now
    q, qd = servo.q.copy(), servo.qd.copy()
    assert np.all(qd > 1.0)
    servo.hold()
    path = run(servo, 2000)
    braking = qd ** 2 / (2 * np.asarray(ACCELERATION_LIMITS))
    assert np.all(path[-1] <= q + braking + 1e-3)
    np.testing.assert_allclose(servo.qd, 0.0, atol=1e-9)
    np.testing.assert_allclose(path[-1], path[-100], atol=1e-9)  # held
    servo.command(np.zeros(6))  # a new reference: tracking again
    assert not servo.holding


@pytest.mark.parametrize('kwargs, match', [
    ({'bandwidth_hz': 0.0}, 'bandwidth'), ({'bandwidth_hz': 200.0}, 'too high'),
    ({'delay_s': -0.1}, 'delay'), ({'speed_limits': [1.0] * 5}, 'speed limits'),
    ({'acceleration_limits': [0.0] * 6}, 'acceleration limits')])
def test_bad_configuration_is_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        PositionServo(DT, np.zeros(6), **kwargs)


def test_a_bad_reference_is_refused_and_the_old_one_kept():
    servo = PositionServo(DT, np.zeros(6))
    servo.command(np.ones(6))
    for bad in (np.ones(5), np.array([np.nan] + [0.0] * 5)):
        with pytest.raises(ValueError):
            servo.command(bad)
    assert np.all(servo.reference == 1.0)
    with pytest.raises(ValueError):
        servo.command(np.ones(6), speed=np.full(6, np.inf))


@pytest.mark.parametrize('with_speed', [False, True])
def test_a_steady_move_lags_by_the_dead_time_and_without_its_speed_by_the_loop_too(
        with_speed):
    """The default drive: EGM as its users measure it (ibvs_model.drive)."""
    servo = PositionServo(DT, np.zeros(6))
    speed = 0.2  # rad/s, far inside every limit
    t = np.arange(1, 3001) * DT
    path = np.array([servo.command(np.full(6, speed * tk), np.full(6, speed) if with_speed
                                   else None) or servo.step()[0] for tk in t])
    lag_s = t[-1] - path[-1, 0] / speed
    loop_s = 1.0 / (2 * math.pi * EGM_BANDWIDTH_HZ)
    expected = EGM_DELAY_S + (0.0 if with_speed else loop_s)
    assert lag_s == pytest.approx(expected, abs=2 * DT)
    assert (0.045 <= lag_s <= 0.055) if with_speed else (0.07 <= lag_s <= 0.08)


# -- the trajectory controller (TrajectoryFollower) fed at 250 Hz, updating at another rate --

COMMAND_NS = 4_000_000  # the joint controller's 250 Hz
GRID_NS = 100_000  # the time grid of the loop below: 0.1 ms
CAP = math.radians(20.0)  # max_joint_speed_deg_s


def run_cell(update_rate_hz, window_points, old_single_point=False, duration_ns=800_000_000):
    """
    Run the 250 Hz command stream through a trajectory controller into the drive.

    The controller updates at ``update_rate_hz``. Returns (update times ns, the references
    it wrote, the shaper's own path (command times ns, positions), the drive's speeds).

    Each command is the window the node publishes (stamp = its time, point k at k command
    periods: the reference now and its shaped course ahead) or, ``old_single_point``, the
    former message (stamp 0, one point one command period ahead). It arrives 1.3 ms after
    its time, every other one 0.7 ms later still (DDS and the executor's jitter).
    """
    from ibvs_control.position_interface import PositionShaper
    from ibvs_sim.position_servo import TrajectoryFollower
    q0 = np.zeros(6)
    target = np.r_[1.0, np.zeros(5)]  # joint_1 far away: it cruises at the cap
    shaper = PositionShaper(250.0, max_speed=CAP)
    shaper.start(q0)
    servo = PositionServo(GRID_NS * 1e-9, q0)
    follower = TrajectoryFollower(update_rate_hz)
    inbox, updates, written, path, speeds = [], [], [], [], []
    for t in range(0, duration_ns, GRID_NS):
        if t % COMMAND_NS == 0 and t:
            q = shaper.step(target)
            path.append((t, q[0]))
            if old_single_point:
                message = (0, [COMMAND_NS], q[None])
            else:
                ahead = shaper.preview(window_points - 1)[0]
                message = (t, np.arange(window_points) * COMMAND_NS, np.vstack([q, ahead]))
            late = 1_300_000 + (700_000 if (t // COMMAND_NS) % 2 else 0)
            inbox.append((t + late, message))
        while inbox and inbox[0][0] <= t:
            follower.receive(*inbox.pop(0)[1])
        if follower.due(t):
            sample = follower.update(t, servo.q)
            if sample is not None:
                servo.command(*sample)
                updates.append(t)
                written.append(sample[0][0])
        speeds.append(servo.step()[1][0])
    return np.array(updates), np.array(written), np.array(path), np.array(speeds)


@pytest.mark.parametrize('update_rate_hz', [200.0, 300.0, 250.0])
def test_a_trajectory_controller_off_250_hz_neither_holds_nor_skips(update_rate_hz):
    updates, written, path, speeds = run_cell(update_rate_hz, window_points=26)
    # every update writes the shaper's reference of its own time: the window's line
    expected = np.interp(updates, path[:, 0], path[:, 1])
    # from the first window's arrival to the last command (the shaper's path ends there)
    inside = (updates >= path[1, 0] + 2_000_000) & (updates <= path[-1, 0])
    np.testing.assert_allclose(written[inside], expected[inside], atol=1e-12)
    # cruising at the cap, each update moves the reference by the cap times its period:
    # none holds (no move), none skips (a double move)
    cruise = (updates > 0.2e9) & (updates < 0.7e9)
    step = np.diff(written[cruise]) / (np.diff(updates[cruise]) * 1e-9)
    np.testing.assert_allclose(step, CAP, rtol=0.04)  # the update times on the 0.1 ms grid
    # and so the drive turns smoothly at the cap
    drive = speeds[int(0.3e9 // GRID_NS):int(0.7e9 // GRID_NS)]
    np.testing.assert_allclose(drive, CAP, rtol=0.05)


@pytest.mark.parametrize('update_rate_hz', [200.0, 300.0])
def test_the_former_single_point_command_holds_or_skips_off_250_hz(update_rate_hz):
    """The same check on the former message shows the failure the window removes."""
    updates, written, _, speeds = run_cell(update_rate_hz, 1, old_single_point=True)
    cruise = (updates > 0.2e9) & (updates < 0.7e9)
    step = np.diff(written[cruise]) / (np.diff(updates[cruise]) * 1e-9)
    held = np.mean(np.abs(step) < 0.5 * CAP)
    assert held > 0.2 or np.abs(step).max() > 1.5 * CAP


def test_the_trajectory_follower_samples_as_joint_trajectory_controller():
    from ibvs_sim.position_servo import TrajectoryFollower
    follower = TrajectoryFollower(100.0)  # updates every 10 ms
    q = np.zeros(6)
    assert follower.due(0) and follower.update(0, q) is None  # nothing received yet
    points = np.outer([1.0, 2.0, 4.0], np.ones(6))
    follower.receive(0, [20_000_000, 30_000_000, 50_000_000], points)  # stamp 0: now
    assert not follower.due(5_000_000) and follower.due(10_000_000)
    # first sampling at 10 ms: starts now, from the measured state, toward the first point;
    # the velocity written is the segment's slope (positions only)
    for t_ms, position, velocity in ((10, 0.0, 50.0), (20, 0.5, 50.0),  # 1 rad in 20 ms
                                     (35, 1.5, 100.0), (50, 3.0, 100.0),  # points 0 to 2
                                     (90, 4.0, 0.0)):  # played out: the last, at rest
        written = follower.update(t_ms * 1_000_000, q)
        np.testing.assert_allclose(written[0], position)
        np.testing.assert_allclose(written[1], velocity)
    # a stamped trajectory is placed at its stamp, and replaces the current one; its points'
    # own velocities are written where it carries them
    follower.receive(100_000_000, [0, 10_000_000], np.outer([5.0, 6.0], np.ones(6)),
                     np.outer([0.0, 2.0], np.ones(6)))
    written = follower.update(105_000_000, q)
    np.testing.assert_allclose(written[0], 5.5)
    np.testing.assert_allclose(written[1], 1.0)
    np.testing.assert_allclose(follower.update(200_000_000, q)[1], 2.0)
    with pytest.raises(ValueError):
        TrajectoryFollower(0.0)
