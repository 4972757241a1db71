"""
Recorder: the graph's topics into a rosbag2 MCAP bag; images and per-step ones on request.

Written with ``rosbags`` (rosbag2 format version 9, MCAP storage, message definitions from
the ROS 2 Jazzy type store), so ``ros2 bag info``, Foxglove and PlotJuggler open it: the
file is ``<bag>/<bag>.mcap`` (``bag/bag.mcap`` in a run's directory). Messages are received
serialized (``raw=True``) and written as they are: no deserialisation on the hot path. The
topics of the contract are subscribed before the simulator starts, so nothing of the run's
beginning is lost; any other topic that appears is picked up by discovery, as
``ros2 bag record --all`` does.

The lockstep's per-step messages, /joint_states and /joint_effort_commands, are not
recorded unless asked (``include_per_step``): the simulator publishes the same states, with
the torque each step applied, in batches on /ibvs/joint_path, ten a second, which the
recorder records instead. A subscriber in this process would have the simulator and the
joint controller send each of their 1000 messages a second out of their process, where the
lockstep needs none (docs/speed.md); the analysis reads either
(:func:`ibvs_analysis.analysis.load_joints`).

What ``ros2 bag play`` needs beyond the messages, as ``ros2 bag record`` writes it: each
topic's ``offered_qos_profiles`` (the QoS of its publishers, read when its first message
comes, so that /stereo/pose and the feedforward trajectory are replayed transient local),
its type hash (RIHS01, in metadata.yaml and on the MCAP channel as ``topic_type_hash``) and
``ros_distro: jazzy`` (:class:`JazzyWriter`). A topic is added to the bag with its first
message: one that never had a message is not in it.

A recorder that dies before :meth:`Recorder.close` (its runner killed with SIGKILL) leaves
a bag that ``rosbags`` (``AnyReader``, ``Reader``) opens as it is. The MCAP file holds every
message up to the last /clock (each /clock closes a chunk, :meth:`_JazzyMcapStorage.flush`;
on the wall clock, a real cell's, every :data:`WALL_FLUSH_S`) and ends after each chunk as
a file without summary does (:data:`OPEN_END`; the next chunk is written over it, in one
write). ``metadata.yaml`` is written when the bag opens, with the run's custom data and
:data:`IN_PROGRESS_KEY`, and again, atomically, at each flush that put a new topic's channel
on disk (a few a run: the topics come in the first tenths of a second): a reader of the bag
sees every topic the file holds, with every message of it. Its counts and times are those
of the last new topic's flush; :func:`recover` (called by ``ibvs analyse`` and every
analysis of a run) writes the exact ones, and ends an MCAP file cut inside a record after
its last whole one.
"""

from collections.abc import Mapping
from functools import partial
import importlib
from io import BytesIO, StringIO
import os
from pathlib import Path
import time
from typing import Any

from ibvs_common import contract
from ibvs_common.profiling import Stopwatch
from ibvs_common.sim_time import clock_problem
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness,
                                QosReliability, QosTime)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionMode
from rosbags.rosbag2.storage_mcap import (Channel, McapReader, McapWriter, write_channel,
                                          write_string)
from rosbags.typesys import get_typestore, Stores
from ruamel.yaml import YAML

#: The type store the bag's message definitions come from, and the distro the bag names.
TYPESTORE = Stores.ROS2_JAZZY
ROS_DISTRO = 'jazzy'

