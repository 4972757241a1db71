"""Parameters, conversions, diagnostics and the lockstep rule shared by the nodes."""

from types import SimpleNamespace

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from ibvs_common import contract, conversions
from ibvs_common.conversions import FeatureStatus, InputError
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.params import declare, Param, ParameterError
from ibvs_common.timing import check_camera_rate, ns_to_seconds, seconds_to_ns
from ibvs_model import default_model, forward_kinematics
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


def test_stamp_round_trip_is_exact():
    for ns in (0, 1, 999_999_999, 1_000_000_000, 123_456_789_012):
        assert conversions.stamp_ns(conversions.ns_stamp(ns)) == ns


def test_joint_state_round_trip_and_reordering():
    q = np.arange(6) * 0.1
    msg = conversions.joint_state(5, position=q)
    np.testing.assert_array_equal(conversions.read_joints(msg), q)
    msg.name = list(reversed(msg.name))
    msg.position = list(reversed(msg.position))
    np.testing.assert_array_equal(conversions.read_joints(msg), q)


def test_read_joints_ignores_other_joints_in_any_order():
    # joint_state_broadcaster: every joint of every hardware (a track, a gripper), its order
    q = np.arange(6) * 0.1 + 1.0
    names = ['gripper', 'joint_4', 'joint_2', 'track_1', 'joint_6', 'joint_1', 'joint_5',
             'joint_3']
    by_name = dict(zip(contract.JOINT_NAMES, q))
    position = [by_name.get(n, 7.5) for n in names]
    velocity = [float('nan') if n in ('gripper', 'track_1') else 0.0 for n in names]
    msg = conversions.joint_state(5, position=position, velocity=velocity, names=names)
    np.testing.assert_array_equal(conversions.read_joints(msg), q)
    np.testing.assert_array_equal(conversions.read_joints(msg, 'velocity'), np.zeros(6))
    assert conversions.ignored_joints(msg) == ('gripper', 'track_1')
    assert conversions.ignored_joints(conversions.joint_state(5, q)) == ()
    # the values of the other joints are not bounded: only the arm's are
    bound = (np.full(6, -2.0), np.full(6, 2.0))
    np.testing.assert_array_equal(conversions.read_joints(msg, bound=bound), q)
    # a controller's own joint order (``joints``) is read as well
    order = ['joint_6', 'joint_5', 'joint_4', 'joint_3', 'joint_2', 'joint_1']
    np.testing.assert_array_equal(conversions.read_joints(msg, names=order), q[::-1])


def test_joint_order_cache_stays_bounded():
    for k in range(3 * conversions.JOINT_ORDER_CACHE):
        names = list(contract.JOINT_NAMES) + [f'extra_{k}']
        assert conversions.joint_order(names)[1] == (f'extra_{k}',)
    assert len(conversions._JOINT_ORDERS) <= conversions.JOINT_ORDER_CACHE


@pytest.mark.parametrize('position,names,reason', [
    ([0.0] * 5, contract.JOINT_NAMES, 'wrong position length'),
    ([0.0] * 5 + [float('nan')], contract.JOINT_NAMES, 'non-finite position'),
    ([0.0] * 5 + [float('inf')], contract.JOINT_NAMES, 'non-finite position'),
    ([0.0] * 6, ['a', 'b', 'c', 'd', 'e', 'f'], 'missing joints'),
    ([0.0] * 5, contract.JOINT_NAMES[:5], 'missing joints'),
    ([0.0] * 6, contract.JOINT_NAMES[:5] + ('joint_1',), 'wrong joint names'),
    ([0.0] * 7, contract.JOINT_NAMES + ('joint_1',), 'wrong joint names'),
    ([0.0] * 6, contract.JOINT_NAMES + ('track_1',), 'wrong position length'),
    # values are mapped by name: a message that names no joint cannot be mapped
    ([0.0] * 6, [], 'no joint names'),
])
def test_read_joints_rejects_bad_messages(position, names, reason):
    msg = conversions.joint_state(0, position=position, names=names)
    with pytest.raises(InputError) as info:
        conversions.read_joints(msg)
    assert info.value.reason == reason


