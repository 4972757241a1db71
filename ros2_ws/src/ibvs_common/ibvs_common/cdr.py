"""
A JointTrajectory read from and written to its serialized bytes (CDR) as arrays.

rclpy turns every message it takes into Python objects in the executor's thread and holds
the interpreter while it does: for a JointTrajectory a point object, four arrays and a
Duration per point. A trajectory of thousands of points keeps every timer and callback of
the process waiting that long, and a callback group or thread of its own would not help,
as the conversion never lets another thread run. A subscription made with ``raw=True``
takes the serialized bytes instead (a copy), and :func:`trajectory_arrays` reads the points
from them with numpy, a few array operations whatever their number.

The encoding read: little-endian CDR version 1 (DDS-XTypes' XCDR1, encapsulation ``CDR_LE``
0x0001), which rmw_fastrtps_cpp sends for a ROS message on x86 and ARM: a 4-byte encapsulation
header, then the fields in order, a primitive aligned to its own size counted from the end
of the header, a string as a uint32 length (its NUL included) and its bytes, a sequence as
a uint32 count and its elements, an empty sequence of doubles without padding. Points all
of the same shape (the four arrays of each as long as those of the first) are read at
once (bytes after the last point are ignored, as rclpy ignores them: rmw_serialize's buffer
may be longer than the message); anything else (points of different lengths, another
encapsulation, bytes too few) gives None, and the caller reads the message as rclpy does.

Publishing costs the same in the other direction: a message object of thousands of points
takes rclpy as long to build as to read. :func:`trajectory_bytes` writes the bytes
``rclpy.serialization.serialize_message`` would (padding zero) from the arrays, and a
publisher sends bytes as they are (``Publisher.publish`` takes ``bytes``).
"""

from collections.abc import Sequence
from dataclasses import dataclass
import struct

from builtin_interfaces.msg import Time
import numpy as np
from numpy.typing import ArrayLike, NDArray

#: The encapsulation identifier read here (``CDR_LE``) and its byte order (numpy's).
ENCAPSULATIONS = {b'\x00\x01': '<'}
#: Bytes before the first field; alignment counts from there.
HEADER_BYTES = 4
#: A JointTrajectoryPoint's arrays of float64, in their order in the message.
POINT_ARRAYS = ('positions', 'velocities', 'accelerations', 'effort')


@dataclass(frozen=True)
class TrajectoryArrays:
    """
    What :func:`ibvs_common.conversions.read_trajectory` checks of a JointTrajectory.

    ``times_ns``: each point's ``time_from_start`` (ns); ``positions``: (N, k), or None when
    the points' positions differ in length; ``finite``: per other array of the points
    (:data:`POINT_ARRAYS` but positions), whether every value of every point is finite.
    """

    stamp: Time
    joint_names: list[str]
    times_ns: NDArray[np.int64]
    positions: NDArray[np.float64] | None
    finite: dict[str, bool]


class _Cursor:
    """A read position in CDR bytes: primitives aligned to their size (module docstring)."""

    def __init__(self, data: bytes, order: str) -> None:
        self.data, self.order, self.pos = data, order, HEADER_BYTES

    def align(self, size: int) -> None:
        self.pos += -(self.pos - HEADER_BYTES) % size

    def uint32(self) -> int:
        self.align(4)
        (value,) = struct.unpack_from(self.order + 'I', self.data, self.pos)
        self.pos += 4
        return value

    def int32(self) -> int:
        self.align(4)
        (value,) = struct.unpack_from(self.order + 'i', self.data, self.pos)
        self.pos += 4
        return value

    def string(self) -> str:
        length = self.uint32()
        raw = self.data[self.pos:self.pos + length]
        if length == 0 or len(raw) != length or raw[-1:] != b'\x00':
            raise ValueError('not a CDR string')
        self.pos += length
        return raw[:-1].decode('utf-8')