#: The contract's topics and their types, subscribed from the start.
KNOWN_TOPICS = {
    contract.CLOCK: 'rosgraph_msgs/msg/Clock',
    contract.JOINT_STATES: 'sensor_msgs/msg/JointState',
    contract.JOINT_PATH: 'trajectory_msgs/msg/JointTrajectory',
    contract.FRAME_JOINT_STATES: 'sensor_msgs/msg/JointState',
    contract.LEFT_INFO: 'sensor_msgs/msg/CameraInfo',
    contract.RIGHT_INFO: 'sensor_msgs/msg/CameraInfo',
    contract.LEFT_IMAGE: 'sensor_msgs/msg/Image',
    contract.RIGHT_IMAGE: 'sensor_msgs/msg/Image',
    contract.STEREO_POSE: 'geometry_msgs/msg/PoseStamped',
    contract.FEATURES: 'geometry_msgs/msg/PolygonStamped',
    contract.FEATURE_STATUS: 'diagnostic_msgs/msg/DiagnosticArray',
    contract.FEEDFORWARD_TRAJECTORY: 'trajectory_msgs/msg/JointTrajectory',
    contract.Q_FEEDBACK: 'sensor_msgs/msg/JointState',
    contract.EFFORT_COMMANDS: 'sensor_msgs/msg/JointState',
    contract.TOOL_PATH: 'nav_msgs/msg/Path',
    contract.DIAGNOSTICS: 'diagnostic_msgs/msg/DiagnosticArray',
    contract.ROBOT_DESCRIPTION: 'std_msgs/msg/String',
    contract.TF: 'tf2_msgs/msg/TFMessage',
    contract.TF_STATIC: 'tf2_msgs/msg/TFMessage',
    contract.MARKERS: 'visualization_msgs/msg/MarkerArray',
    contract.DEBUG_LEFT_IMAGE: 'sensor_msgs/msg/Image',
    contract.DEBUG_RIGHT_IMAGE: 'sensor_msgs/msg/Image',
    contract.SERVO_STATUS: 'std_msgs/msg/Int8',
    contract.FEEDBACK_STATUS: 'std_msgs/msg/Int8',
}
IMAGE_TYPES = {'sensor_msgs/msg/Image', 'sensor_msgs/msg/CompressedImage'}
#: Per-step topics recorded with ``include_per_step`` only: /ibvs/joint_path has them.
PER_STEP_TOPICS = {contract.JOINT_STATES, contract.EFFORT_COMMANDS}
#: Image topics recorded with ``include_overlays`` (subscribing to them has them drawn).
OVERLAY_TOPICS = {contract.DEBUG_LEFT_IMAGE, contract.DEBUG_RIGHT_IMAGE}
#: Deep queues: a recorder that falls behind must not lose lockstep messages.
RECORD_QOS = QoSProfile(depth=2000, reliability=contract.RELIABLE.reliability,
                        durability=contract.RELIABLE.durability)
LATCHED_TOPICS = {contract.STEREO_POSE, contract.FEEDFORWARD_TRAJECTORY,
                  contract.ROBOT_DESCRIPTION, contract.TF_STATIC, contract.SERVO_STATUS,
                  contract.FEEDBACK_STATUS}
#: How a latched topic is read: transient local, as its publishers offer it, and deep. A
#: latched topic may have several publishers (/tf_static: robot_state_node's fixed joints and
#: viz_node's frames), each delivering its last message when it matches; a reader of depth 1
#: keeps only the last of those that arrive before it is read (tf2_ros's static listener reads
#: with transient local and a depth of 100: ``StaticListenerQoS``, geometry2 02849c0,
#: ``tf2_ros/include/tf2_ros/qos.hpp`` L53-61).
LATCHED_RECORD_QOS = QoSProfile(depth=100, reliability=contract.LATCHED.reliability,
                                durability=contract.LATCHED.durability)
#: Wall seconds between two flushes of a bag on the wall clock (``wall_clock``): what a
#: killed recorder leaves readable, as each /clock does on sim time.
WALL_FLUSH_S = 0.1


def bag_qos(profile: QoSProfile) -> Qos:
    """Return an rclpy QoSProfile as the rosbags ``Qos`` written to the bag's metadata."""
    def duration(d):
        sec, nsec = divmod(d.nanoseconds, 1_000_000_000)
        return QosTime(sec, nsec)

    return Qos(QosHistory(int(profile.history)), profile.depth,
               QosReliability(int(profile.reliability)), QosDurability(int(profile.durability)),
               duration(profile.deadline), duration(profile.lifespan),
               QosLiveliness(int(profile.liveliness)),
               duration(profile.liveliness_lease_duration),
               profile.avoid_ros_namespace_conventions)


