"""
trajectory_msgs/JointTrajectory <-> (N, 6) arrays: feedforward, commands, joint paths.

A trajectory sampled every period (:func:`joint_trajectory`, :func:`read_trajectory`, also
from its serialized bytes: :mod:`.cdr`), a joint_trajectory_controller command
(:func:`read_command_trajectory`, :func:`command_velocities`) and a batch of joint states
as one message (:func:`joint_path`, :func:`read_joint_path`). Readers raise
:class:`.input_error.InputError`.
"""

from collections.abc import Iterable, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from . import cdr, contract
from .input_error import InputError
from .msg_joints import POSITION_BOUND_RAD
from .msg_time import duration_ns, ns_stamp, read_stamp, stamp_ns
from .timing import NS_PER_S


def joint_trajectory(start_ns: int, period_ns: int, positions: ArrayLike,
                     names: Iterable[str] = contract.JOINT_NAMES,
                     velocities: ArrayLike | None = None,
                     accelerations: ArrayLike | None = None) -> JointTrajectory:
    """
    Return positions sampled every ``period_ns`` from ``start_ns`` as a JointTrajectory.

    ``positions``: (N, 6). Point k has time_from_start = k * period_ns; the header stamp is
    the time of point 0 (the trajectory_msgs convention). ``velocities`` and
    ``accelerations`` (N, 6), when given, fill the points' own (joint_trajectory_controller
    then sends each point's velocity to the hardware, not the segments' slopes).
    """
    msg = JointTrajectory()
    msg.header.stamp = ns_stamp(start_ns)
    msg.header.frame_id = contract.BASE_FRAME
    msg.joint_names = list(names)
    points = []
    velocities = None if velocities is None else np.asarray(velocities, dtype=float)
    accelerations = None if accelerations is None else np.asarray(accelerations, dtype=float)
    for k, row in enumerate(np.asarray(positions, dtype=float)):
        point = JointTrajectoryPoint(positions=row.tolist())
        if velocities is not None:
            point.velocities = velocities[k].tolist()
        if accelerations is not None:
            point.accelerations = accelerations[k].tolist()
        t = k * int(period_ns)
        point.time_from_start.sec, point.time_from_start.nanosec = divmod(t, NS_PER_S)
        points.append(point)
    msg.points = points
    return msg


def joint_trajectory_bytes(start_ns: int, period_ns: int, positions: ArrayLike,
                           names: Iterable[str] = contract.JOINT_NAMES,
                           velocities: ArrayLike | None = None,
                           accelerations: ArrayLike | None = None) -> bytes:
    """
    Return :func:`joint_trajectory`'s message as its serialized bytes, for a publisher.

    The same message (it deserializes equal), written by :func:`.cdr.trajectory_bytes`
    from the arrays without a point object: a publisher sends these bytes as they are, in
    a few milliseconds where building the message takes rclpy about 7 us a point.
    """
    positions = np.asarray(positions, dtype=float)
    return cdr.trajectory_bytes(ns_stamp(start_ns), contract.BASE_FRAME, list(names),
                                np.arange(len(positions), dtype=np.int64) * int(period_ns),
                                positions, velocities, accelerations)


def trajectory_arrays(msg: 'JointTrajectory | bytes | cdr.TrajectoryArrays'
                      ) -> cdr.TrajectoryArrays:
    """
    Return what :func:`read_trajectory` checks of a JointTrajectory, as arrays.

    ``msg``: the message, or its serialized bytes (a subscription made with ``raw=True``:
    read with numpy, :mod:`.cdr`, where its points are all of one shape, else deserialized
    as rclpy does), or arrays already read (returned as they are). Raises
    :class:`InputError` ('malformed message') for bytes that are no JointTrajectory.
    """
    if isinstance(msg, cdr.TrajectoryArrays):
        return msg
    if isinstance(msg, (bytes, bytearray, memoryview)):
        arrays = cdr.trajectory_arrays(msg)
        if arrays is not None:
            return arrays
        try:
            msg = deserialize_message(bytes(msg), JointTrajectory)
        except Exception as exc:  # rclpy raises what rmw says, of no one class
            raise InputError('malformed message', f'not a JointTrajectory: {exc}') from None
    try:
        positions = np.array([p.positions for p in msg.points], dtype=float)
    except ValueError:
        positions = None  # ragged
    return cdr.TrajectoryArrays(
        msg.header.stamp, list(msg.joint_names),
        np.array([duration_ns(p.time_from_start) for p in msg.points], dtype=np.int64),
        positions, {field: all(np.all(np.isfinite(np.asarray(getattr(p, field), dtype=float)))
                               for p in msg.points) for field in cdr.POINT_ARRAYS[1:]})


