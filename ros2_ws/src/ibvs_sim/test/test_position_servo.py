"""The simulated position drive (no rclpy): dead time, bandwidth, limits, hold."""

import math

from ibvs_model.drive import ACCELERATION_LIMITS, EGM_BANDWIDTH_HZ, SPEED_LIMITS
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
    assert EGM_BANDWIDTH_HZ == 20.0