def _with_distro(text):
    """Return rosbag2 metadata YAML ``text`` with ``ros_distro`` set to :data:`ROS_DISTRO`."""
    yaml = YAML(typ='safe')
    yaml.default_flow_style = False
    data = yaml.load(text)
    info = data.get('rosbag2_bagfile_information', data)
    info['ros_distro'] = ROS_DISTRO
    out = StringIO()
    yaml.dump(data, out)
    return out.getvalue()


#: The first and last 8 bytes of an MCAP file.
MCAP_MAGIC = b'\x89MCAP0\r\n'
#: How an MCAP file without summary ends: a DataEnd record (0x0F, a zero CRC: not checked),
#: a Footer (0x02) whose summary offsets are 0, and the magic. Readers then scan the records
#: before it (rosbags' ``McapReader``: its ``meta_scan``).
OPEN_END = (b'\x0f' + (4).to_bytes(8, 'little') + bytes(4)
            + b'\x02' + (20).to_bytes(8, 'little') + bytes(20) + MCAP_MAGIC)


class _Spool(BytesIO):
    """A buffer that tells the file offset its bytes will have: ``start`` + its position."""

    def __init__(self, start):
        super().__init__()
        self.start = start

    def tell(self):
        """Return the offset in the file (what rosbags' chunk index records)."""
        return self.start + super().tell()


class _JazzyMcapStorage(McapWriter):
    """
    rosbags' MCAP storage, with each channel's type hash and the distro that rosbag2 writes.

    The file on disk is a readable MCAP file at any time (:data:`OPEN_END` after its last
    chunk), also when its writer is killed between two chunks.
    """

    def __init__(self, path, compression):
        """Open the file as rosbags does; on disk at once, readable and empty."""
        super().__init__(path, compression)
        self._end_after(b'')

    def add_connection(self, connection, offered_qos_profiles):
        """
        Add the channel with ``offered_qos_profiles`` and ``topic_type_hash`` (RIHS01).

        rosbags' own method writes the first key only; rosbag2 (Jazzy) writes both and reads
        the hash back from ``topic_type_hash``.
        """
        metadata = BytesIO()
        for key, value in (('offered_qos_profiles', offered_qos_profiles),
                           ('topic_type_hash', connection.digest)):
            write_string(metadata, key)
            write_string(metadata, value)
        self.channels.append(Channel(connection.id, connection.msgtype, connection.topic,
                                     connection.ext.serialization_format, metadata.getvalue()))
        self.channel_stats[connection.id] = 0
        write_channel(self.chunk.bio, self.channels[-1], self.schemas)

    def _end_after(self, data):
        """
        Write ``data`` at the file's position, :data:`OPEN_END` after it; stay before the end.

        One write, flushed: what follows (the next chunk, or :meth:`close`'s summary, longer
        than the end) is written over the end.
        """
        start = self.bio.tell()
        self.bio.write(data + OPEN_END)
        self.bio.flush()
        self.bio.seek(start + len(data))

    def close_chunk(self):
        """Write the pending chunk and its message indexes as rosbags does, then the end."""
        file, spool = self.bio, _Spool(self.bio.tell())
        self.bio = spool
        try:
            super().close_chunk()
        finally:
            self.bio = file
        self._end_after(spool.getvalue())

    def flush(self):
        """
        Write the messages so far to the file as a chunk, and the file to the disk.

        rosbags closes a chunk at 1 MB, about 1.5 s of sim time: a runner killed before left
        a 0-byte bag. The recorder flushes at every /clock (10 Hz of sim time, so the chunks
        stay the same from run to run); a killed runner's bag then holds every message up to
        its last /clock, without the summary that :meth:`close` writes.
        """
        if self.chunk.msgs:
            self.close_chunk()

    def close(self, version, metadata):
        """Close the file, its embedded metadata naming :data:`ROS_DISTRO`."""
        super().close(version, _with_distro(metadata).strip())


