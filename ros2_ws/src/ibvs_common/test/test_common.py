"""Parameters, diagnostics and the lockstep rule shared by the nodes."""

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from ibvs_common import contract
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.params import declare, Param, ParameterError
from ibvs_common.timing import check_camera_rate, ns_to_seconds, seconds_to_ns
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock


RATE = Param('rate_hz', 30.0, 'a rate', 'Hz', low=0.0, high=100.0, low_open=True)
MODE = Param('mode', 'ideal', 'a mode', choices=('ideal', 'limited'))
VEC = Param('vec', [0.0, 0.0, 0.0], 'a vector', 'm', low=-1.0, high=1.0, length=3)
COUNT = Param('count', 3, 'a count', low=1, high=10)


def make_node(context, overrides):
    return Node('param_test', context=context,
                parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])


def test_declare_returns_defaults_and_overrides(context):
    node = make_node(context, {'rate_hz': 60, 'vec': [0.5, -0.5, 0.0]})
    try:
        values = declare(node, [RATE, MODE, VEC, COUNT])
        assert values == {'rate_hz': 60.0, 'mode': 'ideal', 'vec': [0.5, -0.5, 0.0],
                          'count': 3}
        assert isinstance(values['rate_hz'], float)
        desc = node.describe_parameter('rate_hz')
        assert 'Hz' in desc.description and '(0, 100]' in desc.description
    finally:
        node.destroy_node()


@pytest.mark.parametrize('overrides,match', [
    ({'rate_hz': -1.0}, r"'rate_hz'.*out of range.*allowed: \(0, 100\]"),
    ({'rate_hz': 0.0}, r"'rate_hz' = 0.0 is invalid: out of range; allowed: \(0, 100\]"),
    ({'mode': 'turbo'}, "'mode'.*one of 'ideal', 'limited'"),
    ({'vec': [0.0, 0.0]}, "'vec'.*has 2 values.*3 values"),
    ({'vec': [0.0, 0.0, 5.0]}, "'vec'.*out of range"),
    ({'count': 2.5}, "'count'"),
    ({'rate_hz': 'fast'}, "'rate_hz'.*not a number"),
])
def test_bad_parameters_name_the_parameter_and_range(context, overrides, match):
    node = make_node(context, overrides)
    try:
        with pytest.raises(ParameterError, match=match):
            declare(node, [RATE, MODE, VEC, COUNT])
    finally:
        node.destroy_node()


def test_boolean_and_string_parameters_describe_their_values_not_a_number_range(context):
    flag = Param('flag', False, 'a switch')
    name = Param('label', 'x', 'a free string')
    assert flag.allowed() == 'true or false'
    assert name.allowed() == 'any string'
    assert 'inf' not in flag.descriptor().description
    assert 'inf' not in name.descriptor().description
    with pytest.raises(ParameterError, match="'flag'.*not a boolean; allowed: true or false"):
        flag.check(1)


def test_feedback_frame_rule():
    period, latency, step = 33_333_333, 0, 1_000_000
    # 30 Hz frames on 1 kHz physics are stamped with the step they are rendered from
    assert [contract.frame_stamp_ns(n, period, step) for n in range(4)] == \
        [0, 34_000_000, 67_000_000, 100_000_000]
    assert contract.feedback_frame_ns(0, period, latency, step) == 0
    assert contract.feedback_frame_ns(33_000_000, period, latency, step) == 0
    assert contract.feedback_frame_ns(34_000_000, period, latency, step) == 34_000_000
    assert contract.feedback_frame_ns(10_000_000, period, 20_000_000, step) is None
    assert contract.feedback_frame_ns(20_000_000, period, 20_000_000, step) == 0
    assert contract.feedback_frame_ns(53_000_000, period, 20_000_000, step) == 0
    assert contract.feedback_frame_ns(54_000_000, period, 20_000_000, step) == 34_000_000
    for bad in ((0, 0, 0, step), (0, period, -1, step), (0, period, 0, 0)):
        with pytest.raises(ValueError):
            contract.feedback_frame_ns(*bad)


