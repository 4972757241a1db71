"""
viz_node in an rclpy executor: what a viewer gets from camera, joint states and features.

A driver node publishes the simulator's and the feature node's topics; the viz node's
/tf_static and /ibvs/markers are checked against ibvs_model, with ABB's tool0 (where the
cell's robot_state_publisher, or ibvs_sim's robot_state_node, puts it). It publishes neither
/robot_description nor /tf.
"""


from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PolygonStamped, PoseStamped
from ibvs_common import contract
from ibvs_common.contract import MARKERS, ROBOT_DESCRIPTION, TF, TF_STATIC
from ibvs_common.conversions import (camera_infos, feature_status_msg, features_msg,
                                     FeatureStatus, joint_state, pose_matrix, pose_stamped)
from ibvs_common.params import ParameterError
from ibvs_model import (abb_urdf, CameraRobotModel, default_camera, forward_kinematics,
                        IRB4600, paper)
from ibvs_model.robot import fiducial_points
from ibvs_testing.fixtures import spin_until
from ibvs_viz import scene
from ibvs_viz.viz_node import (NS_CAMERA, NS_ESTIMATED, NS_MEASURED, NS_PATH, NS_TOOL,
                               VizNode)
import numpy as np
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

D_Q_DEG = [0.5, -0.3, 0.2, 0.0, 0.4, -0.6]
Q = np.array([0.1, 0.2, -0.1, 0.3, 0.5, -0.2])


class Driver(Node):
    """Publishes camera, joint states and features; keeps what the viz node publishes."""

    def __init__(self, context):
        super().__init__('driver', context=context)
        self.got = {ROBOT_DESCRIPTION: [], TF_STATIC: [], TF: [], MARKERS: [], 'diag': []}
        self.pub = {
            'joints': self.create_publisher(JointState, contract.JOINT_STATES,
                                            contract.RELIABLE),
            'left_info': self.create_publisher(CameraInfo, contract.LEFT_INFO,
                                               contract.RELIABLE),
            'right_info': self.create_publisher(CameraInfo, contract.RIGHT_INFO,
                                                contract.RELIABLE),
            'pose': self.create_publisher(PoseStamped, contract.STEREO_POSE, contract.LATCHED),
            'features': self.create_publisher(PolygonStamped, contract.FEATURES,
                                              contract.RELIABLE),
            'status': self.create_publisher(DiagnosticArray, contract.FEATURE_STATUS,
                                            contract.RELIABLE),
        }
        for topic, kind, qos in ((ROBOT_DESCRIPTION, String, contract.LATCHED),
                                 (TF_STATIC, TFMessage, contract.LATCHED),
                                 (TF, TFMessage, 100), (MARKERS, MarkerArray, 10)):
            self.create_subscription(kind, topic, self.got[topic].append, qos)
        self.create_subscription(DiagnosticArray, contract.DIAGNOSTICS, self._on_diag, 10)

    def _on_diag(self, msg):
        for status in msg.status:
            if status.name.startswith('viz_node'):
                self.got['diag'].append({kv.key: kv.value for kv in status.values})

    def camera(self, camera):
        left, right = camera_infos(camera.intrinsics, 0)
        self.pub['left_info'].publish(left)
        self.pub['right_info'].publish(right)
        self.pub['pose'].publish(pose_stamped(camera.pose_C_O, 0))

    def status(self, t_ns, mode):
        self.pub['status'].publish(feature_status_msg(
            FeatureStatus(mode, mode, mode, 0.0, 'full'), t_ns, name='feature_node: features'))


@pytest.fixture
def rig(context, executor_of):
    params = [Parameter('disturbance_deg', value=D_Q_DEG),
              Parameter('marker_rate_hz', value=10.0)]
    node = VizNode(context=context, parameter_overrides=params)
    driver = Driver(context)
    executor = executor_of(node, driver)
    spin_until(executor, lambda: driver.count_subscribers(contract.JOINT_STATES) == 1
               and driver.count_subscribers(contract.FEATURE_STATUS) == 1, what='discovery')
    return executor, driver, node