class JazzyWriter(Writer):
    """A rosbags rosbag2 writer whose bag says ``ros_distro: jazzy`` and carries type hashes."""

    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: _JazzyMcapStorage}

    def close(self) -> None:
        """Close the bag; metadata.yaml names :data:`ROS_DISTRO` (replaced whole, atomically)."""
        super().close()
        tmp = self.metapath.with_name(f'.{self.metapath.name}.tmp')
        tmp.write_text(_with_distro(self.metapath.read_text('utf8')), 'utf8')
        os.replace(tmp, self.metapath)


#: Custom-data key of the metadata written when a bag opens; the metadata that
#: :meth:`JazzyWriter.close` writes has not got it, so a bag that has it was never closed.
IN_PROGRESS_KEY = 'ibvs.recording'
#: Custom-data key that :func:`recover` adds: what it did.
RECOVERED_KEY = 'ibvs.recovered'


class _MetadataOnly:
    """A storage that writes nothing: :func:`write_metadata` closes a writer through it."""

    def __init__(self, path):
        self.path = path

    def close(self, version, metadata):
        """Leave the storage file as it is."""


def write_metadata(bag_path: str | Path, connections: list = (),
                   counts: Mapping[int, int] | None = None,
                   custom_data: Mapping[str, str] | None = None,
                   start_ns: int = 0, end_ns: int = 0) -> None:
    """
    Write ``bag_path/metadata.yaml`` of an MCAP bag, as :meth:`JazzyWriter.close` does.

    ``connections``: rosbags ``Connection`` s of the bag's topics (none when it opens);
    ``counts``: messages per connection id; ``start_ns``/``end_ns``: the first and last
    message's time. The writer's own ``close`` writes the file (rosbags' format, the
    distro of :class:`JazzyWriter`), on a writer whose storage writes nothing.
    """
    bag = Path(bag_path)
    writer = JazzyWriter.__new__(JazzyWriter)
    writer.path, writer.metapath = bag, bag / 'metadata.yaml'
    writer.version, writer.storage_plugin = 9, StoragePlugin.MCAP
    writer.compression_mode, writer.compression_format = CompressionMode.NONE, ''
    writer.connections = list(connections)
    writer.counts = dict(counts or {c.id: 0 for c in writer.connections})
    writer.custom_data = dict(custom_data or {})
    writer.added_types = set()
    writer.min_timestamp, writer.max_timestamp = start_ns, end_ns
    writer.storage = _MetadataOnly(bag / f'{bag.name}.mcap')
    writer.close()


class BagUnreadable(ValueError):
    """A bag's MCAP file that holds no record to recover (named, with the reason)."""


def _end_mcap(path):
    """
    End the MCAP file ``path`` after its last whole record, with a footer without summary.

    What a writer killed mid-file leaves: records up to its last flush, perhaps part of
    one more written over the :data:`OPEN_END` it had ended with. Return whether the file
    had to be ended (False: it ends as a closed or an open-ended file does).
    """
    with open(path, 'r+b') as f:
        size = f.seek(0, 2)
        if size >= 16:
            f.seek(size - 8)
            if f.read(8) == MCAP_MAGIC:
                return False
        f.seek(0)
        if f.read(8) != MCAP_MAGIC:
            raise BagUnreadable(
                f'{path}: no MCAP record in it ({size} bytes): its recorder was killed '
                'before it wrote one' if size < len(MCAP_MAGIC) else
                f'{path}: not an MCAP file')
        end = 8
        while end + 9 <= size:
            f.seek(end)
            header = f.read(9)
            length = int.from_bytes(header[1:], 'little')
            if end + 9 + length > size or header[0] in (0x02, 0x0F):
                break
            end += 9 + length
        f.truncate(end)
        f.seek(end)
        f.write(OPEN_END)
    return True