def test_check_finite_rejects_nan_or_inf_in_any_named_field_and_allows_empty_ones():
    msg = conversions.joint_state(0, position=np.zeros(6))
    conversions.check_finite(msg, ('velocity', 'effort'))  # empty: nothing to reject
    for field in ('velocity', 'effort'):
        for bad in (float('nan'), float('inf'), -float('inf')):
            msg = conversions.joint_state(0, position=np.zeros(6), **{field: [0.0] * 5 + [bad]})
            with pytest.raises(InputError) as info:
                conversions.check_finite(msg, ('velocity', 'effort'))
            assert info.value.reason == f'non-finite {field}'


@pytest.mark.parametrize('sec,nanosec,reason', [
    (-1, 0, 'negative time'),
    (-2 ** 31, 999_999_999, 'negative time'),
    (0, 1_000_000_000, 'malformed stamp'),
    (3, 4_000_000_000, 'malformed stamp'),
])
def test_read_stamp_rejects_what_stamp_ns_would_misread(sec, nanosec, reason):
    stamp = Time(sec=sec, nanosec=nanosec)
    with pytest.raises(InputError) as info:
        conversions.read_stamp(stamp)
    assert info.value.reason == reason


def test_read_stamp_is_stamp_ns_on_good_stamps():
    for ns in (0, 1, 999_999_999, 1_000_000_000, 2 ** 31 * 1_000_000_000 - 1):
        assert conversions.read_stamp(conversions.ns_stamp(ns)) == ns


def test_the_one_stamp_rule_refuses_future_and_off_grid_stamps():
    ms, cam = 1_000_000, 33_333_333
    # one input period and the clock's lag margin (a stale timeout shorter than it: that)
    lead = conversions.stamp_lead_ns(0.5, cam)
    assert lead == conversions.STAMP_LEAD_MARGIN_NS + cam
    assert conversions.stamp_lead_ns(0.05, cam) == 50 * ms + cam
    # Time unknown (None) counts as 0, the start of sim time: 2^31 s is in the future.
    with pytest.raises(InputError, match='stamp in the future'):
        conversions.read_stamp(Time(sec=2 ** 31 - 1), None, lead)
    assert conversions.read_stamp(Time(sec=0, nanosec=lead), None, lead) == lead
    with pytest.raises(InputError, match='stamp in the future'):
        conversions.read_stamp(Time(sec=0, nanosec=lead + 1), None, lead)
    assert conversions.read_stamp(Time(sec=10), 9_900 * ms, lead) == 10_000 * ms
    with pytest.raises(InputError, match='stamp in the future'):  # 0.4 s ahead: refused
        conversions.read_stamp(Time(sec=10), 9_600 * ms, lead)
    frames = (cam, ms)
    assert conversions.read_stamp(Time(sec=0, nanosec=34 * ms), 0, lead, frames) == 34 * ms
    for off_grid in (33 * ms, 33_333_333, 35 * ms):
        with pytest.raises(InputError, match='off the frame grid'):
            conversions.read_stamp(Time(sec=0, nanosec=off_grid), 0, lead, frames)


def test_joint_trajectory_round_trip_reorders_by_name_and_rejects_bad_ones():
    rng = np.random.default_rng(3)
    rows = rng.normal(size=(7, 6))
    msg = conversions.joint_trajectory(5_000_000_123, 1_000_000, rows)
    assert conversions.stamp_ns(msg.header.stamp) == 5_000_000_123
    assert conversions.duration_ns(msg.points[-1].time_from_start) == 6_000_000
    start, back = conversions.read_trajectory(msg, 1_000_000)
    assert start == 5_000_000_123
    np.testing.assert_array_equal(back, rows)  # exact: doubles travel as doubles
    msg.joint_names = list(reversed(msg.joint_names))
    np.testing.assert_array_equal(conversions.read_trajectory(msg, 1_000_000)[1],
                                  rows[:, ::-1])
    with pytest.raises(InputError, match='wrong sample times'):
        conversions.read_trajectory(msg, 2_000_000)
    msg.points[2].positions = [np.nan] * 6
    with pytest.raises(InputError, match='non-finite positions'):
        conversions.read_trajectory(msg, 1_000_000)
    msg.joint_names = ['a'] * 6
    with pytest.raises(InputError, match='wrong joint names'):
        conversions.read_trajectory(msg, 1_000_000)
    for field in ('velocities', 'accelerations', 'effort'):
        msg = conversions.joint_trajectory(0, 1_000_000, rows)
        setattr(msg.points[3], field, [0.0] * 5 + [float('nan')])
        with pytest.raises(InputError, match=f'non-finite {field}'):
            conversions.read_trajectory(msg, 1_000_000)
        setattr(msg.points[3], field, [0.0] * 6)  # finite: allowed, and not read
        np.testing.assert_array_equal(conversions.read_trajectory(msg, 1_000_000)[1], rows)
    with pytest.raises(InputError, match='empty trajectory'):
        conversions.read_trajectory(conversions.joint_trajectory(0, 1, np.empty((0, 6))), 1)