def has_camera(driver):
    """Whether the newest /tf_static has the camera's frames."""
    return bool(driver.got[TF_STATIC]) and contract.CAMERA_FRAME in {
        t.child_frame_id for t in driver.got[TF_STATIC][-1].transforms}


def chain(tf_messages, known=None):
    """
    Compose the transforms of TFMessages from base_link, as a tf listener does.

    ``known``: {frame: T_frame^base_link} of frames another node publishes (the arm's).
    """
    local = {t.child_frame_id: (t.header.frame_id, t.transform)
             for msg in tf_messages for t in msg.transforms}
    known = {contract.BASE_FRAME: np.eye(4), **(known or {})}

    def pose(frame):
        if frame in known:
            assert frame not in local, f'{frame} published by the viz node too'
            return known[frame]
        parent, tf = local[frame]
        m = pose_matrix(type('Pose', (), {'position': tf.translation,
                                          'orientation': tf.rotation}))
        return pose(parent) @ m
    return pose


def test_static_frames_match_the_model_and_nothing_of_the_arm_is_published(rig):
    executor, driver, node = rig
    # Before the camera is known: the tool on tool0 and the target.
    spin_until(executor, lambda: driver.got[TF_STATIC], what='the first /tf_static')
    true_q = Q + np.radians(D_Q_DEG)
    arm = abb_urdf.link_poses(true_q)  # what robot_state_publisher gives a listener
    first = chain([driver.got[TF_STATIC][-1]], arm)
    assert {t.child_frame_id for t in driver.got[TF_STATIC][-1].transforms} == {
        'screwdriver', 'marker_1', 'marker_2', scene.TARGET_FRAME}
    np.testing.assert_allclose(first('screwdriver'), forward_kinematics(true_q), atol=1e-12)
    markers = np.array([first('marker_1')[:3, 3], first('marker_2')[:3, 3]])
    np.testing.assert_allclose(markers, fiducial_points(true_q), atol=1e-12)
    camera = default_camera('VGA')
    driver.camera(camera)
    spin_until(executor, lambda: has_camera(driver), what='/tf_static with the camera')
    driver.pub['joints'].publish(joint_state(34_000_000, Q))
    spin_until(executor, lambda: driver.got[MARKERS], what='markers')
    assert not driver.got[ROBOT_DESCRIPTION] and not driver.got[TF]
    pose = chain([driver.got[TF_STATIC][-1]], arm)
    np.testing.assert_allclose(pose('marker_2')[:3, 3], fiducial_points(true_q)[1],
                               atol=1e-12)
    np.testing.assert_allclose(pose(contract.CAMERA_FRAME), camera.pose_C_O, atol=1e-9)
    target = paper.target_pose(paper.TARGET_POSITION, np.ravel(paper.TARGET_ROTATION))
    np.testing.assert_allclose(pose(scene.TARGET_FRAME), target, atol=1e-9)
    # The shapes no URDF of the cell has, drawn in their frames.
    drawn = {(m.ns, m.header.frame_id) for m in driver.got[MARKERS][-1].markers}
    assert {(NS_TOOL, f) for f in scene.TOOL_FRAMES} | {(NS_CAMERA, contract.CAMERA_FRAME)} \
        <= drawn


def test_tool_frames_stay_off_where_the_cells_urdf_has_them(context, executor_of):
    node = VizNode(context=context,
                   parameter_overrides=[Parameter('tool_frames_tf', value=False)])
    driver = Driver(context)
    executor = executor_of(node, driver)
    spin_until(executor, lambda: driver.got[TF_STATIC], what='/tf_static')
    assert [t.child_frame_id for t in driver.got[TF_STATIC][-1].transforms] == [
        scene.TARGET_FRAME]


