"""The node kit (ibvs_common.kit): transport by QoS, the registry, waits, the camera input."""

import gc

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from ibvs_common import contract, intra_process, kit
from ibvs_common.conversions import camera_infos, pose_stamped
from ibvs_common.diagnostics import Diagnostics
from ibvs_model import default_camera
import numpy as np
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile
from sensor_msgs.msg import JointState

CAMERA = default_camera('VGA')


def test_direct_delivery_follows_rclcpps_rule():
    assert kit.direct(contract.RELIABLE) and kit.direct(contract.IMAGES) and kit.direct(10)
    assert not kit.direct(contract.LATCHED)  # transient local: DDS only
    assert not kit.direct(QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=10))
    assert not kit.direct(QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=0))
    assert not kit.direct(QoSProfile(depth=5, durability=DurabilityPolicy.TRANSIENT_LOCAL))


def test_the_kit_records_each_topic_a_node_opens_with_its_transport(context):
    node = Node('kit_probe', namespace='/probe', context=context,
                cli_args=['--ros-args', '-r', '/joint_states:=/stereo/joint_states'])
    try:
        pub = kit.publisher(node, JointState, contract.Q_FEEDBACK, contract.RELIABLE)
        latched = kit.publisher(node, PoseStamped, contract.STEREO_POSE, contract.LATCHED)
        sub = kit.subscription(node, JointState, contract.JOINT_STATES, lambda m: None,
                               contract.RELIABLE)
        kit.subscription(node, DiagnosticArray, 'status', lambda m: None, 10)
        assert isinstance(pub, intra_process.Publisher)
        assert not isinstance(latched, intra_process.Publisher)
        assert sub.topic_name == '/stereo/joint_states'
        ends = {(e.topic, e.direction): e for e in kit.opened('/probe/kit_probe')}
        assert set(ends) == {(contract.Q_FEEDBACK, kit.PUBLISHES),
                             (contract.STEREO_POSE, kit.PUBLISHES),
                             ('/stereo/joint_states', kit.SUBSCRIBES),
                             ('/probe/status', kit.SUBSCRIBES)}
        assert ends[(contract.Q_FEEDBACK, kit.PUBLISHES)].direct
        assert not ends[(contract.STEREO_POSE, kit.PUBLISHES)].direct
        assert ends[(contract.STEREO_POSE, kit.PUBLISHES)].msg_type == \
            'geometry_msgs/msg/PoseStamped'
        assert ends[('/probe/status', kit.SUBSCRIBES)].qos.depth == 10
        assert all(e.node == '/probe/kit_probe' for e in ends.values())
        assert set(kit.opened('/probe/kit_probe')) <= set(kit.opened())
        assert kit.opened(node) == kit.opened('/probe/kit_probe')
    finally:
        node.destroy_node()


def test_a_node_gone_is_forgotten(context):
    node = Node('kit_gone', context=context)
    kit.publisher(node, JointState, contract.Q_FEEDBACK, contract.RELIABLE)
    assert len(kit.opened('/kit_gone')) == 1
    node.destroy_node()
    del node
    gc.collect()
    assert kit.opened('/kit_gone') == []


class _Logger:
    """The lines logged at INFO."""

    def __init__(self):
        self.lines = []

    def info(self, line):
        self.lines.append(line)


class _FakeNode:
    """What the wait reporter uses of a node: a timer and a logger."""

    def __init__(self):
        self.logger = _Logger()

    def create_timer(self, period_s, callback, clock=None):
        return (period_s, callback)

    def get_logger(self):
        return self.logger


def test_the_wait_reporter_speaks_only_after_a_second_without_progress():
    node, missing = _FakeNode(), ['/ibvs/features']
    waits = kit.WaitReporter(node, lambda: 'waiting for ' + ', '.join(missing) if missing
                             else None)
    waits.tick()  # the first look, just after the start: silent
    assert node.logger.lines == []
    waits.tick()
    assert node.logger.lines == ['waiting for /ibvs/features']
    waits.progress()
    waits.tick()  # moved on since the last look: silent
    assert len(node.logger.lines) == 1
    missing.clear()
    waits.tick()  # nothing missing: silent
    assert len(node.logger.lines) == 1


def _shift(dz):
    """Return a translation of ``dz`` along z (4x4)."""
    tf = np.eye(4)
    tf[2, 3] = dz
    return tf


class _Camera:
    """A StereoCameraInput on a node, with the cameras it gave."""

    def __init__(self, context, name, **values):
        self.node = Node(name, context=context)
        self.diag = Diagnostics(self.node, 'probe')
        self.cameras, self.inputs = [], []
        self.input = kit.StereoCameraInput(
            self.node, self.diag, values, lambda camera, source: self.cameras.append(
                (camera, source)), self.inputs.append)

    def reasons(self, topic):
        return {k[len(topic) + 2:]: n for k, n in self.diag.rejections.items()
                if k.startswith(topic + ': ')}


