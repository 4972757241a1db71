"""
Messages <-> numpy arrays and :mod:`ibvs_model` objects.

Readers raise :class:`InputError` with a short reason (used as the rejection reason on
/diagnostics) and never return NaN.
"""

from array import array as Array
from collections.abc import Iterable, Sequence
import math
from typing import NamedTuple, Optional, Tuple, TYPE_CHECKING, Union

from builtin_interfaces.msg import Duration, Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point32, PolygonStamped, Pose, PoseStamped, TransformStamped
from ibvs_model import IRB4600, StereoCamera, StereoIntrinsics
from nav_msgs.msg import Path
import numpy as np
from numpy.typing import ArrayLike, NDArray
from rclpy.serialization import deserialize_message
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from . import cdr, contract
from .sim_time import clock_problem
from .timing import is_frame_stamp, NS_PER_S, seconds_to_ns

if TYPE_CHECKING:
    from ibvs_model.robot import RobotParams

#: How far (rad) a start posture may lie outside its joint's travel (ibvs_model.IRB4600
#: q_min, q_max) and still be read (:func:`travel_bounds`).
POSITION_MARGIN_RAD = 0.1
#: Largest |position| (rad) of a joint state or trajectory point that is read
#: (:func:`position_bounds`). Not the travel: the paper's feedforward leads the arm and
#: overshoots it (scenarios 1-3: up to 44 rad on joint 1 in the first steps), and the ideal
#: actuators follow where no hard stop is modelled; a thousand radians is no reading.
POSITION_BOUND_RAD = 1000.0
#: Largest |velocity| (rad/s) of a joint that is read: about ten times the 1.2e3 rad/s the
#: paper's feedforward asks of the ideal actuators (a stand-in plant without PyBullet's
#: 100 rad/s cap follows it), far below what breaks the dynamics.
SPEED_BOUND_RAD_S = 1e4


class InputError(ValueError):
    """A message cannot be used; ``reason`` is a short key for the rejection counter."""

    def __init__(self, reason: str, detail: str = '') -> None:
        """Keep the short ``reason`` and a longer ``detail`` for the log."""
        super().__init__(f'{reason}: {detail}' if detail else reason)
        self.reason = reason
        self.detail = detail