def read_trajectory(msg: 'JointTrajectory | bytes | cdr.TrajectoryArrays', period_ns: int,
                    names: Sequence[str] = contract.JOINT_NAMES
                    ) -> tuple[int, NDArray[np.float64]]:
    """
    Return (start ns, (N, 6) positions) of a JointTrajectory sampled every ``period_ns``.

    The points must be at 0, period_ns, 2 period_ns, ... from the header stamp, with finite
    positions for the six joints (in any order, mapped by name). Velocities, accelerations
    and efforts are not read: they may be empty, but a non-finite value there rejects the
    trajectory (as :func:`check_finite` does for a JointState), and so does a position beyond
    :data:`POSITION_BOUND_RAD`. The stamp is returned as it is: the caller applies
    :func:`read_stamp` with its own time. ``msg`` may also be the message's serialized bytes
    or its arrays (:func:`trajectory_arrays`). Raises :class:`InputError`.
    """
    arrays = trajectory_arrays(msg)
    joint_names = arrays.joint_names
    if len(joint_names) != len(names) or set(joint_names) != set(names):
        raise InputError('wrong joint names', f'{joint_names}')
    times = arrays.times_ns
    if not len(times):
        raise InputError('empty trajectory')
    if not np.array_equal(times, np.arange(len(times)) * int(period_ns)):
        raise InputError('wrong sample times', f'points must be {period_ns} ns apart from 0')
    positions = arrays.positions
    if positions is None:
        raise InputError('wrong positions length', 'ragged points')
    if positions.shape != (len(times), len(names)):
        raise InputError('wrong positions length',
                         f'{positions.shape[1:]} values per point, expected {len(names)}')
    if not np.all(np.isfinite(positions)):
        raise InputError('non-finite positions')
    if np.any(np.abs(positions) > POSITION_BOUND_RAD):
        raise InputError('positions out of range',
                         f'beyond +-{POSITION_BOUND_RAD:g} rad (POSITION_BOUND_RAD)')
    positions = positions[:, [joint_names.index(n) for n in names]]
    for field in cdr.POINT_ARRAYS[1:]:
        if not arrays.finite[field]:
            raise InputError(f'non-finite {field}')
    return stamp_ns(arrays.stamp), positions


def read_command_trajectory(msg: JointTrajectory, now_ns: int, timeout_ns: int,
                            names: Sequence[str] = contract.JOINT_NAMES
                            ) -> NDArray[np.float64]:
    """
    Return the (N, 6) positions of a joint_trajectory_controller command, names' order.

    What ros2_controllers' joint_trajectory_controller refuses (jazzy branch, 4.42.1,
    commit ed360c9, ``joint_trajectory_controller/src/joint_trajectory_controller.cpp``,
    ``validate_trajectory_msg`` from line 1671) is refused here, each with its reason:

    - 'wrong joint names' (lines 1676-1714: every controller joint, no other) and 'empty
      trajectory' (line 1695); our names must also be distinct;
    - 'times not increasing': a ``time_from_start`` not after the point before (line 1755,
      "not strictly increasing");
    - 'trajectory ends in the past': a non-zero header stamp whose last point's time
      (stamp + its ``time_from_start``) is before now (lines 1732-1749; a zero stamp means
      start now). Here with ``timeout_ns`` (the command timeout) of grace: a reference
      stamped at its publication reaches a free-running sim a few steps later, and one
      older than the timeout would be stale on arrival anyway;
    - 'wrong positions length', 'wrong velocities length', 'wrong accelerations length':
      a field not one value per joint, velocities and accelerations also empty (lines
      1796-1804, ``validate_trajectory_point_field``), and 'effort in a position command'
      (lines 1805-1812: effort only with an effort command interface).

    Not taken over: the controller's refusal of a non-zero velocity at the last point
    (lines 1718-1730, ``allow_nonzero_velocity_at_trajectory_end``), which is about its
    spline, not the sanity of the numbers; the drive here takes the last point only.

    Stricter than the controller, which passes the numbers to the hardware as they are: a
    negative ``time_from_start`` ('negative time_from_start': a point before the
    trajectory's start, which trajectory_msgs does not define), a non-finite position,
    velocity or acceleration ('non-finite ...'; a real drive, ABB EGM, refuses it), and a
    header stamp that :func:`read_stamp` refuses (malformed, or more than ``timeout_ns``
    after ``now_ns``). The joint range is the caller's (it knows the robot).

    Parameters
    ----------
    msg : trajectory_msgs.msg.JointTrajectory
        The command.
    now_ns : int
        The controller's time (ns).
    timeout_ns : int
        The command timeout (ns): how far a stamp may lead now, and the grace of a
        trajectory that ends in the past.
    names : sequence of str
        The controller's joints, the order of the columns returned.

    Returns
    -------
    numpy.ndarray
        (N, 6) positions, one row per point.

    """
    given = list(msg.joint_names)
    if len(given) != len(names) or set(given) != set(names):
        raise InputError('wrong joint names', f'{given}: each of {list(names)} once')
    if not msg.points:
        raise InputError('empty trajectory')
    start_ns = read_stamp(msg.header.stamp, now_ns, timeout_ns)
    times = [duration_ns(p.time_from_start) for p in msg.points]
    for k, t in enumerate(times):
        if t < 0:
            raise InputError('negative time_from_start', f'point {k}: {t} ns')
        if k and t <= times[k - 1]:
            raise InputError('times not increasing',
                             f'point {k} at {t} ns, point {k - 1} at {times[k - 1]} ns')
    if start_ns != 0 and start_ns + times[-1] < now_ns - timeout_ns:
        raise InputError('trajectory ends in the past',
                         f'at {start_ns + times[-1]} ns, now {now_ns} ns (grace '
                         f'{timeout_ns} ns)')
    for k, point in enumerate(msg.points):
        for field, may_be_empty in (('positions', False), ('velocities', True),
                                    ('accelerations', True)):
            values = np.asarray(getattr(point, field), dtype=float)
            if may_be_empty and values.size == 0:
                continue
            if values.shape != (len(names),):
                raise InputError(f'wrong {field} length',
                                 f'{values.size} in point {k}, expected {len(names)}')
            if not np.all(np.isfinite(values)):
                raise InputError(f'non-finite {field}', f'point {k}: {values.tolist()}')
        if len(point.effort):
            raise InputError('effort in a position command',
                             f'point {k}: {len(point.effort)} efforts')
    positions = np.array([p.positions for p in msg.points], dtype=float)
    return positions[:, [given.index(n) for n in names]]


