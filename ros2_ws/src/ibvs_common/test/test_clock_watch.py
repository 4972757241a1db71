"""A node's clock as its readers see it (ibvs_common.sim_time.ClockWatch), without a node."""

from ibvs_common.conversions import StampOrder
from ibvs_common.sim_time import CLOCK_STALL_INTERVALS, CLOCK_STALL_MIN_S, ClockWatch
import pytest
from rclpy.clock import ClockChange, TimeJump
from rclpy.duration import Duration

S = 1_000_000_000


class Steady:
    """A wall clock the test moves."""

    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


def test_a_reading_before_the_newest_is_a_jump_back_and_every_order_forgets():
    warnings, jumps = [], []
    watch = ClockWatch(warnings.append)
    order = StampOrder()
    order.take('/joint_states', 30 * S)
    watch.on_back(lambda f, t: jumps.append((f, t)), lambda f, t: order.forget())
    for t in (10 * S, 30 * S, 30 * S):  # forward, or standing: no jump
        assert watch.read(t) == t
    assert not jumps and watch.jumps_back == 0
    watch.read(25 * S)  # an NTP step 5 s back
    assert jumps == [(30 * S, 25 * S)] and watch.last_jump == (30 * S, 25 * S)
    assert order.newest('/joint_states') is None  # a fresh stamp is taken again
    order.check('/joint_states', 25 * S)
    assert warnings == ['the clock jumped back from 30.000 s to 25.000 s: every stamp order '
                        'starts again']
    watch.read(26 * S)
    assert watch.jumps_back == 1  # counted once, from the new time line on


def test_rclpys_jump_callback_counts_back_jumps_only():
    jumps = []
    watch = ClockWatch()
    watch.on_back(lambda f, t: jumps.append((f, t)))
    watch.on_jump(28 * S, TimeJump(ClockChange.ROS_TIME_NO_CHANGE, Duration(seconds=1)))
    assert not jumps
    watch.on_jump(0, TimeJump(ClockChange.ROS_TIME_NO_CHANGE, Duration(seconds=-28)))
    assert jumps == [(28 * S, 0)]
    watch.read(1)  # the reading after the callback is no second jump
    assert watch.jumps_back == 1


def test_one_failing_forget_does_not_keep_the_others_orders():
    warnings, done = [], []

    def broken(f, t):
        raise RuntimeError('boom')

    watch = ClockWatch(warnings.append)
    watch.on_back(broken, lambda f, t: done.append(t))
    watch.read(5 * S)
    watch.read(S)
    assert done == [S] and "RuntimeError('boom')" in warnings[-1]


def test_a_clock_that_stopped_is_told_by_the_wall_time_since_it_last_moved():
    steady = Steady()
    watch = ClockWatch(steady=steady)
    assert watch.stalled_s() is None and not watch.stalled()  # no /clock yet: not stopped
    for k in range(40):  # /clock every 10 ms of wall time
        watch.clock_message(k * 4_000_000)
        steady.t += 0.01
    watch.clock_message(39 * 4_000_000)  # the same time again: not a move
    assert watch.stall_bound_s() == CLOCK_STALL_MIN_S
    steady.t += CLOCK_STALL_MIN_S
    assert watch.stalled_s() == pytest.approx(CLOCK_STALL_MIN_S + 0.01)
    assert watch.stalled()
    watch.clock_message(40 * 4_000_000)
    assert not watch.stalled()


def test_a_slow_clock_widens_the_bound_to_its_measured_interval():
    steady = Steady()
    watch = ClockWatch(steady=steady)
    for k in range(10):  # a small real-time factor: /clock every 0.5 s of wall time
        watch.clock_message(k)
        steady.t += 0.5
    assert watch.stall_bound_s() == CLOCK_STALL_INTERVALS * 0.5
    steady.t += 3.0
    assert not watch.stalled()
