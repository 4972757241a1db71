"""
Recorder: every topic of the graph, raw images only on request, into a rosbag2 MCAP bag.

Written with ``rosbags`` (rosbag2 format version 9, MCAP storage, message definitions from
the ROS 2 Jazzy type store), so ``ros2 bag info``, Foxglove and PlotJuggler open it.
Messages are received serialized (``raw=True``) and written as they are: no
deserialisation on the hot path. The topics of the contract are subscribed before the
simulator starts, so nothing of the run's beginning is lost; any other topic that appears
is picked up by discovery, as ``ros2 bag record --all`` does.
"""

from functools import partial
import importlib

from ibvs_common import contract
from ibvs_common.profiling import Stopwatch
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import get_typestore, Stores

#: The contract's topics and their types, subscribed from the start.
KNOWN_TOPICS = {
    contract.CLOCK: 'rosgraph_msgs/msg/Clock',
    contract.JOINT_STATES: 'sensor_msgs/msg/JointState',
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
    contract.TOOL_POSE: 'geometry_msgs/msg/PoseStamped',
    contract.DIAGNOSTICS: 'diagnostic_msgs/msg/DiagnosticArray',
}
IMAGE_TYPES = {'sensor_msgs/msg/Image', 'sensor_msgs/msg/CompressedImage'}
#: Deep queues: a recorder that falls behind must not lose lockstep messages.
RECORD_QOS = QoSProfile(depth=2000, reliability=contract.RELIABLE.reliability,
                        durability=contract.RELIABLE.durability)
LATCHED_TOPICS = {contract.STEREO_POSE, contract.FEEDFORWARD_TRAJECTORY}


def message_class(type_name):
    """Return the Python class of 'pkg/msg/Type' (what rosidl_runtime_py.get_message does)."""
    pkg, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{pkg}.{kind}'), name)


class Recorder(Node):
    """Subscribe to the graph's topics and write them to an MCAP bag as they arrive."""

    def __init__(self, bag_path, include_images=False, custom_data=None, **kwargs):
        """Open the bag at ``bag_path`` (must not exist) and subscribe to the known topics."""
        super().__init__('ibvs_recorder', **kwargs)
        self._include_images = include_images
        self._typestore = get_typestore(Stores.ROS2_JAZZY)
        self._writer = Writer(bag_path, version=9, storage_plugin=StoragePlugin.MCAP)
        for key, value in (custom_data or {}).items():
            self._writer.set_custom_data(key, value)
        self._writer.open()
        self._connections = {}
        self._topic_subs = {}
        self.clock_ns = 0
        #: Wall time spent writing messages (ibvs_common.profiling), for ``make bench``.
        self.timing = Stopwatch()
        self.counts = {}
        self._skipped = set()
        for topic, type_name in KNOWN_TOPICS.items():
            self._record(topic, type_name)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._discovery = self.create_timer(0.5, self._discover, clock=self._steady)

    def set_custom_data(self, key, value):
        """Add a key/value (strings) to the bag's metadata; effective at :meth:`close`."""
        self._writer.set_custom_data(key, value)

    def _record(self, topic, type_name):
        if type_name in IMAGE_TYPES and not self._include_images:
            return
        if type_name not in self._typestore.types:
            if topic not in self._skipped:
                self._skipped.add(topic)
                self.get_logger().warn(f'not recording {topic}: unknown type {type_name}')
            return
        conn = self._writer.add_connection(topic, type_name, typestore=self._typestore)
        self._connections[topic] = conn
        qos = contract.LATCHED if topic in LATCHED_TOPICS else RECORD_QOS
        self._topic_subs[topic] = self.create_subscription(
            message_class(type_name), topic, partial(self._on_message, topic), qos, raw=True)
        self.counts[topic] = 0

    def _discover(self):
        for topic, types in self.get_topic_names_and_types():
            if topic in self._connections or topic in self._skipped or not types:
                continue
            if topic.startswith('/rosout') or topic.startswith('/parameter_events'):
                continue
            self._record(topic, types[0])

    def _on_message(self, topic, data):
        with self.timing.section('recording'):
            if topic == contract.CLOCK:
                clock = self._typestore.deserialize_cdr(data, 'rosgraph_msgs/msg/Clock')
                self.clock_ns = clock.clock.sec * 1_000_000_000 + clock.clock.nanosec
                self.timing.reached(self.clock_ns)
            self._writer.write(self._connections[topic], self.clock_ns, data)
        self.counts[topic] += 1

    def close(self):
        """Stop recording and write the bag's metadata."""
        for sub in self._topic_subs.values():
            self.destroy_subscription(sub)
        self._topic_subs.clear()
        self._discovery.cancel()
        self._writer.close()