def test_joint_path_round_trip_keeps_stamps_and_values_and_reorders_by_name():
    rng = np.random.default_rng(4)
    names = list(reversed(contract.JOINT_NAMES))
    states = [conversions.joint_state(1_999_000_000 + k * 1_000_000, rng.normal(size=6),
                                      rng.normal(size=6), rng.normal(size=6), names)
              for k in range(3)]
    msg = conversions.joint_path(states)
    assert conversions.stamp_ns(msg.header.stamp) == 1_999_000_000  # the first state's
    stamps, q, qd, tau = conversions.read_joint_path(msg)
    assert stamps.tolist() == [1_999_000_000, 2_000_000_000, 2_001_000_000]
    for got, field in ((q, 'position'), (qd, 'velocity'), (tau, 'effort')):
        assert got.tobytes() == np.array([list(getattr(m, field))[::-1]
                                          for m in states]).tobytes()
    # A position-controlled simulator models no torque: no effort in the batch.
    no_torque = conversions.joint_path([conversions.joint_state(0, np.zeros(6), np.zeros(6))])
    assert conversions.read_joint_path(no_torque)[3].shape == (1, 0)
    msg.points[1].velocities = [0.0] * 5
    with pytest.raises(InputError, match='wrong velocities length'):
        conversions.read_joint_path(msg)
    msg.joint_names = ['a'] * 6
    with pytest.raises(InputError, match='wrong joint names'):
        conversions.read_joint_path(msg)
    assert not conversions.joint_path([]).points


def test_pose_round_trip():
    tf = forward_kinematics(np.radians([10, 20, 30, 40, 50, 60]))
    back = conversions.pose_matrix(conversions.matrix_pose(tf))
    np.testing.assert_allclose(back, tf, atol=1e-12)
    bad = conversions.matrix_pose(tf)
    bad.orientation.w = 5.0
    with pytest.raises(InputError, match='quaternion'):
        conversions.pose_matrix(bad)


def test_camera_round_trip_through_camera_info_and_pose():
    camera = default_model().camera
    left, right = conversions.camera_infos(camera.intrinsics, 0)
    assert right.p[3] == pytest.approx(-camera.intrinsics.fu * 0.12)
    pose = conversions.pose_stamped(camera.pose_C_O, 0, contract.BASE_FRAME)
    back = conversions.camera_from_msgs(left, right, pose)
    k, kb = camera.intrinsics, back.intrinsics
    assert (kb.width, kb.height) == (k.width, k.height)
    np.testing.assert_allclose([kb.fu, kb.fv, kb.cu, kb.cv, kb.baseline],
                               [k.fu, k.fv, k.cu, k.cv, k.baseline], rtol=1e-12)
    np.testing.assert_allclose(back.pose_C_O, camera.pose_C_O, atol=1e-12)
    point = np.array([[0.1, 0.3, 0.8]])
    np.testing.assert_allclose(back.project(point), camera.project(point), atol=1e-9)


