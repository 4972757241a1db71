"""JointState <-> (6,) arrays by joint name, and the ranges a joint value is read in."""

from ibvs_common import contract, conversions
from ibvs_common.conversions import InputError
from ibvs_model import IRB4600
import numpy as np
import pytest


def test_joint_state_round_trip_and_reordering():
    q = np.arange(6) * 0.1
    msg = conversions.joint_state(5, position=q)
    np.testing.assert_array_equal(conversions.read_joints(msg), q)
    msg.name = list(reversed(msg.name))
    msg.position = list(reversed(msg.position))
    np.testing.assert_array_equal(conversions.read_joints(msg), q)


def test_joint_state_round_trip_is_exact_for_every_field_in_any_name_order():
    rng = np.random.default_rng(21)
    for _ in range(200):
        names = [str(n) for n in rng.permutation(contract.JOINT_NAMES)]
        values = {field: rng.normal(scale=10.0, size=6) for field in conversions.JOINT_FIELDS}
        ns = int(rng.integers(0, 2 ** 31 * 10 ** 9))
        msg = conversions.joint_state(ns, names=names, **values)
        assert conversions.stamp_ns(msg.header.stamp) == ns
        assert msg.header.frame_id == contract.BASE_FRAME
        for field, given in values.items():
            by_name = dict(zip(names, given))
            expected = np.array([by_name[n] for n in contract.JOINT_NAMES])
            assert conversions.read_joints(msg, field).tobytes() == expected.tobytes()
            # read in the message's own order, the values come back as given
            assert conversions.read_joints(msg, field, names).tobytes() == given.tobytes()


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


def test_the_read_bounds_are_symmetric_read_only_and_the_same_arrays_each_call():
    for bounds, limit in ((conversions.position_bounds, conversions.POSITION_BOUND_RAD),
                          (conversions.velocity_bounds, conversions.SPEED_BOUND_RAD_S)):
        low, high = bounds()
        assert bounds()[0] is low and bounds()[1] is high
        assert low.tolist() == [-limit] * 6 and high.tolist() == [limit] * 6
        assert not low.flags.writeable and not high.flags.writeable


def test_the_travel_bounds_are_the_travel_widened_by_the_margin():
    low, high = conversions.travel_bounds()
    margin = conversions.POSITION_MARGIN_RAD
    assert low.tolist() == (np.asarray(IRB4600.q_min, dtype=float) - margin).tolist()
    assert high.tolist() == (np.asarray(IRB4600.q_max, dtype=float) + margin).tolist()


@pytest.mark.parametrize('field, bounds', [('position', conversions.position_bounds),
                                           ('velocity', conversions.velocity_bounds)])
def test_a_value_outside_its_bound_is_refused_as_out_of_range(field, bounds):
    low, high = bounds()
    for joint in range(6):
        for value, ok in ((high[joint], True), (low[joint], True),
                          (np.nextafter(high[joint], np.inf), False),
                          (np.nextafter(low[joint], -np.inf), False)):
            values = np.zeros(6)
            values[joint] = value
            msg = conversions.joint_state(0, **{'position': np.zeros(6), field: values})
            if ok:
                assert conversions.read_joints(msg, field, bound=(low, high))[joint] == value
            else:
                with pytest.raises(InputError) as info:
                    conversions.read_joints(msg, field, bound=(low, high))
                assert info.value.reason == f'{field} out of range'