def test_the_camera_input_builds_the_camera_once_complete_and_counts_rejections(context):
    probe = _Camera(context, 'camera_input_probe')
    cam = probe.input
    try:
        left, right = camera_infos(CAMERA.intrinsics, 0)
        assert cam.missing() == [contract.LEFT_INFO, contract.RIGHT_INFO, contract.STEREO_POSE]
        bad = camera_infos(CAMERA.intrinsics, 0)[0]
        bad.width = 0
        cam.on_info('left', bad)
        assert probe.reasons(contract.LEFT_INFO) == {'bad camera_info size': 1}
        cam.on_info('left', left)
        cam.on_info('right', right)
        assert probe.cameras == [] and cam.missing() == [contract.STEREO_POSE]
        cam.on_pose(pose_stamped(CAMERA.pose_C_O, 0))
        (camera, source), = probe.cameras
        assert source == contract.STEREO_POSE
        np.testing.assert_allclose(camera.pose_C_O, CAMERA.pose_C_O, atol=1e-12)
        assert probe.inputs == [contract.LEFT_INFO, contract.RIGHT_INFO, contract.STEREO_POSE]
        cam.on_info('right', right)  # the same again: no new camera
        assert len(probe.cameras) == 1
        # Lenses that disagree: refused under the lens that came last, even when the pose
        # completes the set.
        other = camera_infos(default_camera('HD720').intrinsics, 0)[1]
        cam.on_info('right', other)
        assert probe.cameras[-1] == (None, contract.RIGHT_INFO)
        assert probe.reasons(contract.RIGHT_INFO) == {'camera_info size mismatch': 1}
        cam.on_pose(pose_stamped(CAMERA.pose_C_O @ _shift(0.01), 0))
        assert probe.cameras[-1] == (None, contract.STEREO_POSE)
        assert probe.reasons(contract.RIGHT_INFO) == {'camera_info size mismatch': 2}
        assert probe.reasons(contract.STEREO_POSE) == {}
        cam.on_info('right', right)  # back to a pair that agrees: a camera again
        assert probe.cameras[-1][0] is not None
        n = len(probe.cameras)
        cam.hold()  # built for good: a different lens is refused, a pose ignored
        cam.on_info('right', other)
        assert probe.reasons(contract.RIGHT_INFO)['camera_info changed'] == 1
        cam.on_pose(pose_stamped(CAMERA.pose_C_O, 5))
        assert cam.pose.header.stamp.sec == 0 and len(probe.cameras) == n
        cam.forget_infos()
        assert cam.missing() == [contract.LEFT_INFO, contract.RIGHT_INFO]
    finally:
        probe.node.destroy_node()


def test_the_camera_pose_parameter_replaces_the_topic(context):
    pose = [1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0]
    probe = _Camera(context, 'camera_pose_probe', camera_pose=pose)
    try:
        assert probe.input.missing() == [contract.LEFT_INFO, contract.RIGHT_INFO]
        topics = {e.topic for e in kit.opened(probe.node)}
        assert contract.STEREO_POSE not in topics and contract.LEFT_INFO in topics
        subs = {e.topic: e for e in kit.opened(probe.node)}
        assert subs[contract.LEFT_INFO].qos.depth == contract.CAMERA_INFO.depth
        assert subs[contract.LEFT_INFO].msg_type == 'sensor_msgs/msg/CameraInfo'
    finally:
        probe.node.destroy_node()


class _Counts:
    """A stand-in for Diagnostics.reject: the rejections, in order."""

    def __init__(self):
        self.seen = []

    def reject(self, source, reason, detail=''):
        self.seen.append((source, reason, detail))


def _joint_state(sec, positions=(0.0,) * 6):
    msg = JointState(name=list(contract.JOINT_NAMES), position=list(positions))
    msg.header.stamp.sec = sec
    return msg


def test_inputs_apply_the_stamp_rule_and_the_order_and_count_rejections():
    from ibvs_common.conversions import InputError, read_joints
    counts = _Counts()
    inputs = kit.Inputs(counts, lambda: 10 * 10**9, lead_ns=10**9)
    got = inputs.read('/j', _joint_state(5), read_joints)
    assert got[0] == 5 * 10**9 and np.allclose(got[1], 0.0) and counts.seen == []
    assert inputs.read('/j', _joint_state(5)) is None  # the same stamp again
    assert inputs.read('/j', _joint_state(4)) is None  # back in time
    assert inputs.read('/j', _joint_state(60)) is None  # beyond now + lead
    assert [reason for _, reason, _ in counts.seen] == [
        'duplicate stamp', 'stamp went back', 'stamp in the future']
    assert all(source == '/j' for source, _, _ in counts.seen)
    # A message refused for its values leaves its stamp to a good one.
    assert inputs.read('/j', _joint_state(6, [float('nan')] * 6), read_joints) is None
    assert inputs.read('/j', _joint_state(6), read_joints)[0] == 6 * 10**9
    # take=False: checked, not taken; ordered=False: no order at all.
    assert inputs.read('/k', _joint_state(7), take=False)[0] == 7 * 10**9
    assert inputs.read('/k', _joint_state(7))[0] == 7 * 10**9
    assert inputs.read('/k', _joint_state(7), ordered=False)[0] == 7 * 10**9
    inputs.reject('/k', InputError('bad', 'why'), '; held')
    assert counts.seen[-1] == ('/k', 'bad', 'why; held')