def test_the_frames_the_images_name_are_placed_at_the_lenses(rig):
    # The ZED wrapper's images carry zed_{left,right}_camera_frame_optical.
    executor, driver, node = rig
    camera = default_camera('VGA')
    infos = camera_infos(camera.intrinsics, 0,
                         (contract.ZED_LEFT_FRAME, contract.ZED_RIGHT_FRAME))
    for side, info in zip(('left_info', 'right_info'), infos):
        driver.pub[side].publish(info)
    driver.pub['pose'].publish(pose_stamped(camera.pose_C_O, 0))
    spin_until(executor, lambda: has_camera(driver), what='/tf_static with the camera')
    pose = chain([driver.got[TF_STATIC][-1]])
    for ours, theirs in zip(scene.LENS_FRAMES,
                            (contract.ZED_LEFT_FRAME, contract.ZED_RIGHT_FRAME)):
        np.testing.assert_array_equal(pose(theirs), pose(ours))
    np.testing.assert_allclose(pose(contract.ZED_LEFT_FRAME)[:3, 3],
                               camera.pose_C_O[:3, :3] @ [-camera.intrinsics.baseline / 2, 0, 0]
                               + camera.pose_C_O[:3, 3], atol=1e-12)
    # A frame id that names a frame of the cell would loop the tree: refused, counted.
    before = len(driver.got[TF_STATIC])
    left, right = camera_infos(camera.intrinsics, 0, ('base_link', contract.ZED_RIGHT_FRAME))
    driver.pub['left_info'].publish(left)
    spin_until(executor, lambda: len(driver.got[TF_STATIC]) > before, what='/tf_static again')
    children = [t.child_frame_id for t in driver.got[TF_STATIC][-1].transforms]
    assert contract.ZED_RIGHT_FRAME in children and children.count('base_link') == 0
    spin_until(executor, lambda: any(
        d.get(f'rejected[{contract.LEFT_INFO}: frame_id not publishable]') == '1'
        for d in driver.got['diag']), what='the rejection on /diagnostics')


def test_markers_show_measured_and_estimated_fiducials(rig):
    executor, driver, node = rig
    camera = default_camera('VGA')
    driver.camera(camera)
    spin_until(executor, lambda: driver.got[TF_STATIC], what='/tf_static')
    true_q = Q + np.radians(D_Q_DEG)
    measured = CameraRobotModel(camera, IRB4600).features(true_q)
    for k, (t_ns, mode) in enumerate(((0, 'estimated'), (100_000_000, 'measured'))):
        driver.pub['features'].publish(features_msg(measured, joint_state(t_ns).header.stamp))
        driver.status(t_ns, mode)
        spin_until(executor, lambda: (node.measured is not None) == (mode == 'measured')
                   and not node._features, what='the feature status')
        driver.pub['joints'].publish(joint_state(t_ns, Q))
        spin_until(executor, lambda: len(driver.got[MARKERS]) == k + 1, what='markers')
    first, second = ({(m.ns, m.id): m for m in a.markers} for a in driver.got[MARKERS])
    assert first[(NS_MEASURED, 0)].action == Marker.DELETE   # not measured: not drawn
    points = np.array([[p.x, p.y, p.z] for p in second[(NS_MEASURED, 0)].points])
    np.testing.assert_allclose(points, fiducial_points(true_q), atol=1e-4)  # float32 px
    estimated = np.array([[p.x, p.y, p.z] for p in second[(NS_ESTIMATED, 0)].points])
    np.testing.assert_allclose(estimated, fiducial_points(Q), atol=1e-12)
    assert len(second[(NS_PATH, 0)].points) == 2


def test_bad_joint_state_is_rejected_and_counted(rig):
    executor, driver, node = rig
    bad = joint_state(0, [np.nan] * 6)
    driver.pub['joints'].publish(bad)
    spin_until(executor, lambda: any(
        d.get('rejected[/joint_states: non-finite position]') == '1'
        for d in driver.got['diag']), what='the rejection on /diagnostics')
    assert node._diag.values['joint_states_taken'] == 0


def test_bad_parameter_is_refused_with_its_range(context):
    with pytest.raises(ParameterError, match='marker_rate_hz'):
        VizNode(context=context, parameter_overrides=[Parameter('marker_rate_hz', value=0.0)])
    with pytest.raises(ParameterError, match='image_frames_tf'):
        VizNode(context=context, parameter_overrides=[Parameter('image_frames_tf', value=2)])
    with pytest.raises(ParameterError, match='tool_frames_tf'):
        VizNode(context=context, parameter_overrides=[Parameter('tool_frames_tf', value=1)])
