"""
A real cell's joint states into the feature and feedback nodes.

abb_ros2's joint_state_broadcaster publishes /joint_states at the controller manager's
250 Hz, stamped on its own cycle, never at the camera's exposure. Here 30 Hz stereo frames
(synthetic VGA pairs of the markers at the true angles) and 250 Hz joint states on an
unaligned cycle with +-0.5 ms of jitter go into feature_node and adaptive_feedback_node in
one executor; the arm moves (a slow sine on every joint), so a state taken at the wrong
stamp would be visibly wrong. Every frame after the first joint state must produce features
and a q_feedback, and the state each node used must be the true one at the frame's stamp.
"""

from geometry_msgs.msg import PolygonStamped, PoseStamped
from ibvs_common import contract
from ibvs_common.conversions import (camera_infos, image_msg, joint_state, ns_stamp,
                                     pose_stamped, stamp_ns)
from ibvs_common.sync import Rejection
from ibvs_control.adaptive_feedback_node import AdaptiveFeedbackNode
from ibvs_model import default_camera, fiducial_points, inverse_kinematics, paper
from ibvs_testing.fixtures import spin_until
from ibvs_vision import synthetic
from ibvs_vision.feature_node import FeatureNode
import numpy as np
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, JointState

MS = 1_000_000
FRAMES = 45                       # 1.5 s at 30 Hz
JOINT_PERIOD_NS = 4 * MS          # 250 Hz
JOINT_OFFSET_NS = 1_234_567       # the controller manager's cycle, not the camera's
JITTER_NS = 0.5 * MS
D_Q = np.radians(paper.DISTURBANCE_DEG)
Q_MID = inverse_kinematics(paper.target_pose()) - D_Q
AMPLITUDE = 0.01                  # rad: the markers stay in view
OMEGA = 2 * np.pi * 1.5           # rad/s


def q_true(t_ns):
    """Return the encoder angles at ``t_ns`` (a slow sine on every joint)."""
    return Q_MID + AMPLITUDE * np.sin(OMEGA * t_ns * 1e-9 + np.arange(6))


def qd_true(t_ns):
    return AMPLITUDE * OMEGA * np.cos(OMEGA * t_ns * 1e-9 + np.arange(6))


class Cell(Node):
    """The camera and the arm's driver: images, camera_info, pose, /joint_states at 250 Hz."""

    def __init__(self, context):
        super().__init__('cell', context=context)
        pub = self.create_publisher
        self.pub = {
            'clock': pub(Clock, contract.CLOCK, contract.RELIABLE),
            'joints': pub(JointState, contract.JOINT_STATES, contract.RELIABLE),
            'left': pub(Image, contract.LEFT_IMAGE, contract.IMAGES),
            'right': pub(Image, contract.RIGHT_IMAGE, contract.IMAGES),
            'left_info': pub(CameraInfo, contract.LEFT_INFO, contract.IMAGES),
            'right_info': pub(CameraInfo, contract.RIGHT_INFO, contract.IMAGES),
            'pose': pub(PoseStamped, contract.STEREO_POSE, contract.LATCHED),
        }
        self.features = []
        self.q_feedback = []
        self.create_subscription(PolygonStamped, contract.FEATURES, self.features.append,
                                 contract.RELIABLE)
        self.create_subscription(JointState, contract.Q_FEEDBACK, self.q_feedback.append,
                                 contract.RELIABLE)


def test_30_hz_frames_with_250_hz_joint_states_on_their_own_cycle(context):
    camera = default_camera('VGA')
    rng = np.random.default_rng(34)
    params = [Parameter('use_sim_time', value=True)]
    feature = FeatureNode(context=context, parameter_overrides=params)
    feedback = AdaptiveFeedbackNode(context=context, parameter_overrides=params)
    cell = Cell(context)
    executor = SingleThreadedExecutor(context=context)
    for node in (feature, feedback, cell):
        executor.add_node(node)
    used = {'feature': {}, 'feedback': {}}
    process, answer = feature._process, feedback._answer

    def spy_process(t_ns, images, joints):
        used['feature'][t_ns] = joints
        return process(t_ns, images, joints)

    def spy_answer(t_ns, features, joints, measured=True):
        used['feedback'][t_ns] = joints
        return answer(t_ns, features, joints, measured)

    feature._process, feedback._answer = spy_process, spy_answer
    try:
        # both nodes read the clock, the joint states, camera_info and the pose
        readers = {'left': 1, 'right': 1}
        spin_until(executor, lambda: all(p.get_subscription_count() >= readers.get(k, 2)
                                         for k, p in cell.pub.items()), what='discovery')
        cell.pub['pose'].publish(pose_stamped(camera.pose_C_O, 0))
        joint_stamps = iter(sorted(
            int(JOINT_OFFSET_NS + k * JOINT_PERIOD_NS + rng.uniform(-JITTER_NS, JITTER_NS))
            for k in range(FRAMES * 9)))
        next_joint = next(joint_stamps)
        frames = [round(n * 1e9 / 30) for n in range(1, FRAMES + 1)]
        for n, t in enumerate(frames, start=1):
            # the arm's driver goes on until its first state after the frame's exposure
            while True:
                cell.pub['clock'].publish(Clock(clock=ns_stamp(next_joint)))
                cell.pub['joints'].publish(joint_state(next_joint, q_true(next_joint),
                                                       qd_true(next_joint)))
                published, next_joint = next_joint, next(joint_stamps)
                if published > t:
                    break
            left, right = synthetic.render_stereo(camera, fiducial_points(q_true(t) + D_Q),
                                                  rng, clutter=10)
            for side, info in zip(('left_info', 'right_info'),
                                  camera_infos(camera.intrinsics, t)):
                cell.pub[side].publish(info)
            cell.pub['left'].publish(image_msg(left, t, 'rgb8'))
            cell.pub['right'].publish(image_msg(right, t, 'rgb8'))
            # processed, or dropped with a count (the old one-physics-step rule dropped most)
            spin_until(executor, lambda: len(used['feature'])
                       + sum(feature._diag.rejections.values()) >= n
                       and len(cell.q_feedback) >= len(cell.features), what=f'frame {n}')
        spin_until(executor, lambda: len(cell.features) == len(used['feature'])
                   and len(cell.q_feedback) == len(cell.features), what='the last q_feedback')
    finally:
        executor.shutdown()
        for node in (feature, feedback, cell):
            node.destroy_node()
    featured = [stamp_ns(m.header.stamp) for m in cell.features]
    answered = {stamp_ns(m.header.stamp) for m in cell.q_feedback}
    assert len(featured) >= 0.98 * FRAMES and set(featured) <= set(frames)
    fed_back = [t for t in featured if t in answered
                and not isinstance(used['feedback'][t], Rejection)]
    assert len(fed_back) >= 0.98 * FRAMES
    for t in featured:
        np.testing.assert_allclose(used['feature'][t], q_true(t), rtol=0, atol=1e-4)
    for t in fed_back:
        q, qd = used['feedback'][t]
        np.testing.assert_allclose(q, q_true(t), rtol=0, atol=1e-4)
        np.testing.assert_allclose(qd, qd_true(t), rtol=0, atol=1e-3)
    # the state is interpolated, not the nearest one: the nearest is up to 2.5 ms away
    nearest_error = max(np.max(np.abs(q_true(t) - q_true(t + 2 * MS))) for t in featured)
    assert nearest_error > 1e-4