def test_camera_info_mismatch_is_rejected():
    camera = default_model().camera
    left, right = conversions.camera_infos(camera.intrinsics, 0)
    right.width += 2  # a lens of its own, not this one's pair
    with pytest.raises(InputError, match='size mismatch'):
        conversions.intrinsics_from_infos(left, right)
    left, right = conversions.camera_infos(camera.intrinsics, 0)
    right.p[3] = 0.0
    with pytest.raises(InputError, match='P\\[3\\]'):
        conversions.intrinsics_from_infos(left, right)


def test_feature_status_round_trip_and_rejection():
    """The writer and the reader of /ibvs/feature_status agree; bad statuses are refused."""
    for mode in contract.FEATURE_MODES:
        for reason in (contract.FEATURE_MEASURED, 'not in view: marker 1 left'):
            status = FeatureStatus(mode, contract.FEATURE_ESTIMATED, reason, 0.25, 'roi')
            msg = conversions.feature_status_msg(status, 34_000_000, name='n: features')
            assert conversions.stamp_ns(msg.header.stamp) == 34_000_000
            assert [kv.key for kv in msg.status[0].values] == list(contract.FEATURE_STATUS_KEYS)
            back = conversions.read_feature_status(msg)
            assert back == status and back.measured == (reason == contract.FEATURE_MEASURED)
    # the weight travels with 6 significant digits
    status = FeatureStatus(contract.FEATURE_BLENDING, contract.FEATURE_MEASURED,
                           contract.FEATURE_MEASURED, 1.0 / 3.0, 'full')
    back = conversions.read_feature_status(conversions.feature_status_msg(status, 0))
    assert back.blend_weight == 0.333333
    assert back._replace(blend_weight=status.blend_weight) == status
    with pytest.raises(InputError, match='no status'):
        conversions.read_feature_status(DiagnosticArray())
    for key, value, match in (('mode', 'guessed', 'mode'), ('blend_weight', 'nan', 'blend'),
                              ('blend_weight', 'x', 'blend'), ('search', None, 'no search')):
        msg = conversions.feature_status_msg(status, 0)
        values = msg.status[0].values
        if value is None:
            msg.status[0].values = [kv for kv in values if kv.key != key]
        else:
            next(kv for kv in values if kv.key == key).value = value
        with pytest.raises(InputError, match=match) as caught:
            conversions.read_feature_status(msg)
        assert caught.value.reason == 'malformed feature status'


def test_seconds_and_nanoseconds_convert_by_one_rule():
    """seconds_to_ns is int(round(s * 1e9)) (not a truncation), ns_to_seconds t * 1e-9."""
    for seconds in (0.0, 0.5, 0.001, 1.0 / 30.0, 0.0335, 2.675, 123.456789, 1e-9, 7):
        assert seconds_to_ns(seconds) == int(round(seconds * 1e9))
        assert ns_to_seconds(seconds_to_ns(seconds)) == seconds_to_ns(seconds) * 1e-9
    assert seconds_to_ns(0.5) == 500_000_000 and seconds_to_ns(np.float64(0.02)) == 20_000_000
    # 4.1 * 1e9 = 4099999999.9999995: truncation would lose a nanosecond
    assert int(4.1 * 1e9) == 4_099_999_999 and seconds_to_ns(4.1) == 4_100_000_000
    assert isinstance(seconds_to_ns(np.float64(4.1)), int)


def test_features_round_trip_and_rejection():
    p = np.array([600.25, 560.5, 300.125, 610.0, 570.75, 320.5])
    np.testing.assert_array_equal(conversions.read_features(conversions.features_msg(p, 7)), p)
    msg = conversions.features_msg(p, 7)
    msg.polygon.points = msg.polygon.points[:1]
    with pytest.raises(InputError, match='wrong feature count'):
        conversions.read_features(msg)
    msg = conversions.features_msg(p, 7)
    msg.polygon.points[0].x = float('nan')
    with pytest.raises(InputError, match='non-finite'):
        conversions.read_features(msg)
    camera = default_model().camera
    left, right = conversions.camera_infos(camera.intrinsics, 0)
    left.p = [0.0] * 3
    with pytest.raises(InputError, match='12 finite'):
        conversions.camera_from_msgs(left, right, SimpleNamespace(pose=None))


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
