"""
Direct delivery between the nodes of one process (ibvs_common.intra_process).

Each test has its own rclpy Context, as rclpy's own tests do. A second Context is a DDS
participant of its own: a reader there stands for a reader in another process.
"""

import time

from geometry_msgs.msg import PolygonStamped
from ibvs_common import intra_process
from ibvs_common.conversions import features_msg, joint_state, ns_stamp
from ibvs_common.node_main import make_executor, spin_until_stopped
import pytest
import rclpy
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState

TOPIC = '/intra_process_test'
COUNT = 20


@pytest.fixture
def context():
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.try_shutdown(context=ctx)


class Stop:
    """What spin_until_stopped asks between callbacks: stop when ``done()`` is true."""

    def __init__(self, done, timeout_s=20.0):
        self.done, self.deadline = done, time.monotonic() + timeout_s

    def is_set(self):
        return self.done() or time.monotonic() > self.deadline


class Talker(Node):
    """Publishes COUNT JointStates, stamped 1..COUNT, once ``ready()`` says so."""

    def __init__(self, context, ready):
        super().__init__('talker', context=context)
        self.pub = intra_process.publisher(self, JointState, TOPIC, 100)
        self.sent, self.ready = 0, ready
        self.create_timer(0.005, self._tick)

    def _tick(self):
        if self.sent < COUNT and self.ready(self.pub.get_subscription_count()):
            self.sent += 1
            self.pub.publish(joint_state(self.sent, [0.0] * 6))


class Listener(Node):
    """Records the stamps it gets."""

    def __init__(self, context, name='listener'):
        super().__init__(name, context=context)
        self.stamps = []
        self.sub = intra_process.subscription(self, JointState, TOPIC, self._on_state, 100)

    def _on_state(self, msg):
        self.stamps.append(msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec)


def _spin_other(node, until, timeout_s=20.0):
    executor = make_executor(node.context)
    executor.add_node(node)
    deadline = time.monotonic() + timeout_s
    while not until() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.01)
    executor.shutdown(timeout_sec=0.0)


def test_a_reader_in_the_process_gets_every_message_directly_in_order(context):
    listener = Listener(context)
    talker = Talker(context, ready=lambda count: count >= 1)
    bus = intra_process.bus_of(context)
    spin_until_stopped([listener, talker], Stop(lambda: len(listener.stamps) >= COUNT))
    assert listener.stamps == list(range(1, COUNT + 1))
    assert bus.delivered >= COUNT and not bus.active
    for node in (talker, listener):
        node.destroy_node()


def test_a_reader_elsewhere_gets_dds_and_the_one_in_the_process_each_message_once(context):
    other = rclpy.Context()
    rclpy.init(context=other)
    try:
        remote = Listener(other, 'remote_listener')
        local = Listener(context)
        talker = Talker(context, ready=lambda count: count >= 2)  # both readers matched
        spin_until_stopped([local, talker], Stop(lambda: len(local.stamps) >= COUNT))
        # The local reader's DDS copies come after its direct deliveries: spin them in.
        spin_until_stopped([local, talker], Stop(lambda: False, timeout_s=0.5))
        _spin_other(remote, lambda: len(remote.stamps) >= COUNT)
        assert local.stamps == list(range(1, COUNT + 1))
        assert remote.stamps == list(range(1, COUNT + 1))
        for node in (talker, local, remote):
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=other)


def test_a_burst_with_a_reader_elsewhere_reaches_the_local_reader_once_each(context):
    # More messages in one callback than a drain slice takes, as the lockstep publishes
    # /joint_states while `ros2 topic echo` listens elsewhere: every DDS copy is dropped.
    burst = 300
    other = rclpy.Context()
    rclpy.init(context=other)
    try:
        remote = Listener(other, 'remote_listener')
        local = Listener(context)

        class Burst(Node):

            def __init__(self):
                super().__init__('burst', context=context)
                self.pub = intra_process.publisher(self, JointState, TOPIC, 1000)
                self.done = False
                self.create_timer(0.01, self._tick)

            def _tick(self):
                if not self.done and self.pub.get_subscription_count() >= 2:
                    for k in range(1, burst + 1):
                        self.pub.publish(joint_state(k, [0.0] * 6))
                    self.done = True

        talker = Burst()
        reader = local.sub.callback.__self__  # the intra_process.Reader

        def settled():  # every message delivered, and the DDS copies came (the last at least)
            return len(local.stamps) >= burst and not any(reader.expected.values())

        spin_until_stopped([local, talker], Stop(settled))
        assert local.stamps == list(range(1, burst + 1))
        assert settled()
        for node in (talker, local, remote):
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=other)


def test_a_message_is_delivered_after_the_publishing_callback_returns(context):
    order = []

    class Echo(Node):

        def __init__(self):
            super().__init__('echo', context=context)
            self.pub = intra_process.publisher(self, JointState, TOPIC, 10)
            intra_process.subscription(self, JointState, TOPIC,
                                       lambda msg: order.append('delivered'), 10)
            self.timer = self.create_timer(0.01, self._tick)

        def _tick(self):
            self.timer.cancel()
            self.pub.publish(joint_state(1, [0.0] * 6))
            order.append('published')

    echo = Echo()
    spin_until_stopped([echo], Stop(lambda: 'delivered' in order))
    assert order == ['published', 'delivered']
    echo.destroy_node()


def test_a_callback_that_raises_ends_the_spin_with_its_exception(context):
    # As a subscription callback's exception does (a traceback and exit code 1 in a node's
    # main), not a crash of the executor's task.
    listener = Listener(context)

    def broken(msg):
        raise RuntimeError('broken callback')

    listener.sub.callback.__self__.callback = broken
    talker = Talker(context, ready=lambda count: count >= 1)
    with pytest.raises(RuntimeError, match='broken callback'):
        spin_until_stopped([listener, talker], Stop(lambda: False))
    assert not intra_process.bus_of(context).active
    for node in (talker, listener):
        node.destroy_node()


def test_a_destroyed_subscription_gets_nothing_more(context):
    listener = Listener(context)
    talker = Talker(context, ready=lambda count: count >= 1)
    spin_until_stopped([listener, talker], Stop(lambda: len(listener.stamps) >= 3))
    listener.destroy_subscription(listener.sub)
    got = len(listener.stamps)
    spin_until_stopped([listener, talker], Stop(lambda: talker.sent >= COUNT))
    assert len(listener.stamps) == got
    for node in (talker, listener):
        node.destroy_node()


def test_without_a_draining_loop_every_message_takes_dds(context):
    listener = Listener(context)
    talker = Talker(context, ready=lambda count: count >= 1)
    executor = make_executor(context)
    for node in (listener, talker):
        executor.add_node(node)
    deadline = time.monotonic() + 20.0
    while len(listener.stamps) < COUNT and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.01)
    executor.shutdown(timeout_sec=0.0)
    assert listener.stamps == list(range(1, COUNT + 1))
    assert intra_process.bus_of(context).delivered == 0
    for node in (talker, listener):
        node.destroy_node()


def test_features_hold_what_dds_carries():
    # Point32 is float32: the object a reader gets directly equals the DDS copy, or a
    # reader in the process would see other values than one elsewhere (and would take the
    # DDS copy for a new message).
    msg = features_msg([640.123456789, 600.987654321, 360.5, 700.1, 660.2, 380.3], 123)
    copy = deserialize_message(serialize_message(msg), PolygonStamped)
    assert copy == msg
    assert msg.header.stamp == ns_stamp(123)