def _point_layout(start: int, lengths: tuple[int, ...]) -> tuple[list[tuple[int, int]], int]:
    """
    Return where a point starting at ``start`` keeps its arrays, and its size (bytes).

    One (count offset, data offset) per array of ``lengths`` values, relative to
    ``start``; the Duration's two uint32 follow the last array.
    """
    pos = start
    fields = []
    for length in lengths:
        pos += -(pos - HEADER_BYTES) % 4
        count_at = pos
        pos += 4
        if length:
            pos += -(pos - HEADER_BYTES) % 8
        fields.append((count_at - start, pos - start))
        pos += 8 * length
    pos += -(pos - HEADER_BYTES) % 4
    return fields, pos + 8 - start


def _point_starts(first: int, count: int, size_at) -> NDArray[np.int64]:
    """
    Return the byte offset of each of ``count`` points, the first at ``first``.

    A point's size depends only on where it starts modulo 8 (``size_at(start)``: the
    padding before its doubles), so from the second point on the sizes repeat every one or
    two points: a start 0 modulo 8 either stays there or alternates with 4.
    """
    starts = np.empty(count, dtype=np.int64)
    pos = first
    for k in range(min(count, 2)):
        starts[k] = pos
        pos += size_at(pos)
    if count > 2:
        second = int(starts[1])
        size_1 = size_at(second)
        size_2 = size_at(second + size_1)
        k = np.arange(count - 1, dtype=np.int64)
        starts[1:] = second + (k // 2) * (size_1 + size_2) + (k % 2) * size_1
    return starts


def _gather(buf: NDArray[np.uint8], offsets: NDArray[np.int64], dtype: str,
            width: int) -> NDArray:
    """Return ``width`` values of ``dtype`` read at each of ``offsets`` (one row each)."""
    size = np.dtype(dtype).itemsize
    index = offsets[:, None] + np.arange(width * size, dtype=np.int64)
    return np.ascontiguousarray(buf[index]).view(dtype).reshape(len(offsets), width)


def trajectory_arrays(data: bytes) -> TrajectoryArrays | None:
    """
    Return the arrays of a serialized JointTrajectory, or None where it is not read here.

    None: an encapsulation other than XCDR1's, points whose arrays differ in length from
    the first point's, or bytes that do not add up to such a message (module docstring).
    """
    order = ENCAPSULATIONS.get(bytes(data[:2]))
    if order is None:
        return None
    data = bytes(data)
    try:
        cursor = _Cursor(data, order)
        stamp = Time(sec=cursor.int32(), nanosec=cursor.uint32())
        cursor.string()  # header.frame_id
        names = [cursor.string() for _ in range(cursor.uint32())]
        count = cursor.uint32()
        if count == 0:
            return TrajectoryArrays(stamp, names, np.zeros(0, dtype=np.int64),
                                    np.zeros((0, 0)), dict.fromkeys(POINT_ARRAYS[1:], True))
        first = cursor.pos
        lengths = []
        for _ in POINT_ARRAYS:  # the first point's array lengths, the shape of all
            length = cursor.uint32()
            lengths.append(length)
            if length:
                cursor.align(8)
            cursor.pos += 8 * length
    except (struct.error, ValueError):
        return None
    lengths = tuple(lengths)
    layouts = {phase: _point_layout(HEADER_BYTES + phase, lengths) for phase in (0, 4)}

    def size_at(start):
        return layouts[(start - HEADER_BYTES) % 8][1]

    starts = _point_starts(first, count, size_at)
    end = int(starts[-1]) + size_at(int(starts[-1]))
    if end > len(data):  # the points do not fit the bytes as the first would
        return None
    buf = np.frombuffer(data, dtype=np.uint8)
    phase = (starts - HEADER_BYTES) % 8 == 4
    u32, f64 = order + 'u4', order + 'f8'
    arrays = {}
    for i, (name, length) in enumerate(zip(POINT_ARRAYS, lengths)):
        count_at = np.where(phase, layouts[4][0][i][0], layouts[0][0][i][0]) + starts
        if np.any(_gather(buf, count_at, u32, 1)[:, 0] != length):
            return None  # a point of another shape: not read here
        data_at = np.where(phase, layouts[4][0][i][1], layouts[0][0][i][1]) + starts
        arrays[name] = _gather(buf, data_at, f64, length).astype(np.float64)
    tail = np.where(phase, layouts[4][1], layouts[0][1]) + starts - 8
    sec = _gather(buf, tail, order + 'i4', 1)[:, 0].astype(np.int64)
    nanosec = _gather(buf, tail + 4, u32, 1)[:, 0].astype(np.int64)
    return TrajectoryArrays(
        stamp, names, sec * 1_000_000_000 + nanosec, arrays['positions'],
        {name: bool(np.all(np.isfinite(arrays[name]))) for name in POINT_ARRAYS[1:]})


def trajectory_bytes(stamp: Time, frame_id: str, joint_names: Sequence[str],
                     times_ns: ArrayLike, positions: ArrayLike,
                     velocities: ArrayLike | None = None,
                     accelerations: ArrayLike | None = None) -> bytes:
    """
    Return the XCDR1 little-endian bytes of a JointTrajectory of points of one shape.

    ``times_ns`` (N,): each point's ``time_from_start``; ``positions`` (N, k); the points'
    ``velocities`` and ``accelerations`` (N, k) when given, else empty, and ``effort``
    empty. The bytes are those rclpy serializes for the same message (module docstring),
    written with a few array operations whatever N.
    """
    times_ns = np.asarray(times_ns, dtype=np.int64)
    count = len(times_ns)
    head = bytearray(b'\x00\x01\x00\x00')

    def align(size):
        head.extend(bytes(-(len(head) - HEADER_BYTES) % size))

    def uint32(value):
        align(4)
        head.extend(struct.pack('<I', value))

    def string(text):
        raw = text.encode('utf-8') + b'\x00'
        uint32(len(raw))
        head.extend(raw)

    head.extend(struct.pack('<iI', stamp.sec, stamp.nanosec))
    string(frame_id)
    uint32(len(joint_names))
    for name in joint_names:
        string(name)
    uint32(count)
    if count == 0:
        return bytes(head)
    arrays = [np.asarray(positions, dtype=np.float64).reshape(count, -1)]
    for extra in (velocities, accelerations):
        arrays.append(np.zeros((count, 0)) if extra is None
                      else np.asarray(extra, dtype=np.float64).reshape(count, -1))
    arrays.append(np.zeros((count, 0)))  # effort
    lengths = tuple(a.shape[1] for a in arrays)
    layouts = {phase: _point_layout(HEADER_BYTES + phase, lengths) for phase in (0, 4)}

    def size_at(start):
        return layouts[(start - HEADER_BYTES) % 8][1]

    starts = _point_starts(len(head), count, size_at)
    buf = np.zeros(int(starts[-1]) + size_at(int(starts[-1])), dtype=np.uint8)
    buf[:len(head)] = np.frombuffer(bytes(head), dtype=np.uint8)
    phase = (starts - HEADER_BYTES) % 8 == 4
    for i, (values, length) in enumerate(zip(arrays, lengths)):
        count_at = np.where(phase, layouts[4][0][i][0], layouts[0][0][i][0]) + starts
        _scatter(buf, count_at, np.full((count, 1), length, dtype='<u4'))
        data_at = np.where(phase, layouts[4][0][i][1], layouts[0][0][i][1]) + starts
        _scatter(buf, data_at, values.astype('<f8'))
    tail = np.where(phase, layouts[4][1], layouts[0][1]) + starts - 8
    sec, nanosec = np.divmod(times_ns, 1_000_000_000)
    _scatter(buf, tail, sec.astype('<i4').reshape(-1, 1))
    _scatter(buf, tail + 4, nanosec.astype('<u4').reshape(-1, 1))
    return buf.tobytes()


def _scatter(buf: NDArray[np.uint8], offsets: NDArray[np.int64], values: NDArray) -> None:
    """Write each row of ``values`` at its offset in ``buf`` (the inverse of _gather)."""
    raw = np.ascontiguousarray(values).view(np.uint8).reshape(len(offsets), -1)
    if raw.shape[1]:
        buf[offsets[:, None] + np.arange(raw.shape[1], dtype=np.int64)] = raw
