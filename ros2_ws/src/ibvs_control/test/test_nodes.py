"""
The three control nodes in an rclpy executor, fed messages by a test node.

Each test has its own rclpy Context; nodes share one SingleThreadedExecutor with the
test node and the tests wait on conditions (with a generous deadline that only guards
against a hang), never on wall-clock time.
"""


from contextlib import contextmanager

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PolygonStamped, PoseStamped
from ibvs_common import contract
from ibvs_common.conversions import (camera_infos, feature_status_msg, features_msg,
                                     FeatureStatus, joint_state, joint_trajectory, pose_stamped,
                                     read_joints, read_trajectory, stamp_ns)
from ibvs_common.params import ParameterError
from ibvs_common.timing import frame_stamp_ns
from ibvs_control.adaptive_feedback_node import AdaptiveFeedbackNode
from ibvs_control.controllers import AdaptiveFeedback, Feedforward, JointLoop
from ibvs_control.dynamics import RobotDynamics
from ibvs_control.feedforward_node import FeedforwardNode
from ibvs_control.joint_controller_node import JointControllerNode
from ibvs_control.servo_laws import ClassicIBVS
from ibvs_control.servo_status import ServoStatus
from ibvs_model import default_model, inverse_kinematics, paper
from ibvs_testing.fixtures import spin_until
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, JointState
from std_msgs.msg import Header, Int8
from trajectory_msgs.msg import JointTrajectory

MS = 1_000_000
#: The true joint angles of the scenario 1 start (IK with seed 0, as the simulator).
Q0 = inverse_kinematics(paper.scenario_start_pose(1))
CAMERA_NS = 33_333_333
DEADLINE_S = 20.0


def overrides(**values):
    return [Parameter(k, value=v) for k, v in values.items()]