def command_velocities(msg: JointTrajectory, names: Sequence[str] = contract.JOINT_NAMES
                       ) -> NDArray[np.float64] | None:
    """
    Return the (N, 6) velocities of a command :func:`read_command_trajectory` accepted.

    In ``names``' order; None unless every point carries its velocities (a point without
    them is interpolated from positions only: joint_trajectory_controller's
    ``interpolate_between_points`` takes a spline's velocity only where both ends have one).
    """
    if not msg.points or any(len(p.velocities) == 0 for p in msg.points):
        return None
    given = list(msg.joint_names)
    velocities = np.array([p.velocities for p in msg.points], dtype=float)
    return velocities[:, [given.index(n) for n in names]]


def joint_path(states: Sequence[JointState]) -> JointTrajectory:
    """
    Return a batch of joint states (in stamp order) as one trajectory_msgs/JointTrajectory.

    trajectory_msgs/JointTrajectory, not a Path or a list of JointStates: it is the standard
    message for a joint-space series, one JointTrajectoryPoint per state with the state's
    positions, velocities and effort as they are (the same float64s), at time_from_start =
    its stamp - header.stamp, the first state's stamp (the trajectory_msgs convention).
    The joint names are the first state's; :func:`read_joint_path` reads it back.
    """
    msg = JointTrajectory()
    msg.header.frame_id = contract.BASE_FRAME
    if not states:
        return msg
    msg.header.stamp = states[0].header.stamp
    msg.joint_names = list(states[0].name)
    start = stamp_ns(states[0].header.stamp)
    points = []
    for state in states:
        point = JointTrajectoryPoint(positions=state.position, velocities=state.velocity,
                                     effort=state.effort)
        point.time_from_start.sec, point.time_from_start.nanosec = divmod(
            stamp_ns(state.header.stamp) - start, NS_PER_S)
        points.append(point)
    msg.points = points
    return msg


def read_joint_path(msg: JointTrajectory, names: Sequence[str] = contract.JOINT_NAMES
                    ) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64],
                               NDArray[np.float64]]:
    """
    Return (stamps ns (N,), positions, velocities, efforts) of a :func:`joint_path` batch.

    Values by joint name in the order of ``names``, (N, 6) each; efforts (N, 0) when the
    batch has none (a position-controlled simulator models no torque). Works on rclpy and
    ``rosbags`` messages alike. Raises :class:`InputError` for other joint names or a
    point whose fields have another length.
    """
    if len(msg.joint_names) != len(names) or set(msg.joint_names) != set(names):
        raise InputError('wrong joint names', f'{list(msg.joint_names)}')
    order = [list(msg.joint_names).index(n) for n in names]
    start = stamp_ns(msg.header.stamp)
    stamps = np.array([start + duration_ns(p.time_from_start) for p in msg.points],
                      dtype=np.int64)
    out = [stamps]
    for field in ('positions', 'velocities', 'effort'):
        rows = [np.asarray(getattr(p, field), dtype=float) for p in msg.points]
        width = len(names) if field != 'effort' or any(len(r) for r in rows) else 0
        if any(r.shape != (width,) for r in rows):
            raise InputError(f'wrong {field} length', f'expected {width} in every point')
        values = np.array(rows, dtype=float).reshape(len(rows), width)
        out.append(values[:, order] if width else values)
    return tuple(out)