def recover(bag_path: str | Path) -> bool:
    """
    Make the bag of a recorder that was not closed readable; return whether it had to.

    A bag whose ``metadata.yaml`` is missing or still says :data:`IN_PROGRESS_KEY` (module
    docstring): its MCAP file is ended after its last whole record (:func:`_end_mcap`) and
    the metadata is written from what the file holds, with the custom data written when the
    bag opened and :data:`RECOVERED_KEY`. A closed bag is left as it is.
    """
    bag = Path(bag_path)
    mcap = bag / f'{bag.name}.mcap'
    meta = bag / 'metadata.yaml'
    custom = {}
    if meta.is_file():
        info = YAML(typ='safe').load(meta.read_text('utf8')) or {}
        custom = dict(info.get('rosbag2_bagfile_information', info).get('custom_data') or {})
        if IN_PROGRESS_KEY not in custom:
            return False
    if not mcap.is_file():
        return False
    ended = _end_mcap(mcap)
    reader = McapReader(mcap)
    reader.open()
    try:
        typestore = get_typestore(TYPESTORE)
        connections = [c._replace(digest=c.digest or typestore.hash_rihs01(c.msgtype))
                       if c.msgtype in typestore.types else c for c in reader.connections]
        counts = {c.id: c.msgcount for c in connections}
        start, end = reader.metadata.start_time, reader.metadata.end_time
    finally:
        reader.close()
    custom.pop(IN_PROGRESS_KEY, None)
    custom[RECOVERED_KEY] = ('the recorder was not closed: the MCAP file was ended after its '
                             'last whole record' if ended else 'the recorder was not closed')
    count = sum(counts.values())
    write_metadata(bag, connections, counts, custom, start if count else 0,
                   max(end - 1, start) if count else 0)
    return True


def message_class(type_name: str) -> type:
    """Return the Python class of 'pkg/msg/Type' (what rosidl_runtime_py.get_message does)."""
    pkg, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