def test_feedback_frame_is_the_newest_frame_stamp_acting_by_then():
    """By property: a frame stamp on the step grid, acting by t, and the next one not yet."""
    rng = np.random.default_rng(7)
    for _ in range(3000):
        step = int(rng.integers(1, 10 ** 7))
        period = int(rng.integers(step, 20 * step))
        latency = int(rng.integers(0, 10 ** 8))
        t = int(rng.integers(0, 10 ** 10)) // step * step
        got = contract.feedback_frame_ns(t, period, latency, step)
        if t < latency:
            assert got is None
            continue
        n = next(n for n in range(t // period + 2)
                 if contract.frame_stamp_ns(n + 1, period, step) + latency > t)
        assert got == contract.frame_stamp_ns(n, period, step)
        assert got % step == 0 and got + latency <= t
        # on a grid that the camera period divides, the stamps are n * period
        if period % step == 0:
            assert got == (t - latency) // period * period


def test_seconds_and_nanoseconds_convert_by_one_rule():
    """seconds_to_ns is int(round(s * 1e9)) (not a truncation), ns_to_seconds t * 1e-9."""
    for seconds in (0.0, 0.5, 0.001, 1.0 / 30.0, 0.0335, 2.675, 123.456789, 1e-9, 7):
        assert seconds_to_ns(seconds) == int(round(seconds * 1e9))
        assert ns_to_seconds(seconds_to_ns(seconds)) == seconds_to_ns(seconds) * 1e-9
    assert seconds_to_ns(0.5) == 500_000_000 and seconds_to_ns(np.float64(0.02)) == 20_000_000
    # 4.1 * 1e9 = 4099999999.9999995: truncation would lose a nanosecond
    assert int(4.1 * 1e9) == 4_099_999_999 and seconds_to_ns(4.1) == 4_100_000_000
    assert isinstance(seconds_to_ns(np.float64(4.1)), int)


def test_diagnostics_counts_rejections_and_publishes(context):
    node = Node('diag_test', context=context)
    listener = Node('diag_listener', context=context)
    received = []
    listener.create_subscription(DiagnosticArray, contract.DIAGNOSTICS, received.append, 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(listener)
    try:
        diag = Diagnostics(node, 'test', period_s=0.05)
        diag.reject('/joint_states', 'non-finite position', 'nan')
        diag.reject('/joint_states', 'non-finite position', 'nan')
        diag.reject('/ibvs/features', 'wrong feature count')
        diag.update(mode='measured', rank=5)
        assert diag.rejected_total == 3
        for _ in range(200):
            executor.spin_once(timeout_sec=0.05)
            if received:
                break
        assert received, 'no /diagnostics message within the deadline'
        values = {kv.key: kv.value for kv in received[-1].status[0].values}
        assert values['rejected_total'] == '3'
        assert values['rejected[/joint_states: non-finite position]'] == '2'
        assert values['mode'] == 'measured' and values['rank'] == '5'
    finally:
        executor.shutdown()
        node.destroy_node()
        listener.destroy_node()


def test_a_malformed_clock_is_counted_and_the_node_keeps_its_sim_time(context):
    """A /clock with sec < 0 makes rclpy raise in the executor; Diagnostics' guard rejects it."""
    node = Node('clock_test', context=context,
                parameter_overrides=[Parameter('use_sim_time', value=True)])
    talker = Node('clock_talker', context=context)
    pub = talker.create_publisher(Clock, contract.CLOCK, 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(talker)
    try:
        diag = Diagnostics(node, 'test')
        for _ in range(400):
            if pub.get_subscription_count():
                break
            executor.spin_once(timeout_sec=0.05)

        def send(sec, nanosec, until):
            pub.publish(Clock(clock=Time(sec=sec, nanosec=nanosec)))
            for _ in range(400):  # spin_once raises here without the guard
                if until():
                    return
                executor.spin_once(timeout_sec=0.05)
            raise AssertionError(f'no effect of /clock {sec} s {nanosec} ns')

        send(5, 0, lambda: node.get_clock().now().nanoseconds == 5_000_000_000)
        send(-1, 0, lambda: diag.rejections['/clock: negative time'] == 1)
        send(7, 4_000_000_000, lambda: diag.rejections['/clock: malformed stamp'] == 1)
        assert node.get_clock().now().nanoseconds == 5_000_000_000
        send(6, 250, lambda: node.get_clock().now().nanoseconds == 6_000_000_250)
        assert diag.rejected_total == 2
        # use_sim_time still switches the node's clock, as rclpy's own TimeSource does
        node.set_parameters([Parameter('use_sim_time', value=False)])
        assert node.get_clock().now().nanoseconds > 1_000_000_000 * 10 ** 9
    finally:
        executor.shutdown()
        node.destroy_node()
        talker.destroy_node()


@pytest.mark.parametrize('camera_hz, physics_hz, ok', [
    (30.0, 1000.0, True), (1000.0, 1000.0, True), (7.0, 100.0, True),
    (1001.0, 1000.0, False), (120.0, 100.0, False)])
def test_frames_no_faster_than_physics_steps(camera_hz, physics_hz, ok):
    """The one rate rule, used by the simulator and the joint controller alike."""
    if ok:
        check_camera_rate(camera_hz, physics_hz)
    else:
        with pytest.raises(ValueError, match='camera_rate_hz <= physics_rate_hz'):
            check_camera_rate(camera_hz, physics_hz)
