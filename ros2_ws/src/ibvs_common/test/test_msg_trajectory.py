"""JointTrajectory <-> (N, 6) arrays: sampled trajectories, commands and joint paths."""

from builtin_interfaces.msg import Duration
from ibvs_common import contract, conversions
from ibvs_common.conversions import InputError
from ibvs_common.msg_trajectory import command_velocities
import numpy as np
import pytest

MS = 1_000_000
NAMES = list(contract.JOINT_NAMES)


def _reason(call, *args):
    with pytest.raises(InputError) as caught:
        call(*args)
    return caught.value.reason


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


def test_a_sampled_trajectory_is_read_back_exactly_from_the_message_and_its_arrays():
    rng = np.random.default_rng(31)
    for _ in range(50):
        n, period = int(rng.integers(1, 40)), int(rng.integers(1, 10 ** 9))
        start = int(rng.integers(0, 2 ** 31 * 10 ** 9))
        rows = rng.normal(scale=100.0, size=(n, 6))
        msg = conversions.joint_trajectory(start, period, rows)
        assert [conversions.duration_ns(p.time_from_start) for p in msg.points] == \
            [k * period for k in range(n)]
        for given in (msg, conversions.trajectory_arrays(msg)):
            got_start, got = conversions.read_trajectory(given, period)
            assert got_start == start and got.tobytes() == rows.tobytes()


def test_a_trajectory_point_carries_its_own_velocities_and_accelerations():
    rng = np.random.default_rng(32)
    rows, qd, qdd = (rng.normal(size=(4, 6)) for _ in range(3))
    msg = conversions.joint_trajectory(0, MS, rows, velocities=qd, accelerations=qdd)
    for k, point in enumerate(msg.points):
        assert list(point.positions) == rows[k].tolist()
        assert list(point.velocities) == qd[k].tolist()
        assert list(point.accelerations) == qdd[k].tolist()
        assert not len(point.effort)
    assert msg.header.frame_id == contract.BASE_FRAME and msg.joint_names == NAMES


def test_a_trajectory_position_beyond_the_bound_is_refused():
    bound = conversions.POSITION_BOUND_RAD
    rows = np.zeros((3, 6))
    rows[1, 4] = bound
    conversions.read_trajectory(conversions.joint_trajectory(0, MS, rows), MS)
    for beyond in (np.nextafter(bound, np.inf), -np.nextafter(bound, np.inf)):
        rows[1, 4] = beyond
        msg = conversions.joint_trajectory(0, MS, rows)
        assert _reason(conversions.read_trajectory, msg, MS) == 'positions out of range'


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


def _command(rows, times_ns=None, start_ns=0, names=NAMES):
    msg = conversions.joint_trajectory(start_ns, MS, np.atleast_2d(rows), names)
    if times_ns is not None:
        for point, t in zip(msg.points, times_ns):
            point.time_from_start = Duration(sec=t // 10 ** 9, nanosec=t % 10 ** 9)
    return msg


def test_a_good_trajectory_command_is_read_in_the_controllers_order():
    rows = np.arange(18, dtype=float).reshape(3, 6) * 0.01
    order = [5, 0, 1, 2, 3, 4]
    msg = _command(rows[:, order], names=[NAMES[i] for i in order])
    np.testing.assert_array_equal(conversions.read_command_trajectory(msg, 0, 100 * MS), rows)
    # stamped now, ending within the command timeout, and stamp 0 (start now) long after
    msg = _command(rows, start_ns=5 * MS)
    conversions.read_command_trajectory(msg, 100 * MS, 100 * MS)
    conversions.read_command_trajectory(_command(rows), 10 ** 12, 100 * MS)


def test_a_commands_velocities_are_read_in_the_controllers_order_where_every_point_has_them():
    rows = np.arange(18, dtype=float).reshape(3, 6) * 0.01
    order = [5, 0, 1, 2, 3, 4]
    msg = conversions.joint_trajectory(0, MS, rows[:, order], [NAMES[i] for i in order],
                                       velocities=-rows[:, order])
    np.testing.assert_array_equal(command_velocities(msg, NAMES), -rows)
    msg.points[1].velocities = []
    assert command_velocities(msg, NAMES) is None
    assert command_velocities(_command(rows), NAMES) is None


def _point_change(field, k, value):
    def change(msg):
        setattr(msg.points[k], field, value)
        return msg
    return change


@pytest.mark.parametrize('change, reason', [
    (lambda m: _command(np.zeros((3, 6)), [0, 2 * MS, 2 * MS]), 'times not increasing'),
    (lambda m: _command(np.zeros((3, 6)), [0, 3 * MS, 2 * MS]), 'times not increasing'),
    (lambda m: _command(np.zeros((2, 6)), [-2 * 10 ** 9, MS]), 'negative time_from_start'),
    (_point_change('positions', 0, [np.nan] + [0.0] * 5), 'non-finite positions'),
    (_point_change('positions', 1, [np.inf] + [0.0] * 5), 'non-finite positions'),
    (_point_change('velocities', 0, [np.nan] + [0.0] * 5), 'non-finite velocities'),
    (_point_change('accelerations', 2, [0.0] * 5 + [-np.inf]), 'non-finite accelerations'),
    (_point_change('velocities', 1, [0.0] * 5), 'wrong velocities length'),
    (_point_change('positions', 0, [0.0] * 7), 'wrong positions length'),
    (_point_change('effort', 2, [0.0] * 6), 'effort in a position command'),
    (lambda m: _command(np.zeros((3, 6)), names=NAMES[:5] + ['joint_7']), 'wrong joint names'),
    (lambda m: _command(np.zeros((3, 6)), names=[NAMES[0]] * 6), 'wrong joint names'),
    (lambda m: _command(np.zeros((0, 6))), 'empty trajectory'),
    (lambda m: _command(np.zeros((3, 6)), start_ns=10 * MS), 'trajectory ends in the past'),
    (lambda m: _command(np.zeros((3, 6)), start_ns=10 ** 12), 'stamp in the future'),
])
def test_a_trajectory_command_joint_trajectory_controller_refuses(change, reason):
    msg = change(_command(np.zeros((3, 6))))
    # now 1 s, command timeout 100 ms: stamp 10 ms + 2 ms is 888 ms too old
    assert _reason(conversions.read_command_trajectory, msg, 10 ** 9, 100 * MS) == reason