class Recorder(Node):
    """Subscribe to the graph's topics and write them to an MCAP bag as they arrive."""

    def __init__(self, bag_path: str | Path, include_images: bool = False,
                 custom_data: Mapping[str, str] | None = None,
                 include_overlays: bool = False, include_per_step: bool = False,
                 wall_clock: bool = False, **kwargs: Any) -> None:
        """
        Open the bag at ``bag_path`` (must not exist) and subscribe to the known topics.

        Image topics are recorded with ``include_images``, but the feature node's overlays
        (:data:`OVERLAY_TOPICS`), which are recorded with ``include_overlays``: they are
        drawn only while someone subscribes to them. The lockstep's per-step messages
        (:data:`PER_STEP_TOPICS`) are recorded with ``include_per_step`` (module docstring).
        ``wall_clock``: a graph on the wall clock, with no /clock (a real cell's): each
        message's time in the bag is the system time it came at, and the file is flushed
        every :data:`WALL_FLUSH_S` of wall time instead of at each /clock.
        """
        super().__init__('ibvs_recorder', **kwargs)
        self._include_images = include_images
        self._include_overlays = include_overlays
        self._include_per_step = include_per_step
        self._typestore = get_typestore(TYPESTORE)
        self._writer = JazzyWriter(bag_path, version=9, storage_plugin=StoragePlugin.MCAP)
        for key, value in (custom_data or {}).items():
            self._writer.set_custom_data(key, value)
        self._writer.open()
        # What a recorder that dies leaves (recover): the run's custom data, and that the
        # bag was not closed.
        self._bag_path = Path(bag_path)
        self._listed = 0  # topics in metadata.yaml
        self._write_open_metadata()
        self._connections = {}
        self._types = {}
        self._qos = {}
        self._topic_subs = {}
        self.clock_ns = 0
        #: The newest serialized message of each topic (read by the runner's Monitor).
        self.latest = {}
        #: Wall time spent writing messages (ibvs_common.profiling), for ``make bench``.
        self.timing = Stopwatch()
        self.counts = {}
        self._skipped = set()
        for topic, type_name in KNOWN_TOPICS.items():
            self._record(topic, type_name)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._discovery = self.create_timer(0.5, self._discover, clock=self._steady)
        self._wall_clock = wall_clock
        self._flush = self.create_timer(WALL_FLUSH_S, self.flush,
                                        clock=self._steady) if wall_clock else None

    def _write_open_metadata(self):
        """Write metadata.yaml of what the file holds now, marked :data:`IN_PROGRESS_KEY`."""
        writer = self._writer
        write_metadata(self._bag_path, writer.connections, writer.counts,
                       {**writer.custom_data, IN_PROGRESS_KEY: 'true'},
                       writer.min_timestamp, writer.max_timestamp)
        self._listed = len(writer.connections)

    def flush(self) -> None:
        """
        Put every message so far on disk; list new topics in metadata.yaml (module docstring).

        Right after the flush the writer's connections and counts are what the file holds.
        """
        self._writer.storage.flush()
        if len(self._writer.connections) > self._listed:
            self._write_open_metadata()

    def set_custom_data(self, key: str, value: str) -> None:
        """Add a key/value (strings) to the bag's metadata; effective at :meth:`close`."""
        self._writer.set_custom_data(key, value)

    def _record(self, topic, type_name):
        if topic in PER_STEP_TOPICS and not self._include_per_step:
            return
        wanted = self._include_overlays if topic in OVERLAY_TOPICS else self._include_images
        if type_name in IMAGE_TYPES and not wanted:
            return
        if type_name not in self._typestore.types:
            if topic not in self._skipped:
                self._skipped.add(topic)
                self.get_logger().warn(f'not recording {topic}: unknown type {type_name}')
            return
        latched = topic in LATCHED_TOPICS
        # the bag's QoS where no publisher says its own: what the topic's publishers offer
        self._types[topic] = type_name
        self._qos[topic] = contract.LATCHED if latched else RECORD_QOS
        self._topic_subs[topic] = self.create_subscription(
            message_class(type_name), topic, partial(self._on_message, topic),
            LATCHED_RECORD_QOS if latched else RECORD_QOS, raw=True)
        self.counts[topic] = 0

    def _discover(self):
        for topic, types in self.get_topic_names_and_types():
            if topic in self._topic_subs or topic in self._skipped or not types:
                continue
            if topic.startswith('/rosout') or topic.startswith('/parameter_events'):
                continue
            self._record(topic, types[0])

    def _connection(self, topic):
        """Return the bag connection of ``topic``, added with its publishers' QoS at first."""
        conn = self._connections.get(topic)
        if conn is None:
            offered = [bag_qos(info.qos_profile)
                       for info in self.get_publishers_info_by_topic(topic)]
            conn = self._writer.add_connection(
                topic, self._types[topic], typestore=self._typestore,
                offered_qos_profiles=offered or [bag_qos(self._qos[topic])])
            self._connections[topic] = conn
        return conn

    def _on_message(self, topic, data):
        with self.timing.section('recording'):
            if topic == contract.CLOCK:
                clock = self._typestore.deserialize_cdr(data, 'rosgraph_msgs/msg/Clock').clock
                if clock_problem(clock.sec, clock.nanosec) is None:  # else keep the last time
                    self.clock_ns = clock.sec * 1_000_000_000 + clock.nanosec
                    self.timing.reached(self.clock_ns)
                    self.flush()  # what came before this /clock: on disk
            self._writer.write(self._connection(topic),
                               time.time_ns() if self._wall_clock else self.clock_ns, data)
            self.latest[topic] = data
        self.counts[topic] += 1

    def close(self) -> None:
        """Stop recording and write the bag's metadata."""
        for sub in self._topic_subs.values():
            self.destroy_subscription(sub)
        self._topic_subs.clear()
        self._discovery.cancel()
        if self._flush is not None:
            self._flush.cancel()
        self._writer.close()