def stamp_ns(stamp: Time) -> int:
    """Return a builtin_interfaces/Time as integer nanoseconds (exact)."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def read_stamp(stamp: Time, now_ns: Optional[int] = None, lead_ns: Optional[int] = None,
               frames: Optional[Tuple[int, int]] = None) -> int:
    """
    Return a header stamp as integer nanoseconds; :class:`InputError` if no node may use it.

    The one stamp rule of every node (docs/design.md §4). Refused:

    - malformed: a negative ``sec`` (before the sim starts at 0) or ``nanosec`` of a second
      or more, which :func:`stamp_ns` would silently carry into the seconds;
    - with ``lead_ns``, 'stamp in the future': more than ``lead_ns`` after ``now_ns``, the
      newest time the node knows (:func:`ibvs_common.sim_time.node_time_ns`; None: 0, the
      start of sim time). A node never stores such a stamp: one input from a bad publisher
      would otherwise make every later good one look stale, or hold a buffer for ever;
    - with ``frames`` = (camera_period_ns, step_ns), 'off the frame grid': not the stamp
      of a camera frame (:func:`ibvs_common.timing.is_frame_stamp`).

    Parameters
    ----------
    stamp : builtin_interfaces.msg.Time
        The stamp read.
    now_ns : int, optional
        The node's newest known time (ns).
    lead_ns : int, optional
        How far (ns) a stamp may lead ``now_ns``; None: no bound.
    frames : tuple of (int, int), optional
        The camera period and the physics step (ns) of a frame stamp.

    Returns
    -------
    int
        The stamp in nanoseconds.

    """
    problem = clock_problem(stamp.sec, stamp.nanosec)
    if problem is not None:
        raise InputError(*problem)
    t_ns = stamp_ns(stamp)
    now_ns = max(int(now_ns or 0), 0)
    if lead_ns is not None and t_ns > now_ns + lead_ns:
        raise InputError('stamp in the future',
                         f'{t_ns} ns, more than {lead_ns} ns after the newest time known, '
                         f'{now_ns} ns')
    if frames is not None and not is_frame_stamp(t_ns, *frames):
        raise InputError('off the frame grid',
                         f'{t_ns} ns is not the stamp of a frame (every {frames[0]} ns, '
                         f'at the physics step of {frames[1]} ns at or after it)')
    return t_ns


#: How far (ns) a node's clock may lag the stamps it reads, beyond one input period: the
#: period of a lockstep graph's /clock (``clock_rate_hz``, 10 Hz) or a real cell's clock
#: offset between hosts. A stamp that leads by more is refused ('stamp in the future') and
#: moves no order: taken, it would refuse every later input stamped before it.
STAMP_LEAD_MARGIN_NS = 100_000_000


def stamp_lead_ns(stale_timeout_s: float, input_period_ns: int) -> int:
    """
    Return how far (ns) an input's stamp may lead the newest time its node knows.

    One period of the input (the next input of a stream is one period after the last) and
    the clock's lag, :data:`STAMP_LEAD_MARGIN_NS`, or ``stale_timeout_s`` (the parameter
    that ages inputs out) where that is shorter: the ``lead_ns`` of :func:`read_stamp`.
    """
    return min(seconds_to_ns(stale_timeout_s), STAMP_LEAD_MARGIN_NS) + int(input_period_ns)


class StampOrder:
    """
    The newest stamp taken from each source; a stamp not after it is refused.

    A source (one publisher's stream, e.g. a topic) stamps its messages in order. A stamp
    equal to the newest taken is 'duplicate stamp' (the same message again, or a second
    publisher), one before it 'stamp went back' (a restarted or a foreign clock): both
    raise :class:`InputError`, so that the node counts and skips the message. Only a stamp
    the node :meth:`take` s moves the order on: a message refused for its values leaves its
    stamp free for a good one.
    """

    def __init__(self) -> None:
        """Start with no stamp taken from any source."""
        self._newest = {}

    def check(self, source: str, t_ns: int) -> None:
        """Raise :class:`InputError` unless ``t_ns`` is after the newest taken from ``source``."""
        newest = self._newest.get(source)
        if newest is None or t_ns > newest:
            return
        if t_ns == newest:
            raise InputError('duplicate stamp', f'{t_ns} ns again')
        raise InputError('stamp went back', f'{t_ns} ns after {newest} ns')

    def take(self, source: str, t_ns: int) -> None:
        """Note that the message stamped ``t_ns`` from ``source`` was used."""
        self._newest[source] = int(t_ns)

    def newest(self, source: str) -> Optional[int]:
        """Return the newest stamp taken from ``source`` (ns), or None."""
        return self._newest.get(source)

    def forget(self) -> None:
        """Forget every stamp taken (the clock jumped back: a new time line starts)."""
        self._newest.clear()


def ns_stamp(ns: int) -> Time:
    """Return integer nanoseconds as builtin_interfaces/Time."""
    ns = int(ns)
    return Time(sec=ns // NS_PER_S, nanosec=ns % NS_PER_S)


def joint_state(stamp: int | Time, position: ArrayLike | None = None,
                velocity: ArrayLike | None = None, effort: ArrayLike | None = None,
                names: Iterable[str] = contract.JOINT_NAMES) -> JointState:
    """Build a JointState with the contract's joint names."""
    msg = JointState()
    msg.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
    msg.header.frame_id = contract.BASE_FRAME
    msg.name = list(names)
    if position is not None:
        msg.position = [float(v) for v in position]
    if velocity is not None:
        msg.velocity = [float(v) for v in velocity]
    if effort is not None:
        msg.effort = [float(v) for v in effort]
    return msg


#: Most distinct (JointState.name, names) pairs whose mapping :func:`joint_order` keeps: a
#: cell publishes one or two name lists; a publisher of ever new names (a fuzzer) does not
#: grow the cache beyond this.
JOINT_ORDER_CACHE = 64
_JOINT_ORDERS: dict = {}


def joint_order(given: Sequence[str], names: Sequence[str] = contract.JOINT_NAMES
                ) -> tuple[NDArray[np.int_] | None, tuple[str, ...]]:
    """
    Return (where each of ``names`` is in ``given``, the names of ``given`` that are ignored).

    joint_state_broadcaster publishes every joint of every hardware of the
    controller_manager (an arm's track, a gripper), in its own order. The arm's joints
    ``names`` are taken by name, in any order; the others are ignored and returned (in the
    order given) so that a node can say once which it ignores. The index array is None
    when ``given`` is ``names`` as it is (no reordering needed). Raises
    :class:`InputError`: 'no joint names' (``given`` empty: values are mapped by name),
    'wrong joint names' (a name given twice) or 'missing joints' (one of ``names`` not
    given).
    """
    key = (tuple(given), tuple(names))
    found = _JOINT_ORDERS.get(key)
    if found is not None:
        return found
    given, names = key
    if not given:
        raise InputError('no joint names', 'JointState.name is empty; values are mapped by name')
    if len(set(given)) != len(given):
        raise InputError('wrong joint names', f'{list(given)}: a name given twice')
    missing = [n for n in names if n not in given]
    if missing:
        raise InputError('missing joints', f'{missing} not in {list(given)}')
    order = None if given == names else np.array([given.index(n) for n in names])
    found = (order, tuple(n for n in given if n not in names))
    if len(_JOINT_ORDERS) >= JOINT_ORDER_CACHE:
        _JOINT_ORDERS.clear()
    _JOINT_ORDERS[key] = found
    return found


def ignored_joints(msg: JointState, names: Sequence[str] = contract.JOINT_NAMES
                   ) -> tuple[str, ...]:
    """Return the joints of ``msg`` that are not ``names`` (ignored); () if it cannot be read."""
    try:
        return joint_order(msg.name, names)[1]
    except InputError:
        return ()


#: The per-joint fields of a JointState.
JOINT_FIELDS = ('position', 'velocity', 'effort')


def read_joints(msg: JointState, field: str = 'position',
                names: Sequence[str] = contract.JOINT_NAMES,
                bound: tuple[ArrayLike, ArrayLike] | None = None) -> NDArray[np.float64]:
    """
    Return ``msg.<field>`` of the joints ``names``, a (6,) array in their order.

    Values are mapped by joint name (:func:`joint_order`): the message must name each of
    ``names`` once, in any order, and may name other joints too (a track, a gripper: what
    joint_state_broadcaster publishes), whose values are ignored, not checked. Raises
    :class:`InputError` for the names :func:`joint_order` refuses, a field whose length is
    not the number of names given, a non-finite value of one of ``names`` (in ``field``, or
    in another of :data:`JOINT_FIELDS`, which may be empty: a NaN there is a broken
    publisher, and the whole message is refused rather than half used) or, with
    ``bound`` = (low, high) (arrays in the order of ``names``), a value outside [low, high]
    ('out of range': :func:`position_bounds`, :func:`velocity_bounds`).
    """
    order, _ = joint_order(msg.name, names)
    values = np.asarray(getattr(msg, field), dtype=float)
    if values.shape != (len(msg.name),):
        raise InputError(f'wrong {field} length',
                         f'{values.size} values for {len(msg.name)} joint names')
    if order is not None:
        values = values[order]
    if not np.isfinite(values).all():
        raise InputError(f'non-finite {field}', f'{values.tolist()}')
    for other in JOINT_FIELDS:
        if other == field:
            continue
        extra = np.asarray(getattr(msg, other), dtype=float)
        if extra.shape == (len(msg.name),) and order is not None:
            extra = extra[order]
        if not np.isfinite(extra).all():
            raise InputError(f'non-finite {other}', f'{extra.tolist()}')
    if bound is not None and not ((values >= bound[0]) & (values <= bound[1])).all():
        raise InputError(f'{field} out of range',
                         f'{values.tolist()}, allowed {np.round(bound[0], 3).tolist()} to '
                         f'{np.round(bound[1], 3).tolist()}')
    return values


def travel_bounds(params: 'RobotParams' = IRB4600
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return (low, high) of a posture the arm can start from: the travel, with a margin."""
    return (np.asarray(params.q_min, dtype=float) - POSITION_MARGIN_RAD,
            np.asarray(params.q_max, dtype=float) + POSITION_MARGIN_RAD)


def _symmetric_bounds(limit):
    """Return read-only (low, high) arrays of +-``limit`` for the six joints."""
    high = np.full(len(contract.JOINT_NAMES), float(limit))
    low = -high
    low.flags.writeable = high.flags.writeable = False
    return low, high


# Built once: the joint controller reads both bounds on every /joint_states (1 kHz).
_POSITION_BOUNDS = _symmetric_bounds(POSITION_BOUND_RAD)
_VELOCITY_BOUNDS = _symmetric_bounds(SPEED_BOUND_RAD_S)


def position_bounds() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return (low, high) of a joint position that is read: +-POSITION_BOUND_RAD."""
    return _POSITION_BOUNDS


def velocity_bounds() -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return (low, high) of a joint velocity that can be meant: +-SPEED_BOUND_RAD_S."""
    return _VELOCITY_BOUNDS


def check_finite(msg: JointState, fields: Iterable[str]) -> None:
    """
    Raise :class:`InputError` if a JointState field in ``fields`` holds a non-finite value.

    For the fields a consumer does not read (e.g. velocity and effort of a position
    reference): they may be empty, but a NaN or inf there means a broken publisher, and the
    whole message is rejected rather than half used.
    """
    for field in fields:
        values = np.asarray(getattr(msg, field), dtype=float)
        if not np.all(np.isfinite(values)):
            raise InputError(f'non-finite {field}', f'{values.tolist()}')


def duration_ns(duration: Duration) -> int:
    """Return a builtin_interfaces/Duration as integer nanoseconds (exact)."""
    return int(duration.sec) * NS_PER_S + int(duration.nanosec)


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


def pose_matrix(pose: Pose) -> NDArray[np.float64]:
    """Return a geometry_msgs/Pose as a 4x4 homogeneous transform."""
    q = pose.orientation
    quat = np.array([q.x, q.y, q.z, q.w], dtype=float)
    pos = np.array([pose.position.x, pose.position.y, pose.position.z], dtype=float)
    if not (np.all(np.isfinite(quat)) and np.all(np.isfinite(pos))):
        raise InputError('non-finite pose')
    norm = np.linalg.norm(quat)
    if abs(norm - 1.0) > 1e-3:
        raise InputError('quaternion not normalised', f'|q| = {norm:.6f}')
    tf = np.eye(4)
    tf[:3, :3] = Rotation.from_quat(quat / norm).as_matrix()
    tf[:3, 3] = pos
    return tf


def matrix_poses(tfs: ArrayLike) -> list[Pose]:
    """Return 4x4 homogeneous transforms (N, 4, 4) as geometry_msgs/Pose, one quaternion call."""
    tfs = np.asarray(tfs, dtype=float).reshape(-1, 4, 4)
    quats = Rotation.from_matrix(tfs[:, :3, :3]).as_quat()
    poses = []
    for tf, (x, y, z, w) in zip(tfs, quats):
        pose = Pose()
        pose.position.x, pose.position.y, pose.position.z = (float(v) for v in tf[:3, 3])
        pose.orientation.x, pose.orientation.y = float(x), float(y)
        pose.orientation.z, pose.orientation.w = float(z), float(w)
        poses.append(pose)
    return poses


def transforms_msg(triples: Sequence[tuple[str, str, ArrayLike]], stamp: Time) -> TFMessage:
    """
    Return (parent, child, 4x4 T_child^parent) triples as one tf2_msgs/TFMessage.

    Every transform stamped ``stamp``, as tf2_ros's TransformBroadcaster sends a batch
    (robot_state_node's links, viz_node's frames).
    """
    msg = TFMessage()
    for (parent, child, _), pose in zip(triples, matrix_poses([tf for *_, tf in triples])):
        t = TransformStamped()
        t.header.stamp = stamp
        t.header.frame_id = parent
        t.child_frame_id = child
        t.transform.translation.x = pose.position.x
        t.transform.translation.y = pose.position.y
        t.transform.translation.z = pose.position.z
        t.transform.rotation = pose.orientation
        msg.transforms.append(t)
    return msg


def matrix_pose(tf: ArrayLike) -> Pose:
    """Return a 4x4 homogeneous transform as a geometry_msgs/Pose."""
    return matrix_poses(tf)[0]


def pose_stamped(tf: ArrayLike, stamp: int | Time,
                 frame_id: str = contract.BASE_FRAME) -> PoseStamped:
    """Return a 4x4 transform as PoseStamped in ``frame_id``."""
    msg = PoseStamped()
    msg.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
    msg.header.frame_id = frame_id
    msg.pose = matrix_pose(tf)
    return msg


def path_msg(stamped_poses: Sequence[tuple[int, ArrayLike]],
             frame_id: str = contract.BASE_FRAME) -> Path:
    """Return (stamp ns, 4x4 transform) pairs as a nav_msgs/Path stamped with the last one."""
    msg = Path()
    msg.header.frame_id = frame_id
    stamps = [t_ns for t_ns, _ in stamped_poses]
    poses = matrix_poses([tf for _, tf in stamped_poses]) if stamps else []
    msg.poses = [PoseStamped(header=Header(stamp=ns_stamp(t_ns), frame_id=frame_id), pose=pose)
                 for t_ns, pose in zip(stamps, poses)]
    if msg.poses:
        msg.header.stamp = msg.poses[-1].header.stamp
    return msg


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


def image_msg(array: ArrayLike, stamp: int | Time, encoding: str = 'rgb8',
              frame_id: str = '') -> Image:
    """
    Return an (H, W, 3) uint8 array as a sensor_msgs/Image of ``encoding``.

    ``encoding`` rgb8 or bgr8: the array's channels as they are, in that order; bgra8
    (zed-ros2-wrapper's): the array is taken as RGB, reordered to BGR and given an opaque
    alpha channel.
    """
    array = np.ascontiguousarray(array, dtype=np.uint8)
    if array.ndim != 3 or array.shape[2] != 3:
        raise ValueError('array must be (H, W, 3)')
    if encoding == 'bgra8':
        import cv2  # here: of all the messages, only the ZED wrapper's encoding needs it
        # 0.12 ms an HD720 image, where numpy's reversed view and concatenation take 3.3
        array = cv2.cvtColor(array, cv2.COLOR_RGB2BGRA)
    msg = Image()
    msg.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
    msg.header.frame_id = frame_id
    msg.height, msg.width = int(array.shape[0]), int(array.shape[1])
    msg.encoding = encoding
    msg.is_bigendian = 0
    msg.step = array.shape[2] * msg.width
    data = Array('B')
    data.frombytes(array)
    # The one copy of the pixels: the generated setter copies even an array('B') (its
    # fast path is under ROS_PYTHON_CHECK_FIELDS only), 1.5 ms of a 2.7 MB HD720 image.
    msg._data = data
    return msg


def camera_infos(intrinsics: StereoIntrinsics, stamp: int | Time,
                 frames: tuple[str, str] = (contract.LEFT_CAMERA_FRAME,
                                            contract.RIGHT_CAMERA_FRAME)
                 ) -> tuple[CameraInfo, CameraInfo]:
    """
    Return (left, right) CameraInfo of a rectified stereo pair (ROS conventions).

    Each has K = [[f_u, 0, c_u], [0, f_v, c_v], [0, 0, 1]] of its lens (the right's f_u',
    c_u' where they differ: :class:`ibvs_model.StereoIntrinsics`), no distortion, and
    P = [K | t] with t = 0 on the left and t = (-f_u' b, 0, 0) on the right (as
    zed-ros2-wrapper fills it); ``frames`` are their frame ids.
    """
    k = intrinsics
    infos = []
    for frame, tx, fu, cu in zip(frames, (0.0, -k.fu_r * k.baseline), (k.fu, k.fu_r),
                                 (k.cu, k.cu_r)):
        info = CameraInfo()
        info.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
        info.header.frame_id = frame
        info.width, info.height = int(k.width), int(k.height)
        info.distortion_model = 'plumb_bob'
        info.d = [0.0] * 5
        info.k = [fu, 0.0, cu, 0.0, k.fv, k.cv, 0.0, 0.0, 1.0]
        info.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        info.p = [fu, 0.0, cu, tx, 0.0, k.fv, k.cv, 0.0, 0.0, 0.0, 1.0, 0.0]
        infos.append(info)
    return tuple(infos)


#: Largest image side (px) a CameraInfo may give: above any stereo camera's (ZED 2: 2208),
#: far below sizes whose images could not be held in memory.
MAX_IMAGE_SIDE_PX = 8192
#: Narrowest and widest field of view (deg, each axis) of a rectified pinhole lens that is
#: read: 1 deg is a long telephoto lens, 170 deg more than a rectified fisheye keeps (a
#: pinhole image cannot reach 180); a ZED 2 has 86 x 55 deg (``ibvs_model.camera``).
#: f = (side / 2) / tan(fov / 2) (Appendix): f_u within 0.044 to 57 times the width, f_v
#: the height (ZED 2 at HD720: 686 px over 1280). No overflow is left: f at most
#: 57.3 * 8192 = 4.7e5 px.
FOV_RANGE_DEG = (1.0, 170.0)
#: Shortest and longest stereo baseline b (m) that is read, b = -P[3] / P[0] of the right
#: lens: a ZED 2 has 0.12 m, a ZED Mini 0.063, the smallest stereo modules about 0.02 and
#: wide rigs a metre or two; 5 mm to 5 m holds all of them with margin.
BASELINE_RANGE_M = (0.005, 5.0)
#: Largest difference (px) between the rows of the left and right lens of a pair that is
#: read as rectified, over the whole image: |c_v - c_v'| + |f_v - f_v'| / f_v * height / 2
#: (a row offset plus a vertical scale, at the image's top or bottom edge). The model has
#: one v per marker for both images (eq. 22) and the detector pairs markers within
#: ``epipolar_tolerance_px`` = 1.5 px of each other's row (ibvs_vision.detector.config) and
#: takes their mean: half a pixel uses a third of that tolerance and biases v by at most
#: 0.25 px against either image. A pair beyond it is not rectified: refused.
ROW_TOLERANCE_PX = 0.5


#: Largest share of f_u that P's skew and vertical-baseline entries may have, and largest
#: difference of its third row from 0 0 1 0: rounding only (a rectified pinhole has 0).
PINHOLE_TOLERANCE = 1e-9
#: Largest difference between the c_u of the left and the right lens, as a share of the
#: width: a rectification that does not align the principal points (OpenCV's stereoRectify
#: without CALIB_ZERO_DISPARITY) moves them by a few per cent; a ZED 2 differs by 4.6 px
#: at HD720 (0.4 %). Beyond it the disparity, hence the depth, is the pair's offset.
CU_TOLERANCE = 0.05


def focal_range_px(side_px: int) -> tuple[float, float]:
    """Return (low, high) of a focal length (px) along an image side of ``side_px``."""
    narrow, wide = FOV_RANGE_DEG
    return ((side_px / 2.0) / math.tan(math.radians(wide) / 2.0),
            (side_px / 2.0) / math.tan(math.radians(narrow) / 2.0))


def check_camera_info(info: CameraInfo) -> None:
    """
    Raise :class:`InputError` unless one CameraInfo can be a lens of the stereo camera.

    Read from the projection matrix P of a rectified lens ([f_u 0 c_u -f_u b; 0 f_v c_v 0;
    0 0 1 0], the ROS convention that zed-ros2-wrapper follows), each refused with its
    reason:

    - 'bad camera_info size': a side outside 1 to :data:`MAX_IMAGE_SIDE_PX` px;
    - 'bad camera_info': P not 12 finite values;
    - 'focal length out of range': f_u or f_v outside :func:`focal_range_px` of its side
      (a field of view outside :data:`FOV_RANGE_DEG`; f_u <= 0 included);
    - 'camera_info not a rectified pinhole': a skew P[1], P[4], a vertical baseline P[7]
      or a third row other than 0 0 1 0 (beyond :data:`PINHOLE_TOLERANCE`), which the
      model, reading f_u, f_v, c_u, c_v and P[3] only, would ignore;
    - 'principal point off the image': c_u outside [0, width] or c_v outside [0, height];
    - 'baseline out of range': |P[3] / P[0]| beyond the longest of
      :data:`BASELINE_RANGE_M` (0 on the left lens; the right's range is checked by
      :func:`intrinsics_from_infos`, which knows which lens it is).

    So a finite but absurd camera (f_u = 1e308, P[3] = -1e300) never reaches
    :mod:`ibvs_model.camera`, where it would overflow to inf.
    """
    if not (0 < info.width <= MAX_IMAGE_SIDE_PX and 0 < info.height <= MAX_IMAGE_SIDE_PX):
        raise InputError('bad camera_info size',
                         f'{info.width} x {info.height}, each side 1 to {MAX_IMAGE_SIDE_PX}')
    p = np.asarray(info.p, dtype=float)
    if p.shape != (12,) or not np.all(np.isfinite(p)):
        raise InputError('bad camera_info', 'P must have 12 finite values')
    for name, f, side in (('f_u', p[0], info.width), ('f_v', p[5], info.height)):
        low, high = focal_range_px(side)
        if not low <= f <= high:
            raise InputError('focal length out of range',
                             f'{name} = {f:.6g} px, {low:.4g} to {high:.4g} px for a side of '
                             f'{side} px (a field of view of {FOV_RANGE_DEG[0]:g} to '
                             f'{FOV_RANGE_DEG[1]:g} deg)')
    skew = (p[1], p[4], p[7], p[8], p[9], p[11])
    if max(map(abs, skew)) > PINHOLE_TOLERANCE * p[0] or abs(p[10] - 1.0) > PINHOLE_TOLERANCE:
        raise InputError('camera_info not a rectified pinhole',
                         f'P = {p.tolist()}: P[1], P[4], P[7] (skew, vertical baseline) '
                         'must be 0 and the third row 0 0 1 0')
    if not (0.0 <= p[2] <= info.width and 0.0 <= p[6] <= info.height):
        raise InputError('principal point off the image',
                         f'({p[2]:.6g}, {p[6]:.6g}) px in a {info.width} x {info.height} '
                         f'image')
    if abs(p[3] / p[0]) > BASELINE_RANGE_M[1]:
        raise InputError('baseline out of range',
                         f'P[3] / P[0] = {p[3] / p[0]:.6g} m, at most '
                         f'{BASELINE_RANGE_M[1]:g} m')


def intrinsics_from_infos(left: CameraInfo, right: CameraInfo) -> StereoIntrinsics:
    """
    Return :class:`StereoIntrinsics` from the left and right CameraInfo.

    Each is checked by :func:`check_camera_info`. The baseline comes from the right
    projection matrix, b = -P[3] / f_u' (its own f_u': the ROS convention, T_x = -f_x' B),
    and must lie within :data:`BASELINE_RANGE_M` ('baseline out of range'; a right
    P[3] >= 0 is no right lens); the left lens is the reference, its P[3] = 0 ('left lens
    with a baseline': e.g. a right CameraInfo on the left topic). Each lens keeps its own
    f_u and c_u (older ZED SDKs: 701.40 and 696.83 px); raises :class:`InputError` when the
    two disagree on size ('camera_info size mismatch') or their rows are not those of a
    rectified pair, f_v and c_v beyond :data:`ROW_TOLERANCE_PX`, or their c_u differ by
    more than :data:`CU_TOLERANCE` of the width ('camera_info not rectified').
    """
    check_camera_info(left)
    check_camera_info(right)
    pl = np.asarray(left.p, dtype=float)
    pr = np.asarray(right.p, dtype=float)
    if (left.width, left.height) != (right.width, right.height):
        raise InputError('camera_info size mismatch',
                         f'{left.width}x{left.height} vs {right.width}x{right.height}')
    rows = abs(pl[6] - pr[6]) + abs(pl[5] - pr[5]) / pl[5] * left.height / 2.0
    if not rows <= ROW_TOLERANCE_PX:
        raise InputError('camera_info not rectified',
                         f'rows differ by up to {rows:.3g} px (f_v {pl[5]:.6g} and '
                         f'{pr[5]:.6g}, c_v {pl[6]:.6g} and {pr[6]:.6g} px), at most '
                         f'{ROW_TOLERANCE_PX:g}')
    if not abs(pl[2] - pr[2]) <= CU_TOLERANCE * left.width:
        raise InputError('camera_info not rectified',
                         f'c_u {pl[2]:.6g} and {pr[2]:.6g} px differ by more than '
                         f'{CU_TOLERANCE:.0%} of the width ({CU_TOLERANCE * left.width:g} px)')
    if pl[3] != 0.0:
        raise InputError('left lens with a baseline', f'left P[3] = {pl[3]:.6g}, must be 0')
    baseline = float(-pr[3] / pr[0])
    if not BASELINE_RANGE_M[0] <= baseline <= BASELINE_RANGE_M[1]:
        raise InputError('baseline out of range',
                         f'right P[3] = {pr[3]:.6g} gives b = {baseline:.6g} m, '
                         f'{BASELINE_RANGE_M[0]:g} to {BASELINE_RANGE_M[1]:g} m')
    try:
        same = pl[0] == pr[0] and pl[2] == pr[2]
        return StereoIntrinsics(int(left.width), int(left.height), float(pl[0]), float(pl[5]),
                                float(pl[2]), float(pl[6]), baseline,
                                right_fu=None if same else float(pr[0]),
                                right_cu=None if same else float(pr[2]))
    except ValueError as exc:
        raise InputError('bad camera_info', str(exc)) from None


#: Farthest a camera may be from the robot base (m) and still see its markers (the
#: simulator's camera_eye lies within 20 m of it in each axis).
MAX_CAMERA_DISTANCE_M = 100.0


def read_camera_pose(pose_msg: PoseStamped | Pose) -> NDArray[np.float64]:
    """
    Return /stereo/pose (PoseStamped or Pose) as T_C^O; :class:`InputError` if unusable.

    Besides :func:`pose_matrix`'s checks, the camera must be within
    :data:`MAX_CAMERA_DISTANCE_M` of the robot base and look towards the robot: the base
    origin of {O} in front of it (positive depth). A pose looking away is a wrong
    calibration; nothing could be servoed on.
    """
    pose = pose_msg.pose if hasattr(pose_msg, 'pose') else pose_msg
    tf = pose_matrix(pose)
    x, y, z = tf[:3, 3]
    distance = float(np.hypot(np.hypot(x, y), z))  # no overflow warning for 1e308
    if distance > MAX_CAMERA_DISTANCE_M:
        raise InputError('camera too far from the robot',
                         f'{distance:.3g} m from the base, at most {MAX_CAMERA_DISTANCE_M:g}')
    depth = float(tf[:3, 2] @ -tf[:3, 3])  # z_C of the point O = 0
    if depth <= 0.0:
        raise InputError('camera looks away from the robot',
                         f'the robot base is {depth:.3f} m deep in the camera frame')
    return tf


def camera_from_msgs(left_info: CameraInfo, right_info: CameraInfo,
                     pose_msg: PoseStamped | Pose) -> StereoCamera:
    """Return the :class:`StereoCamera` described by both CameraInfo and /stereo/pose."""
    return StereoCamera(intrinsics_from_infos(left_info, right_info),
                        read_camera_pose(pose_msg))


def features_msg(features: ArrayLike, stamp: int | Time,
                 frame_id: str = contract.CAMERA_FRAME) -> PolygonStamped:
    """
    Return p_I (6,) as PolygonStamped: one point per marker, x = u_l, y = u_r, z = v.

    The values are rounded to float32 here, as Point32 carries them: the message holds what
    DDS delivers, also to a reader that gets the object itself (:mod:`.intra_process`).
    """
    p = np.asarray(features, dtype=float).reshape(2, 3).astype(np.float32)
    msg = PolygonStamped()
    msg.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
    msg.header.frame_id = frame_id
    msg.polygon.points = [Point32(x=float(r[0]), y=float(r[1]), z=float(r[2])) for r in p]
    return msg


def read_features(msg: PolygonStamped) -> NDArray[np.float64]:
    """
    Return p_I (6,) from a PolygonStamped; :class:`InputError` if not 2 finite points.

    Point32 holds float32: features travel with about 1e-4 px resolution at HD720.
    """
    points = msg.polygon.points
    if len(points) != 2:
        raise InputError('wrong feature count', f'{len(points)} points, expected 2')
    values = np.array([[p.x, p.y, p.z] for p in points], dtype=float).reshape(6)
    if not np.all(np.isfinite(values)):
        raise InputError('non-finite features', f'{values.tolist()}')
    return values


#: How far (px) a measured feature may lie outside its image: the detector measures
#: markers inside the image, with sub-pixel centres that may reach half a pixel past its
#: edge; one pixel is the margin of the check.
IMAGE_MARGIN_PX = 1.0


def check_features_in_image(features: ArrayLike, intrinsics: StereoIntrinsics,
                            margin_px: float = IMAGE_MARGIN_PX) -> None:
    """
    Raise :class:`InputError` ('features off the image') unless p_I lies in the image.

    ``features`` (6,) as :func:`read_features` returns them (u_l, u_r, v of each marker);
    each u within [-margin, width + margin], each v within [-margin, height + margin]. For
    measured features only: an estimate F(q_T) may lie anywhere.
    """
    p = np.asarray(features, dtype=float).reshape(2, 3)
    u, v = p[:, :2], p[:, 2]
    k = intrinsics
    if (np.any(u < -margin_px) or np.any(u > k.width + margin_px)
            or np.any(v < -margin_px) or np.any(v > k.height + margin_px)):
        raise InputError('features off the image',
                         f'{p.reshape(6).tolist()} px, image {k.width} x {k.height} '
                         f'(margin {margin_px:g} px)')


class FeatureStatus(NamedTuple):
    """
    What the feature node published for one stereo frame (/ibvs/feature_status).

    The fields are the contract's :data:`ibvs_common.contract.FEATURE_STATUS_KEYS`.

    Attributes
    ----------
    mode : str
        One of :data:`ibvs_common.contract.FEATURE_MODES`: what was published.
    source : str
        What the output follows: measured or estimated.
    reason : str
        :data:`ibvs_common.contract.FEATURE_MEASURED` when the detector found both markers
        in both images, else why not.
    blend_weight : float
        Share of the switch offset still blended (0 to 1).
    search : str
        How the detector searched ('roi' or 'full').

    """

    mode: str
    source: str
    reason: str
    blend_weight: float
    search: str

    @property
    def measured(self) -> bool:
        """Return whether the detector measured the frame (eq. 2-3), blended or not."""
        return self.reason == contract.FEATURE_MEASURED


def feature_status_msg(status: FeatureStatus, stamp: Union[int, Time], name: str = '',
                       hardware_id: str = '',
                       frame_id: str = contract.CAMERA_FRAME) -> DiagnosticArray:
    """
    Return ``status`` as the /ibvs/feature_status of the frame stamped ``stamp``.

    One DiagnosticStatus (level OK, message the mode) whose values are the contract's
    keys in their order; the blend weight is written with 6 significant digits.

    Parameters
    ----------
    status : FeatureStatus
        What was published for the frame.
    stamp : int or builtin_interfaces.msg.Time
        The frame's stamp (ns, or as a message).
    name, hardware_id : str
        The DiagnosticStatus's name and hardware id (the publishing node's).
    frame_id : str
        The header's frame.

    Returns
    -------
    diagnostic_msgs.msg.DiagnosticArray
        The message.

    """
    msg = DiagnosticArray()
    msg.header.stamp = stamp if isinstance(stamp, Time) else ns_stamp(stamp)
    msg.header.frame_id = frame_id
    text = status._replace(blend_weight=f'{status.blend_weight:.6g}')
    msg.status = [DiagnosticStatus(
        level=DiagnosticStatus.OK, name=name, message=str(status.mode), hardware_id=hardware_id,
        values=[KeyValue(key=k, value=str(getattr(text, k)))
                for k in contract.FEATURE_STATUS_KEYS])]
    return msg


def read_feature_status(msg: DiagnosticArray) -> FeatureStatus:
    """
    Return the :class:`FeatureStatus` of a /ibvs/feature_status; :class:`InputError` if bad.

    Reads the first DiagnosticStatus. Refused: no status ('no status'), a key of the
    contract missing, a mode not in :data:`ibvs_common.contract.FEATURE_MODES` or a blend
    weight that is not a finite number ('malformed feature status').
    """
    if not msg.status:
        raise InputError('no status')
    values = {kv.key: kv.value for kv in msg.status[0].values}
    missing = [k for k in contract.FEATURE_STATUS_KEYS if k not in values]
    if missing:
        raise InputError('malformed feature status', f'no {", ".join(missing)}')
    if values['mode'] not in contract.FEATURE_MODES:
        raise InputError('malformed feature status', f"mode {values['mode']!r}")
    try:
        weight = float(values['blend_weight'])
    except ValueError:
        weight = math.nan
    if not math.isfinite(weight):
        raise InputError('malformed feature status',
                         f"blend_weight {values['blend_weight']!r}")
    return FeatureStatus(values['mode'], values['source'], values['reason'], weight,
                         values['search'])
