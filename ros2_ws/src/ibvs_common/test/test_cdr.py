"""A JointTrajectory read from and written to its serialized bytes, as arrays."""

from ibvs_common import cdr, conversions
from ibvs_common.conversions import InputError
from ibvs_common.msg_trajectory import joint_trajectory_bytes
import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

MS = 1_000_000


def random_trajectory(rng, ragged):
    """Return a JointTrajectory of random names, stamps, values and array lengths."""
    msg = JointTrajectory(joint_names=['j' * int(rng.integers(1, 8))
                                       for _ in range(int(rng.integers(0, 7)))])
    msg.header.frame_id = 'x' * int(rng.integers(0, 9))
    msg.header.stamp.sec = int(rng.integers(-2 ** 31, 2 ** 31))
    msg.header.stamp.nanosec = int(rng.integers(0, 2 ** 32))
    shape = [int(rng.choice([0, 1, 2, 3, 6, 7])) for _ in cdr.POINT_ARRAYS]
    points = []
    for _ in range(int(rng.integers(0, 7))):
        lengths = [int(rng.choice([0, 1, 6])) for _ in shape] if ragged else shape
        point = JointTrajectoryPoint(**{
            name: rng.normal(size=n).tolist() for name, n in zip(cdr.POINT_ARRAYS, lengths)})
        if rng.random() < 0.1:
            point.velocities = [float('nan')] * max(1, lengths[1])
        point.time_from_start.sec = int(rng.integers(-2 ** 31, 2 ** 31))
        point.time_from_start.nanosec = int(rng.integers(0, 2 ** 32))
        points.append(point)
    msg.points = points
    return msg


def as_read_by_rclpy(msg):
    """Return the arrays of ``msg`` read from its Python objects (the fallback)."""
    return conversions.trajectory_arrays(msg)


@pytest.mark.parametrize('seed', range(4))
def test_the_bytes_give_what_rclpy_reads_and_points_of_one_shape_are_read_as_arrays(seed):
    rng = np.random.default_rng(seed)
    for _ in range(300):
        ragged = rng.random() < 0.3
        raw = serialize_message(random_trajectory(rng, ragged))
        msg = deserialize_message(raw, JointTrajectory)
        shapes = {tuple(len(getattr(p, name)) for name in cdr.POINT_ARRAYS)
                  for p in msg.points}
        fast = cdr.trajectory_arrays(raw)
        assert (fast is None) == (len(shapes) > 1)  # one shape (or none): read as arrays
        got, want = conversions.trajectory_arrays(raw), as_read_by_rclpy(msg)
        assert got.stamp == want.stamp and got.joint_names == want.joint_names
        np.testing.assert_array_equal(got.times_ns, want.times_ns)
        assert got.finite == want.finite
        if want.positions is None:
            assert got.positions is None
        elif msg.points:
            np.testing.assert_array_equal(got.positions, want.positions)  # bit for bit


def test_a_trajectory_from_bytes_is_read_and_refused_as_the_message_is():
    rows = np.random.default_rng(5).normal(size=(6000, 6))
    msg = conversions.joint_trajectory(5_000_000_123, MS, rows,
                                       velocities=np.zeros((6000, 6)))
    msg.joint_names = list(reversed(msg.joint_names))
    raw = serialize_message(msg)
    assert cdr.trajectory_arrays(raw) is not None
    start, back = conversions.read_trajectory(raw, MS)
    assert start == 5_000_000_123
    np.testing.assert_array_equal(back, rows[:, ::-1])
    for field in ('positions', 'velocities', 'accelerations', 'effort'):
        bad = conversions.joint_trajectory(0, MS, rows[:3])
        setattr(bad.points[1], field, [0.0] * 5 + [float('inf')])
        with pytest.raises(InputError, match=f'non-finite {field}'):
            conversions.read_trajectory(serialize_message(bad), MS)
    with pytest.raises(InputError, match='wrong sample times'):
        conversions.read_trajectory(raw, 2 * MS)
    with pytest.raises(InputError, match='empty trajectory'):
        conversions.read_trajectory(serialize_message(JointTrajectory(
            joint_names=msg.joint_names)), MS)
    ragged = conversions.joint_trajectory(0, MS, rows[:3])
    ragged.points[2].positions = [0.0] * 5
    with pytest.raises(InputError, match='wrong positions length'):
        conversions.read_trajectory(serialize_message(ragged), MS)


def test_bytes_that_are_no_trajectory_are_refused_as_malformed():
    raw = serialize_message(conversions.joint_trajectory(0, MS, np.zeros((3, 6))))
    for broken in (raw[:40], b'\x00\x01\x00\x00', b'', raw[:2] + b'\xff' * 60):
        with pytest.raises(InputError, match='malformed message'):
            conversions.read_trajectory(broken, MS)


@pytest.mark.parametrize('seed', range(6))
def test_written_bytes_deserialize_to_the_message_and_read_back_as_its_arrays(seed):
    rng = np.random.default_rng(seed)
    names = ['j' * int(rng.integers(1, 8)) for _ in range(int(rng.integers(0, 7)))]
    count, width = int(rng.integers(0, 9)), int(rng.choice([0, 1, 2, 3, 6, 7]))
    stamp = JointTrajectory().header.stamp
    stamp.sec, stamp.nanosec = int(rng.integers(-2 ** 31, 2 ** 31)), int(rng.integers(0, 2 ** 32))
    frame_id = 'x' * int(rng.integers(0, 9))
    times_ns = rng.integers(-10 ** 12, 10 ** 12, size=count)
    positions = rng.normal(size=(count, width))
    extra = [rng.normal(size=(count, width)) if rng.random() < 0.5 else None for _ in range(2)]
    data = cdr.trajectory_bytes(stamp, frame_id, names, times_ns, positions, *extra)
    expected = JointTrajectory(joint_names=names)
    expected.header.stamp, expected.header.frame_id = stamp, frame_id
    for k in range(count):
        point = JointTrajectoryPoint(positions=positions[k].tolist())
        for field, values in zip(('velocities', 'accelerations'), extra):
            if values is not None:
                setattr(point, field, values[k].tolist())
        point.time_from_start.sec, point.time_from_start.nanosec = divmod(int(times_ns[k]),
                                                                          10 ** 9)
        expected.points.append(point)
    assert deserialize_message(data, JointTrajectory) == expected
    arrays = cdr.trajectory_arrays(data)
    np.testing.assert_array_equal(arrays.times_ns, times_ns)
    if count:
        np.testing.assert_array_equal(arrays.positions, positions)


def test_a_feedforward_trajectory_as_bytes_is_the_message_joint_trajectory_builds():
    positions = np.random.default_rng(7).normal(size=(1000, 6))
    velocities = np.gradient(positions, axis=0)
    data = joint_trajectory_bytes(123 * MS, MS, positions, velocities=velocities)
    assert deserialize_message(data, JointTrajectory) == conversions.joint_trajectory(
        123 * MS, MS, positions, velocities=velocities)
