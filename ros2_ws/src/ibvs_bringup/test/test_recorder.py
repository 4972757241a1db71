"""The recorder's bag says what ``ros2 bag play`` and ``ros2 bag info`` need to replay it."""

from io import BytesIO
import time

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from ibvs_bringup.recorder import Recorder
from ibvs_common import contract
from ibvs_common.conversions import joint_path, joint_state
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rosbags.interfaces import QosDurability, QosReliability
from rosbags.rosbag2 import Reader
from rosbags.rosbag2.storage_mcap import McapReader, read_string
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

DEADLINE_S = 20.0


def channel_metadata(channel):
    """Return an MCAP channel's user metadata (map<string, string>) as a dict."""
    bio, out = BytesIO(channel.metadata), {}
    while bio.tell() < len(channel.metadata):
        key = read_string(bio)
        out[key] = read_string(bio)
    return out


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    """
    Record a latched pose, a /clock (one of them malformed) and a joint path; return the bag.

    A /joint_states is published too, with the recorder's discovery given time to find it:
    it must not be recorded (nor subscribed to).
    """
    path = tmp_path_factory.mktemp('rec') / 'bag'
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    recorder = Recorder(path, context=ctx)
    talker = rclpy.create_node('talker', context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(recorder)
    executor.add_node(talker)
    try:
        pose = talker.create_publisher(PoseStamped, contract.STEREO_POSE, contract.LATCHED)
        clock = talker.create_publisher(Clock, contract.CLOCK, contract.RELIABLE)
        batch = talker.create_publisher(JointTrajectory, contract.JOINT_PATH,
                                        contract.RELIABLE)
        joints = talker.create_publisher(JointState, contract.JOINT_STATES, contract.RELIABLE)
        deadline = time.monotonic() + DEADLINE_S
        while not all(p.get_subscription_count() for p in (pose, clock, batch)):
            assert time.monotonic() < deadline, 'discovery'
            executor.spin_once(timeout_sec=0.05)
        until = time.monotonic() + 1.0  # two passes of the recorder's discovery
        while time.monotonic() < until:
            executor.spin_once(timeout_sec=0.05)
        assert joints.get_subscription_count() == 0
        pose.publish(PoseStamped())
        clock.publish(Clock(clock=Time(sec=2)))
        clock.publish(Clock(clock=Time(sec=-1)))  # a bad publisher: not fatal, not a time
        state = joint_state(2_000_000_000, position=[0.0] * 6)
        joints.publish(state)
        batch.publish(joint_path([state]))
        while recorder.counts[contract.JOINT_PATH] < 1 or recorder.counts[contract.CLOCK] < 2 \
                or recorder.counts[contract.STEREO_POSE] < 1:
            assert time.monotonic() < deadline, 'messages'
            executor.spin_once(timeout_sec=0.05)
        recorder.close()
    finally:
        executor.shutdown()
        talker.destroy_node()
        recorder.destroy_node()
        rclpy.try_shutdown(context=ctx)
    return path


def test_the_bag_file_is_where_the_readme_says(bag):
    # docs/visualisation.md, "Recordings": a run's bag/ holds bag/bag.mcap
    assert sorted(p.name for p in bag.iterdir()) == ['bag.mcap', 'metadata.yaml']


def test_the_bag_names_jazzy_in_both_copies_of_its_metadata(bag):
    with Reader(bag) as reader:
        assert reader.ros_distro == 'jazzy'
    # the copy inside the MCAP file, which a reader of the bare .mcap sees
    assert b'ros_distro: jazzy' in (bag / 'bag.mcap').read_bytes()
    assert b'ros_distro: rosbags' not in (bag / 'bag.mcap').read_bytes()


def test_each_topic_has_its_publishers_qos_and_its_type_hash(bag):
    with Reader(bag) as reader:
        conns = {c.topic: c for c in reader.connections}
        hashes = {c.topic: c.digest for c in reader.connections}
    # /diagnostics may be there too: the nodes of an earlier test's graph on this test
    # process's domain publish it once a second while they shut down (seen under make test).
    assert set(conns) - {contract.DIAGNOSTICS} == {
        contract.STEREO_POSE, contract.CLOCK, contract.JOINT_PATH}
    for topic, conn in conns.items():
        if topic == contract.DIAGNOSTICS:
            continue
        qos = conn.ext.offered_qos_profiles
        assert len(qos) == 1, topic
        assert qos[0].reliability == QosReliability.RELIABLE
        expected = (QosDurability.TRANSIENT_LOCAL if topic == contract.STEREO_POSE
                    else QosDurability.VOLATILE)
        assert qos[0].durability == expected, topic
        assert hashes[topic].startswith('RIHS01_'), topic
    storage = McapReader(bag / 'bag.mcap')
    storage.open()
    try:
        channels = {c.topic: channel_metadata(c) for c in storage.channels.values()}
    finally:
        storage.close()
    for topic, meta in channels.items():
        assert meta['topic_type_hash'] == hashes[topic]
        assert ('transient_local' in meta['offered_qos_profiles']) \
            == (topic == contract.STEREO_POSE)


def test_a_malformed_clock_is_recorded_but_does_not_move_the_bag_time(bag):
    with Reader(bag) as reader:
        times = [t for c, t, _ in reader.messages() if c.topic == contract.JOINT_PATH]
    assert times == [2_000_000_000]


def test_the_lockstep_per_step_messages_are_recorded_when_asked(tmp_path):
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    try:
        for include in (False, True):
            recorder = Recorder(tmp_path / f'bag_{include}', context=ctx,
                                include_per_step=include)
            assert (contract.JOINT_STATES in recorder.counts) == include
            assert (contract.EFFORT_COMMANDS in recorder.counts) == include
            assert contract.JOINT_PATH in recorder.counts
            recorder.close()
            recorder.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


def test_messages_before_a_clock_are_on_disk_before_the_bag_is_closed(tmp_path):
    """A runner killed before the first 1 MB chunk is written leaves its messages on disk."""
    from ibvs_bringup.recorder import JazzyWriter
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.typesys import get_typestore, Stores
    writer = JazzyWriter(tmp_path / 'bag', version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    conn = writer.add_connection('/joint_states', 'sensor_msgs/msg/JointState',
                                 typestore=get_typestore(Stores.ROS2_JAZZY))
    payload = b'\x00\x01\x00\x00' + b'ibvs-marker' * 10
    writer.write(conn, 1, payload)
    mcap = tmp_path / 'bag' / 'bag.mcap'
    assert b'ibvs-marker' not in mcap.read_bytes()  # rosbags keeps it in memory
    writer.storage.flush()
    assert b'ibvs-marker' in mcap.read_bytes()  # a SIGKILL now would keep it
    writer.write(conn, 2, payload)
    writer.close()
    with Reader(tmp_path / 'bag') as reader:
        assert [t for _, t, _ in reader.messages()] == [1, 2]


def test_a_bag_left_open_is_readable_once_recovered(bag, tmp_path):
    """
    A bag that a runner killed with SIGKILL left without metadata is read once recovered.

    The recorder writes the metadata when the bag opens, marked as in progress; recover()
    ends the MCAP file after its last whole record (here: with half a record after it) and
    writes the metadata of what it holds, the run's custom data kept.
    """
    import shutil
    from ibvs_bringup.recorder import IN_PROGRESS_KEY, JazzyWriter, RECOVERED_KEY, recover
    from ibvs_bringup.recorder import write_metadata
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.typesys import get_typestore, Stores
    from ruamel.yaml import YAML
    assert not recover(bag)  # a closed bag is left alone
    path = tmp_path / 'bag'
    writer = JazzyWriter(path, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.set_custom_data('ibvs.parameters', 'camera_rate_hz: 30.0\n')
    writer.open()
    write_metadata(path, custom_data={**writer.custom_data, IN_PROGRESS_KEY: 'true'})
    typestore = get_typestore(Stores.ROS2_JAZZY)
    conn = writer.add_connection('/clock', 'rosgraph_msgs/msg/Clock', typestore=typestore)
    for stamp in (10, 20, 30):
        writer.write(conn, stamp, b'\x00\x01\x00\x00' + bytes(8))
        writer.storage.flush()
    writer.write(conn, 40, b'\x00\x01\x00\x00' + bytes(8))  # in memory: lost with the writer
    killed = tmp_path / 'killed'
    shutil.copytree(path, killed)  # the files as a SIGKILL leaves them
    mcap = killed / 'killed.mcap'
    (killed / 'bag.mcap').rename(mcap)
    with open(mcap, 'ab') as f:
        f.write(b'\x06' + (1000).to_bytes(8, 'little') + bytes(100))  # a chunk cut short
    writer.close()
    assert recover(killed)
    assert not recover(killed)  # once is enough
    with Reader(killed) as reader:
        assert [t for _, t, _ in reader.messages()] == [10, 20, 30]
        assert [c.topic for c in reader.connections] == ['/clock']
    info = YAML(typ='safe').load((killed / 'metadata.yaml').read_text())
    custom = info['rosbag2_bagfile_information']['custom_data']
    assert custom['ibvs.parameters'] == 'camera_rate_hz: 30.0\n'
    assert IN_PROGRESS_KEY not in custom and 'ended after its last whole record' in \
        custom[RECOVERED_KEY]
    assert info['rosbag2_bagfile_information']['ros_distro'] == 'jazzy'


def test_an_open_bag_is_read_by_rosbags_as_it_is(tmp_path):
    """
    A recorder's bag, copied while it records (what a SIGKILL leaves), opens with rosbags.

    The MCAP file ends after each chunk, and metadata.yaml lists the topics once their
    channels are on disk: every message before the last /clock is read, the same after
    recover().
    """
    import shutil
    from ibvs_bringup.recorder import IN_PROGRESS_KEY, recover
    from rosbags.highlevel import AnyReader
    from ruamel.yaml import YAML
    path = tmp_path / 'bag'
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    recorder = Recorder(path, context=ctx)
    talker = rclpy.create_node('talker', context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(recorder)
    executor.add_node(talker)
    copies = []
    try:
        clock = talker.create_publisher(Clock, contract.CLOCK, contract.RELIABLE)
        batch = talker.create_publisher(JointTrajectory, contract.JOINT_PATH,
                                        contract.RELIABLE)
        deadline = time.monotonic() + DEADLINE_S
        while not all(p.get_subscription_count() for p in (clock, batch)):
            assert time.monotonic() < deadline, 'discovery'
            executor.spin_once(timeout_sec=0.05)
        shutil.copytree(path, tmp_path / 'opened')  # nothing recorded yet
        copies.append(tmp_path / 'opened')

        def until_recorded(topic, count):
            while recorder.counts[topic] < count:
                assert time.monotonic() < deadline, 'messages'
                executor.spin_once(timeout_sec=0.05)

        for sec in (1, 2, 3):
            clock.publish(Clock(clock=Time(sec=sec)))
            until_recorded(contract.CLOCK, sec)  # the time of what comes next
            batch.publish(joint_path([joint_state(sec * 1_000_000_000, position=[0.0] * 6)]))
            until_recorded(contract.JOINT_PATH, sec)
        clock.publish(Clock(clock=Time(sec=4)))  # flushes what came at 3 s
        until_recorded(contract.CLOCK, 4)
        shutil.copytree(path, tmp_path / 'killed')  # the files as a SIGKILL leaves them
        copies.append(tmp_path / 'killed')
        recorder.close()
    finally:
        executor.shutdown()
        talker.destroy_node()
        recorder.destroy_node()
        rclpy.try_shutdown(context=ctx)

    def read(bag):
        with AnyReader([bag]) as reader:
            return sorted((c.topic, t) for c, t, _ in reader.messages())

    for copy in copies:
        meta = YAML(typ='safe').load((copy / 'metadata.yaml').read_text())
        assert IN_PROGRESS_KEY in meta['rosbag2_bagfile_information']['custom_data']
    assert read(tmp_path / 'opened') == []
    expected = sorted([(contract.CLOCK, s * 1_000_000_000) for s in (1, 2, 3)] + [
        (contract.JOINT_PATH, s * 1_000_000_000) for s in (1, 2, 3)])
    killed = tmp_path / 'killed'
    assert read(killed) == expected
    (killed / 'bag.mcap').rename(killed / 'killed.mcap')  # recover() finds it by its name
    assert recover(killed)
    assert read(killed) == expected
    assert read(path) == sorted(expected + [(contract.CLOCK, 4_000_000_000)])