class Harness:
    """A test node with publishers/recorders of the contract topics, and an executor."""

    def __init__(self, context, *nodes):
        self.node = Node('harness', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.nodes = list(nodes)
        for n in (self.node, *nodes):
            self.executor.add_node(n)
        self.received = {}
        pub = self.node.create_publisher
        self.pub = {
            contract.JOINT_STATES: pub(JointState, contract.JOINT_STATES, contract.RELIABLE),
            contract.FEEDFORWARD_TRAJECTORY: pub(JointTrajectory,
                                                 contract.FEEDFORWARD_TRAJECTORY,
                                                 contract.LATCHED),
            contract.Q_FEEDBACK: pub(JointState, contract.Q_FEEDBACK, contract.RELIABLE),
            contract.FEATURES: pub(PolygonStamped, contract.FEATURES, contract.RELIABLE),
            contract.LEFT_INFO: pub(CameraInfo, contract.LEFT_INFO, contract.IMAGES),
            contract.RIGHT_INFO: pub(CameraInfo, contract.RIGHT_INFO, contract.IMAGES),
            contract.STEREO_POSE: pub(PoseStamped, contract.STEREO_POSE, contract.LATCHED),
            contract.CLOCK: pub(Clock, contract.CLOCK, contract.RELIABLE),
        }
        for topic, kind, qos in (
                (contract.FEEDFORWARD_TRAJECTORY, JointTrajectory, contract.LATCHED),
                (contract.Q_FEEDBACK, JointState, contract.RELIABLE),
                (contract.EFFORT_COMMANDS, JointState, contract.RELIABLE),
                (contract.DIAGNOSTICS, DiagnosticArray, 10)):
            self.received[topic] = []
            self.node.create_subscription(
                kind, topic, lambda m, t=topic: self.received[t].append(m), qos)

    def spin_until(self, predicate, what='condition'):
        spin_until(self.executor, predicate, DEADLINE_S, what)

    def wait_matched(self, topics):
        """Wait until every publisher in ``topics`` has its subscriber (discovery)."""
        self.spin_until(lambda: all(self.pub[t].get_subscription_count() > 0 for t in topics),
                        'discovery')

    def publish(self, topic, msg):
        self.pub[topic].publish(msg)

    def close(self):
        self.executor.shutdown()
        for n in (*self.nodes, self.node):
            n.destroy_node()


def stamps(msgs):
    return [stamp_ns(m.header.stamp) for m in msgs]


# -- feedforward_node -----------------------------------------------------------------------

def feedforward_rows(Q0, count):
    ref = Feedforward(paper.target_pose(), 0.01, 1e-3)
    ref.start(Q0)
    return np.array([ref.step() for _ in range(count)])


def trajectory(start_ns, rows):
    return joint_trajectory(start_ns, MS, rows)


def test_feedforward_publishes_its_whole_trajectory_once(context):
    node = FeedforwardNode(context=context)
    h = Harness(context, node)
    try:
        h.wait_matched([contract.JOINT_STATES])
        for t in (0, MS, 2 * MS):
            # later encoder values do not matter: the branch and rest state come from the first
            h.publish(contract.JOINT_STATES, joint_state(t, Q0 + 0.01 * (t > 0), np.zeros(6)))
        out = h.received[contract.FEEDFORWARD_TRAJECTORY]
        h.spin_until(lambda: len(out) == 1, 'the feedforward trajectory')
        start_ns, rows = read_trajectory(out[0], MS)
        assert start_ns == 0
        # exactly what the filter gives step by step, until it has settled (then held)
        expected = feedforward_rows(Q0, len(rows) + 500)
        np.testing.assert_array_equal(rows, expected[:len(rows)])
        np.testing.assert_allclose(expected[len(rows):], np.tile(rows[-1], (500, 1)), rtol=0,
                                   atol=1e-14)
        np.testing.assert_allclose(rows[0], Q0, atol=1e-12)
        np.testing.assert_allclose(rows[-1], node.ff.q_target, atol=1e-9)
        # the node has left the lockstep: no second trajectory, no /joint_states reader
        h.publish(contract.JOINT_STATES, joint_state(3 * MS, Q0, np.zeros(6)))
        h.spin_until(lambda: h.pub[contract.JOINT_STATES].get_subscription_count() == 0,
                     'the feedforward to unsubscribe')
        assert len(out) == 1
    finally:
        h.close()


def test_feedforward_rejects_bad_joint_states_and_starts_on_the_first_good_one(context):
    node = FeedforwardNode(context=context)
    h = Harness(context, node)
    try:
        h.wait_matched([contract.JOINT_STATES])
        for msg in (joint_state(3 * MS, [0.0] * 5, np.zeros(5)),
                    joint_state(4 * MS, [np.nan] + [0.0] * 5, np.zeros(6)),
                    joint_state(5 * MS, Q0, np.zeros(6))):
            h.publish(contract.JOINT_STATES, msg)
        out = h.received[contract.FEEDFORWARD_TRAJECTORY]
        h.spin_until(lambda: len(out) == 1, 'the feedforward trajectory')
        h.spin_until(lambda: node.diagnostics.rejected_total == 2, 'rejections')
        assert read_trajectory(out[0], MS)[0] == 5 * MS
        assert node.diagnostics.rejections == {
            '/joint_states: wrong position length': 1,
            '/joint_states: non-finite position': 1}
        # and the count goes out on /diagnostics
        node.diagnostics.publish()
        diags = h.received[contract.DIAGNOSTICS]

        def counted():
            for m in diags:
                for status in m.status:
                    if status.name.startswith('feedforward_node'):
                        values = {kv.key: kv.value for kv in status.values}
                        return values.get('rejected_total') == '2'
            return False
        h.spin_until(counted, 'the rejection count on /diagnostics')
    finally:
        h.close()


def test_feedforward_ignores_a_first_joint_state_from_the_future_or_with_a_bad_stamp(context):
    """A bad first stamp would start the trajectory there and hold the arm until then."""
    node = FeedforwardNode(context=context, parameter_overrides=overrides(use_sim_time=True))
    h = Harness(context, node)
    try:
        h.wait_matched([contract.JOINT_STATES, contract.CLOCK])
        h.publish(contract.CLOCK, Clock(clock=Time(sec=0, nanosec=MS)))
        h.spin_until(lambda: node.get_clock().now().nanoseconds == MS, 'sim time 1 ms')
        for stamp in (Time(sec=1_000_000), Time(sec=0, nanosec=4_000_000_000),
                      Time(sec=-5, nanosec=MS)):
            h.publish(contract.JOINT_STATES, joint_state(stamp, Q0, np.zeros(6)))
        h.spin_until(lambda: node.diagnostics.rejected_total == 3, 'rejections')
        assert node.diagnostics.rejections == {
            '/joint_states: stamp in the future': 1, '/joint_states: malformed stamp': 1,
            '/joint_states: negative time': 1}
        h.publish(contract.JOINT_STATES, joint_state(MS, Q0, np.zeros(6)))
        out = h.received[contract.FEEDFORWARD_TRAJECTORY]
        h.spin_until(lambda: len(out) == 1, 'the feedforward trajectory')
        assert read_trajectory(out[0], MS)[0] == MS
    finally:
        h.close()


@pytest.mark.parametrize('params,name', [
    ({'target_position': [3.0, 0.0, 0.3]}, 'target_position'),
    ({'target_rotation': [1.0] * 9}, 'target_rotation'),
    ({'omega_n': 150.0}, 'omega_n'),
    ({'omega_n': 100.0}, 'omega_n'),
    ({'physics_rate_hz': 5.0}, 'physics_rate_hz'),
    ({'feedforward_ratio': 0.0}, 'feedforward_ratio'),
])
def test_nodes_stop_at_start_on_bad_parameters(context, params, name):
    for cls in (FeedforwardNode, AdaptiveFeedbackNode, JointControllerNode):
        if name == 'physics_rate_hz' and cls is AdaptiveFeedbackNode:
            continue
        if name == 'feedforward_ratio' and cls is not FeedforwardNode:
            continue
        if name.startswith('target') and cls is JointControllerNode:
            continue
        # The bandwidth rule omega_n < 1 / tau_in is the outer loop's (eq. 36): only the
        # node that uses omega_n declares and checks it.
        if name == 'omega_n' and cls is not AdaptiveFeedbackNode:
            continue
        with pytest.raises(ParameterError, match=f"'{name}'"):
            cls(context=context, parameter_overrides=overrides(**params))


# -- adaptive_feedback_node -----------------------------------------------------------------

def camera_messages(model):
    left, right = camera_infos(model.camera.intrinsics, 0)
    return left, right, pose_stamped(model.camera.pose_C_O, 0)


def feedback_harness(context, **params):
    node = AdaptiveFeedbackNode(context=context, parameter_overrides=overrides(**params))
    h = Harness(context, node)
    h.wait_matched([contract.JOINT_STATES, contract.FEATURES, contract.LEFT_INFO,
                    contract.RIGHT_INFO, contract.STEREO_POSE])
    return node, h


def test_feedback_answers_each_frame_like_the_pure_controller(context):
    model = default_model()
    node, h = feedback_harness(context)
    try:
        q_target = inverse_kinematics(paper.target_pose())
        d_q = np.radians(paper.DISTURBANCE_DEG)
        frames = [n * CAMERA_NS for n in range(4)]
        # features first: the node must wait for the camera model and the joint states
        for n, t in enumerate(frames):
            h.publish(contract.FEATURES, features_msg(model.features(q_target + d_q), t))
        h.spin_until(lambda: len(node._lockstep.frames) == 4, 'features buffered')
        left, right, pose = camera_messages(model)
        h.publish(contract.LEFT_INFO, left)
        h.publish(contract.RIGHT_INFO, right)
        h.publish(contract.STEREO_POSE, pose)
        h.spin_until(lambda: node.feedback is not None, 'camera model')
        assert h.received[contract.Q_FEEDBACK] == []
        # joint states on the 1 ms grid: frame n uses the first one at or after n * T_cam
        for t in (0, 33 * MS, 34 * MS, 66 * MS, 67 * MS, 100 * MS):
            h.publish(contract.JOINT_STATES, joint_state(t, q_target, np.zeros(6)))
        out = h.received[contract.Q_FEEDBACK]
        h.spin_until(lambda: len(out) == 4, 'q_feedback')
        assert stamps(out) == frames
        ref = AdaptiveFeedback(model, paper.target_pose(), 0.01, 10.0, paper.ZETA, 1 / 30)
        # the features travel as float32 (Point32)
        sent = model.features(q_target + d_q).astype(np.float32).astype(float)
        for msg in out:
            up = ref.update(sent, q_target, np.zeros(6))
            np.testing.assert_allclose(read_joints(msg), up.q_feedback, atol=1e-9)
        np.testing.assert_allclose(node.feedback.p_target, model.features(q_target),
                                   atol=1e-6)
        status = node.diagnostics.status()
        values = {kv.key: kv.value for kv in status.values}
        assert values['rank'] == '5'
        assert float(values['condition_number']) > 1.0
        assert values['singular_values'].startswith('[')
        # |p_hat - p_bar| of the frame as measured, and the model's pose: at the target
        error = np.linalg.norm(sent - node.feedback.p_target)
        assert float(values['image_error_norm_px']) == pytest.approx(error, rel=1e-5)
        assert float(values['model_position_error_m']) < 1e-9
        assert values['local_minimum'] == 'False'
        assert node._status == ServoStatus.NO_WARNING  # on /ibvs/feedback_status
    finally:
        h.close()


def feature_status(t_ns, measured):
    mode = contract.FEATURE_MEASURED if measured else contract.FEATURE_ESTIMATED
    return feature_status_msg(FeatureStatus(mode, mode, mode if measured else 'not found: test',
                                            0.0, 'full'), t_ns)


def test_ibvs_feedback_waits_for_the_feature_status_and_holds_unmeasured(context):
    model = default_model()
    node, h = feedback_harness(context, servo_law='ibvs', feedforward_method='hold',
                               feature_fallback='hold')
    status_pub = h.pub[contract.FEATURE_STATUS] = h.node.create_publisher(
        DiagnosticArray, contract.FEATURE_STATUS, contract.RELIABLE)
    try:
        h.spin_until(lambda: status_pub.get_subscription_count() > 0, 'discovery')
        q_target = inverse_kinematics(paper.target_pose())
        q = q_target + np.radians([0.3, 0.2, -0.2, 0.0, 0.1, 0.0])
        sent = model.features(q).astype(np.float32).astype(float)
        left, right, pose = camera_messages(model)
        h.publish(contract.LEFT_INFO, left)
        h.publish(contract.RIGHT_INFO, right)
        h.publish(contract.STEREO_POSE, pose)
        h.spin_until(lambda: node.feedback is not None, 'camera model')
        frames = [n * CAMERA_NS for n in range(3)]
        for t in frames:
            h.publish(contract.FEATURES, features_msg(model.features(q), t))
        for t in (0, 34 * MS, 67 * MS):
            h.publish(contract.JOINT_STATES, joint_state(t, q, np.zeros(6)))
        h.spin_until(lambda: len(node._lockstep.frames) == 3
                     and len(node._lockstep.joints) == 3, 'inputs')
        out = h.received[contract.Q_FEEDBACK]
        assert out == [], 'a frame waits for its /ibvs/feature_status'
        for t, measured in zip(frames, (True, False, True)):
            h.publish(contract.FEATURE_STATUS, feature_status(t, measured))
        h.spin_until(lambda: len(out) == 3, 'q_feedback')
        ref = ClassicIBVS(model, paper.target_pose(), 1 / 30, node.gain, svd_damping=0.1,
                          feature_fallback='hold')
        for msg, measured in zip(out, (True, False, True)):
            up = ref.update(sent, q, measured=measured)
            np.testing.assert_allclose(read_joints(msg), up.q_feedback, atol=1e-9)
        np.testing.assert_allclose(read_joints(out[0]), read_joints(out[1]), atol=0.0)
    finally:
        h.close()


def test_vision_only_law_without_hold_stops_at_start(context):
    with pytest.raises(ParameterError, match="'feedforward_method'"):
        AdaptiveFeedbackNode(context=context,
                             parameter_overrides=overrides(servo_law='pbvs'))


def test_feedback_holds_on_bad_and_stale_features_and_freezes(context):
    model = default_model()
    node, h = feedback_harness(context, stale_timeout_s=0.1)
    try:
        left, right, pose = camera_messages(model)
        for topic, msg in ((contract.LEFT_INFO, left), (contract.RIGHT_INFO, right),
                           (contract.STEREO_POSE, pose)):
            h.publish(topic, msg)
        q_target = inverse_kinematics(paper.target_pose())
        q = q_target + np.radians(paper.DISTURBANCE_DEG)
        good = model.features(q)
        out = h.received[contract.Q_FEEDBACK]
        h.publish(contract.JOINT_STATES, joint_state(0, q_target, np.zeros(6)))
        h.publish(contract.FEATURES, features_msg(good, 0))
        h.spin_until(lambda: len(out) == 1, 'first q_feedback')
        held = read_joints(out[0])
        assert np.any(held != 0.0)
        state = node.feedback.filter.x.copy()
        # a NaN frame and a one-point frame: rejected, answered with the held value
        nan = features_msg(good, CAMERA_NS)
        nan.polygon.points[0].x = float('nan')
        one = features_msg(good, 2 * CAMERA_NS)
        one.polygon.points = one.polygon.points[:1]
        h.publish(contract.JOINT_STATES, joint_state(70 * MS, q_target, np.zeros(6)))
        h.publish(contract.FEATURES, nan)
        h.publish(contract.FEATURES, one)
        h.spin_until(lambda: len(out) == 3, 'held answers')
        assert stamps(out) == [0, CAMERA_NS, 2 * CAMERA_NS]
        for msg in out[1:]:
            np.testing.assert_array_equal(read_joints(msg), held)
        np.testing.assert_array_equal(node.feedback.filter.x, state)
        assert node.diagnostics.rejections['/ibvs/features: non-finite features'] == 1
        assert node.diagnostics.rejections['/ibvs/features: wrong feature count'] == 1
        # sim time moves on without usable features: frozen (logged, WARN on /diagnostics)
        h.publish(contract.JOINT_STATES, joint_state(400 * MS, q_target, np.zeros(6)))
        h.spin_until(lambda: node.frozen, 'frozen')
        assert node.diagnostics.level == DiagnosticStatus.WARN
        # a frame older than the timeout (sim time = newest joint state) is stale: held
        h.publish(contract.FEATURES, features_msg(good, 3 * CAMERA_NS))
        h.spin_until(lambda: len(out) == 4, 'stale answer')
        np.testing.assert_array_equal(read_joints(out[3]), held)
        assert node.diagnostics.rejections['/ibvs/features: stale features'] == 1
        assert node.frozen
        # a fresh frame resumes the integration
        h.publish(contract.JOINT_STATES, joint_state(12 * CAMERA_NS, q_target, np.zeros(6)))
        h.publish(contract.FEATURES, features_msg(good, 12 * CAMERA_NS))
        h.spin_until(lambda: len(out) == 5, 'fresh answer')
        assert not node.frozen and np.any(read_joints(out[4]) != held)
        # an old stamp again is not answered twice
        h.publish(contract.FEATURES, features_msg(good, 12 * CAMERA_NS))
        h.spin_until(lambda: node.diagnostics.rejections['/ibvs/features: stale stamp'] == 1,
                     'duplicate rejected')
        assert len(out) == 5
    finally:
        h.close()


# -- joint_controller_node ------------------------------------------------------------------

@contextmanager
def controller_harness(context, **params):
    """
    Yield a joint controller, a harness whose publishers it has matched, and its commands.

    The commands are the list of /joint_effort_commands the harness receives; the harness
    is closed on the way out.
    """
    node = JointControllerNode(context=context, parameter_overrides=overrides(**params))
    h = Harness(context, node)
    try:
        h.wait_matched([contract.JOINT_STATES, contract.FEEDFORWARD_TRAJECTORY,
                        contract.Q_FEEDBACK])
        yield node, h, h.received[contract.EFFORT_COMMANDS]
    finally:
        h.close()


@pytest.fixture(scope='module')
def dynamics():
    dyn = RobotDynamics()
    yield dyn
    dyn.close()


def test_joint_controller_waits_for_both_inputs_and_stamps_its_answer(context, dynamics):
    with controller_harness(context) as (node, h, out):
        h.publish(contract.JOINT_STATES, joint_state(0, Q0, np.zeros(6)))
        h.spin_until(lambda: len(node.mode._lockstep.states) == 1, 'joint state buffered')
        assert node.mode._missing(0)[0].startswith('the feedforward trajectory')
        # Q0 at t = 0, then Q0 + 0.01, held after its last point (2 ms)
        h.publish(contract.FEEDFORWARD_TRAJECTORY, trajectory(0, [Q0, Q0 + 0.01, Q0 + 0.01]))
        h.spin_until(lambda: node.mode._trajectory is not None, 'the trajectory')
        # frame 0 acts at t = 0 (latency 0): still waiting for its q_feedback
        assert node.mode.commands == 0 and node.mode._missing(0) == [
            f'{contract.Q_FEEDBACK} of frame 0 ns (or its {contract.FRAME_LOST})']
        h.publish(contract.Q_FEEDBACK, joint_state(0, np.zeros(6)))
        h.spin_until(lambda: len(out) == 1, 'effort command')
        assert stamps(out) == [0]
        # at rest on its reference: u = h(q, 0), gravity compensation
        np.testing.assert_allclose(read_joints(out[0], 'effort'),
                                   dynamics.bias(Q0, np.zeros(6)), rtol=1e-9, atol=1e-9)
        # next steps: frame 0's q_feedback still applies until frame 1 (due at 33.33 ms,
        # rendered from and stamped with the step at 34 ms)
        q_fb = np.full(6, 0.001)
        h.publish(contract.Q_FEEDBACK, joint_state(34 * MS, q_fb))
        loop = JointLoop(0.01, 1e-3)
        loop.step(Q0, Q0, np.zeros(6))
        for k in (1, 2):
            q, qd = Q0 + 1e-4 * k, np.full(6, 0.01 * k)
            h.publish(contract.JOINT_STATES, joint_state(k * MS, q, qd))
            h.spin_until(lambda: len(out) == k + 1, f'effort command {k}')
            expected = loop.step(Q0 + 0.01, q, qd, dynamics.mass_matrix(q),
                                 dynamics.bias(q, qd))
            np.testing.assert_allclose(read_joints(out[k], 'effort'), expected, rtol=1e-9)
        # t = 34 ms: frame 1 applies
        q = Q0
        h.publish(contract.JOINT_STATES, joint_state(34 * MS, q, np.zeros(6)))
        h.spin_until(lambda: len(out) == 4, 'effort command at 34 ms')
        expected = loop.step(Q0 + 0.01 + q_fb, q, np.zeros(6), dynamics.mass_matrix(q),
                             dynamics.bias(q, np.zeros(6)))
        np.testing.assert_allclose(read_joints(out[3], 'effort'), expected, rtol=1e-9)
        assert stamps(out) == [0, MS, 2 * MS, 34 * MS]


def test_the_effort_controller_reports_its_status_and_relays_the_feedbacks(context):
    with controller_harness(context) as (node, h, out):
        status = []
        h.node.create_subscription(Int8, contract.SERVO_STATUS,
                                   lambda m: status.append(ServoStatus(m.data)),
                                   contract.LATCHED)
        feedback_status = h.node.create_publisher(Int8, contract.FEEDBACK_STATUS,
                                                  contract.LATCHED)
        h.spin_until(lambda: feedback_status.get_subscription_count() > 0, 'discovery')
        h.publish(contract.FEEDFORWARD_TRAJECTORY, trajectory(0, [Q0]))
        h.publish(contract.JOINT_STATES, joint_state(0, Q0, np.zeros(6)))
        h.spin_until(lambda: len(node.mode._lockstep.states) == 1, 'joint state buffered')
        assert status == []  # nothing before the first command
        h.publish(contract.Q_FEEDBACK, joint_state(0, np.zeros(6)))
        h.spin_until(lambda: len(out) == 1 and status, 'the first command and status')
        assert status == [ServoStatus.NO_WARNING]
        feedback_status.publish(Int8(data=int(ServoStatus.LOCAL_MINIMUM)))
        h.spin_until(lambda: len(status) == 2, 'the relayed status')
        assert status[-1] == ServoStatus.LOCAL_MINIMUM
        assert node.diagnostics.values['servo_status'] == 'LOCAL_MINIMUM'
        feedback_status.publish(Int8(data=int(ServoStatus.NO_WARNING)))
        h.spin_until(lambda: len(status) == 3, 'the status back')
        assert status[-1] == ServoStatus.NO_WARNING and len(out) == 1


def test_joint_controller_with_latency_needs_no_feedback_at_first(context):
    node = JointControllerNode(context=context,
                               parameter_overrides=overrides(feedback_latency_s=0.02))
    h = Harness(context, node)
    try:
        h.wait_matched([contract.JOINT_STATES, contract.FEEDFORWARD_TRAJECTORY])
        out = h.received[contract.EFFORT_COMMANDS]
        h.publish(contract.FEEDFORWARD_TRAJECTORY, trajectory(0, [Q0]))
        for k in (0, 19):
            h.publish(contract.JOINT_STATES, joint_state(k * MS, Q0, np.zeros(6)))
        h.spin_until(lambda: len(out) == 2, 'answers before the first frame acts')
        h.publish(contract.JOINT_STATES, joint_state(20 * MS, Q0, np.zeros(6)))
        h.spin_until(lambda: len(node.mode._lockstep.states) == 1, 'joint state at 20 ms buffered')
        assert node.mode._missing(20 * MS) == [
            f'{contract.Q_FEEDBACK} of frame 0 ns (or its {contract.FRAME_LOST})']
        h.publish(contract.Q_FEEDBACK, joint_state(0, np.zeros(6)))
        h.spin_until(lambda: len(out) == 3, 'answer at 20 ms')
        assert stamps(out) == [0, 19 * MS, 20 * MS]
    finally:
        h.close()


def test_joint_controller_rejects_bad_input(context):
    with controller_harness(context) as (node, h, out):
        h.publish(contract.JOINT_STATES, joint_state(0, [np.nan] * 6, np.zeros(6)))
        h.publish(contract.JOINT_STATES, joint_state(0, Q0, [0.0] * 3))
        h.publish(contract.FEEDFORWARD_TRAJECTORY, trajectory(0, [[0.0] * 7]))
        h.publish(contract.Q_FEEDBACK, joint_state(0, [np.inf] * 6))
        h.spin_until(lambda: node.diagnostics.rejected_total == 4, 'rejections')
        wrong_period = joint_trajectory(0, 2 * MS, [Q0, Q0])
        h.publish(contract.FEEDFORWARD_TRAJECTORY, wrong_period)
        h.spin_until(lambda: node.diagnostics.rejected_total == 5, 'wrong sample period')
        for topic, msg in ((contract.FEEDFORWARD_TRAJECTORY, trajectory(0, [Q0])),
                           (contract.Q_FEEDBACK, joint_state(0, np.zeros(6))),
                           (contract.JOINT_STATES, joint_state(0, Q0, np.zeros(6)))):
            h.publish(topic, msg)
        h.spin_until(lambda: len(out) == 1, 'answer')
        h.publish(contract.JOINT_STATES, joint_state(0, Q0, np.zeros(6)))  # answered already
        h.spin_until(lambda: node.diagnostics.rejected_total == 6, 'stale rejection')
        assert len(out) == 1
        assert node.diagnostics.rejections['/joint_states: stale stamp'] == 1
        assert node.diagnostics.rejections[
            '/ibvs/feedforward_trajectory: wrong positions length'] == 1
        assert node.diagnostics.rejections[
            '/ibvs/feedforward_trajectory: wrong sample times'] == 1
        assert node.diagnostics.rejections['/joint_states: non-finite position'] == 1
        assert node.diagnostics.rejections['/joint_states: wrong velocity length'] == 1


def test_joint_controller_rejects_stamps_from_the_future_and_answers_the_good_ones(context):
    """A far-future /joint_states is not buffered, where every good one after would be stale."""
    with controller_harness(context, use_sim_time=True) as (node, h, out):
        h.publish(contract.FEEDFORWARD_TRAJECTORY, trajectory(0, [Q0]))
        h.publish(contract.Q_FEEDBACK, joint_state(0, np.zeros(6)))
        h.publish(contract.JOINT_STATES, joint_state(0, Q0, np.zeros(6)))
        h.spin_until(lambda: len(out) == 1, 'answer at 0')
        # no /clock here: the bound is the last answered stamp (0) + stale_timeout_s
        for stamp in (Time(sec=1_000_000), Time(sec=0, nanosec=600 * MS),
                      Time(sec=0, nanosec=4_000_000_000)):
            h.publish(contract.JOINT_STATES, joint_state(stamp, Q0, np.zeros(6)))
        h.spin_until(lambda: node.diagnostics.rejected_total == 3, 'rejections')
        assert node.diagnostics.rejections == {
            '/joint_states: stamp in the future': 2, '/joint_states: malformed stamp': 1}
        for k in (1, 2, 30):  # good states (frame 0's q_feedback acts until 33.3 ms)
            h.publish(contract.JOINT_STATES, joint_state(k * MS, Q0, np.zeros(6)))
        h.spin_until(lambda: len(out) == 4, 'answers after the bad ones')
        assert stamps(out) == [0, MS, 2 * MS, 30 * MS] and not node.mode._lockstep.states


def test_joint_controller_rejects_unusable_q_feedback_and_recovers(context, dynamics):
    """q_feedback: six finite positions by name, within the joint travel; finite or no rest."""
    with controller_harness(context) as (node, h, out):
        h.publish(contract.FEEDFORWARD_TRAJECTORY, trajectory(0, [Q0]))
        h.publish(contract.JOINT_STATES, joint_state(0, Q0, np.zeros(6)))
        unnamed = joint_state(0, np.zeros(6))
        unnamed.name = []
        bad = [joint_state(0, np.full(6, 1e308)),
               joint_state(0, np.r_[np.zeros(5), -15.0]),
               joint_state(0, np.zeros(6), velocity=[np.nan] * 6),
               joint_state(0, np.zeros(6), effort=[0.0] * 5 + [np.inf]),
               unnamed]
        for msg in bad:
            h.publish(contract.Q_FEEDBACK, msg)
        h.spin_until(lambda: node.diagnostics.rejected_total == len(bad), 'rejections')
        assert node.diagnostics.rejections == {
            '/ibvs/q_feedback: out of range': 2, '/ibvs/q_feedback: non-finite velocity': 1,
            '/ibvs/q_feedback: non-finite effort': 1, '/ibvs/q_feedback: no joint names': 1}
        assert not out  # none of them was taken for frame 0
        # a good q_feedback of the same frame still gets in, and the loop is sound
        h.publish(contract.Q_FEEDBACK, joint_state(0, np.zeros(6), velocity=np.zeros(6)))
        h.spin_until(lambda: len(out) == 1, 'answer')
        np.testing.assert_allclose(read_joints(out[0], 'effort'),
                                   dynamics.bias(Q0, np.zeros(6)), rtol=1e-9, atol=1e-9)
        # the joint's whole travel is the bound: J4 and J6 turn +-400 deg
        assert node.diagnostics.rejected_total == len(bad)
        frame1 = frame_stamp_ns(1, CAMERA_NS, MS)  # frame 1 on the physics grid: 34 ms
        h.publish(contract.Q_FEEDBACK, joint_state(frame1, np.r_[np.zeros(5), 13.9]))
        h.spin_until(lambda: frame1 in node.mode._lockstep.feedback,
                     'a large but possible J6 correction')


def test_limited_joint_controller_clips_torque(context, dynamics):
    node = JointControllerNode(context=context, parameter_overrides=overrides(
        actuators='limited', torque_limits=[50.0, 0.0, 0.0, 0.0, 0.0, 0.0]))
    h = Harness(context, node)
    try:
        np.testing.assert_allclose(node.mode.torque_limits[1:], dynamics.torque_limits[1:])
        assert node.mode.torque_limits[0] == 50.0
        h.wait_matched([contract.JOINT_STATES, contract.FEEDFORWARD_TRAJECTORY,
                        contract.Q_FEEDBACK])
        out = h.received[contract.EFFORT_COMMANDS]
        h.publish(contract.Q_FEEDBACK, joint_state(0, np.zeros(6)))
        h.publish(contract.FEEDFORWARD_TRAJECTORY, trajectory(0, [Q0 + 1.0]))
        for k in range(3):
            h.publish(contract.JOINT_STATES, joint_state(k * MS, Q0, np.zeros(6)))
        h.spin_until(lambda: len(out) == 3, 'answers')
        efforts = np.array([read_joints(m, 'effort') for m in out])
        assert np.all(np.abs(efforts) <= node.mode.torque_limits + 1e-9)
    finally:
        h.close()


# -- several nodes on one executor ----------------------------------------------------------

def test_feedforward_and_joint_controller_in_lockstep_with_a_stand_in_plant(context):
    """A stand-in plant publishes /joint_states and waits for the command of each step."""
    ff = FeedforwardNode(context=context)
    jc = JointControllerNode(context=context)
    h = Harness(context, ff, jc)
    try:
        h.wait_matched([contract.JOINT_STATES, contract.Q_FEEDBACK])
        h.spin_until(lambda: h.pub[contract.JOINT_STATES].get_subscription_count() >= 2,
                     'both subscribers')
        q = inverse_kinematics(paper.scenario_start_pose(1))
        qd = np.zeros(6)
        out = h.received[contract.EFFORT_COMMANDS]
        h.publish(contract.Q_FEEDBACK, joint_state(0, np.zeros(6)))
        dyn = jc.mode.dynamics
        for k in range(10):
            h.publish(contract.JOINT_STATES, joint_state(k * MS, q, qd))
            h.spin_until(lambda: len(out) == k + 1, f'command {k}')
            assert stamps(out)[-1] == k * MS
            u = read_joints(out[-1], 'effort')
            acc = np.linalg.solve(dyn.mass_matrix(q), u - dyn.bias(q, qd))
            q, qd = q + qd * 1e-3 + 0.5 * acc * 1e-6, qd + acc * 1e-3
        assert len(h.received[contract.FEEDFORWARD_TRAJECTORY]) == 1
        # the arm has started toward the target (feedforward through the inner loop)
        q_target = ff.ff.q_target
        q_start = inverse_kinematics(paper.scenario_start_pose(1))
        assert np.linalg.norm(q - q_target) < 0.5 * np.linalg.norm(q_start - q_target)
    finally:
        h.close()


def test_joint_controller_holds_the_last_q_feedback_through_a_lost_frame(context, dynamics):
    node = JointControllerNode(context=context)
    h = Harness(context, node)
    lost_pub = h.node.create_publisher(Header, contract.FRAME_LOST, contract.RELIABLE)
    try:
        h.wait_matched([contract.JOINT_STATES, contract.FEEDFORWARD_TRAJECTORY,
                        contract.Q_FEEDBACK])
        h.spin_until(lambda: lost_pub.get_subscription_count() > 0, 'discovery')
        out = h.received[contract.EFFORT_COMMANDS]
        h.publish(contract.FEEDFORWARD_TRAJECTORY, trajectory(0, [Q0]))
        q_fb = np.full(6, 0.002)
        h.publish(contract.Q_FEEDBACK, joint_state(0, q_fb))
        h.publish(contract.JOINT_STATES, joint_state(0, Q0, np.zeros(6)))
        h.spin_until(lambda: len(out) == 1, 'answer at 0')
        # frame 1 (due at 33.33 ms, stamped 34 ms) is lost: at 34 ms the controller would wait
        # for its q_feedback
        h.publish(contract.JOINT_STATES, joint_state(34 * MS, Q0, np.zeros(6)))
        h.spin_until(lambda: len(node.mode._lockstep.states) == 1, 'joint state at 34 ms buffered')
        assert node.mode.commands == 1
        lost_pub.publish(Header(stamp=joint_state(34 * MS, Q0).header.stamp))
        h.spin_until(lambda: len(out) == 2, 'answer at 34 ms')
        # ... and it holds frame 0's q_feedback
        loop = JointLoop(0.01, 1e-3)
        mass, bias = dynamics.mass_matrix(Q0), dynamics.bias(Q0, np.zeros(6))
        loop.step(Q0 + q_fb, Q0, np.zeros(6), mass, bias)
        expected = loop.step(Q0 + q_fb, Q0, np.zeros(6), mass, bias)
        np.testing.assert_allclose(read_joints(out[1], 'effort'), expected, rtol=1e-9)
        assert node.mode.frames_lost == 1
        # a q_feedback for the lost frame is rejected, frame 2 applies again
        h.publish(contract.Q_FEEDBACK, joint_state(34 * MS, np.zeros(6)))
        rejected = node.diagnostics.rejections
        h.spin_until(lambda: rejected[f'{contract.Q_FEEDBACK}: frame was lost'] == 1,
                     'rejection of a lost frame')
    finally:
        h.close()


def test_feedback_rejects_an_unknown_target_features_source(context):
    with pytest.raises(ParameterError, match="'target_features_source'"):
        AdaptiveFeedbackNode(context=context, parameter_overrides=overrides(
            target_features_source='camera'))


def test_feedback_says_what_a_pending_frame_waits_for(context):
    """A frame whose camera model or joint state has not come is named, never silent."""
    node = AdaptiveFeedbackNode(context=context)
    try:
        assert node._missing() == []
        node._on_features(features_msg(np.arange(6.0), 0))
        (line,) = node._missing()
        assert line.startswith('frame 0 ns waits for ')
        for topic in (contract.LEFT_INFO, contract.RIGHT_INFO, contract.STEREO_POSE,
                      contract.JOINT_STATES):
            assert topic in line
        node.waiting.tick()  # the timer's tick: publishes it on /diagnostics too
        assert node.diagnostics.values['waiting_for'] == line
    finally:
        node.destroy_node()
