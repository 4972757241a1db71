"""
Absurd cameras, duplicate stamps and upstream's refusals into the nodes, one test each.

On the fuzz rigs (:mod:`.rigs`), with the check that the suite's non-finite scan can fail.

Each test sends inputs a node could take for valid and checks what must hold instead:
refused with its reason under its topic (the resolved name), nothing non-finite published,
and the node still acting on the next valid input.
"""

from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point32, PolygonStamped
from ibvs_common import contract
from ibvs_common.conversions import camera_infos, image_msg, joint_state, joint_trajectory
import numpy as np
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo

from . import rigs
from .harness import non_finite_fields, Rig
from .rigs import MS, Q0


def _run(rig):
    rig.setup()
    assert rig.recovered()
    return rig


def _absurd_cameras(intrinsics):
    """Return two absurd pairs: f_u = 1e308 (right P[3] -1e308), and a right P[3] -1e300."""
    left, right = camera_infos(intrinsics, 0)
    for info in (left, right):
        p = list(info.p)
        p[0] = 1e308
        info.p = p
    p = list(right.p)
    p[3] = -1e308
    right.p = p
    only_p3 = camera_infos(intrinsics, 0)[1]
    p = list(only_p3.p)
    p[3] = -1e300
    only_p3.p = p
    return (left, right), only_p3


def test_the_non_finite_scan_finds_nan_and_inf_anywhere_in_a_message():
    features = PolygonStamped()
    features.polygon.points = [Point32(x=1.0, y=2.0, z=3.0), Point32(x=float('inf'))]
    assert non_finite_fields(features) == ['polygon.points[1].x']
    info = CameraInfo(p=[0.0] * 3 + [float('nan')] + [0.0] * 8)
    assert non_finite_fields(info) == ['p']
    status = DiagnosticArray(status=[DiagnosticStatus(values=[
        KeyValue(key='a', value='1.5'), KeyValue(key='b', value='none'),
        KeyValue(key='c', value='-inf')])])
    assert non_finite_fields(status) == ['status[0].values[2].value']
    trajectory = joint_trajectory(0, MS, np.tile(Q0, (2, 1)))
    assert non_finite_fields(trajectory) == []
    trajectory.points[1].velocities = [float('nan')] * 6
    assert non_finite_fields(trajectory) == ['points[1].velocities']
    assert non_finite_fields(image_msg(np.zeros((4, 4, 3), dtype=np.uint8), 0)) == []


def test_the_feature_node_refuses_absurd_cameras_and_publishes_finite(context):
    rig = _run(rigs.FeatureRig(context))
    try:
        (left, right), only_p3 = _absurd_cameras(rig.camera.intrinsics)
        rig.deliver(contract.LEFT_INFO, left)
        rig.deliver(contract.RIGHT_INFO, right)
        rig.deliver(contract.RIGHT_INFO, only_p3)
        assert rig.reasons(contract.LEFT_INFO)['focal length out of range'] == 1
        assert rig.reasons(contract.RIGHT_INFO) == {'focal length out of range': 1,
                                                    'baseline out of range': 1}
        for _ in range(3):
            assert rig.recovered()
        assert rig.non_finite == [] and rig.published[contract.FEATURES] >= 4
        assert all(np.isfinite([p.x, p.y, p.z]).all()
                   for m in rig.out for p in m.polygon.points)
    finally:
        rig.close()


def test_the_feedback_node_counts_its_camera_rejections(context):
    rig = rigs.AdaptiveFeedbackRig(context)
    try:
        (left, right), only_p3 = _absurd_cameras(rig.camera.intrinsics)
        rig.deliver(contract.LEFT_INFO, left)  # before the model: refused, never built from
        rig.deliver(contract.RIGHT_INFO, only_p3)
        assert rig.node.feedback is None
        assert rig.reasons(contract.LEFT_INFO)['focal length out of range'] == 1
        assert rig.reasons(contract.RIGHT_INFO)['baseline out of range'] == 1
        _run(rig)  # the good camera builds the model
        other = camera_infos(rig.camera.intrinsics, 0)[1]
        other.width += 2  # a lens of another size after the model is built
        rig.deliver(contract.RIGHT_INFO, other)
        assert rig.reasons(contract.RIGHT_INFO)['camera_info changed'] == 1
        assert rig.recovered() and rig.non_finite == []
    finally:
        rig.close()


def test_the_simulated_trajectory_controller_refuses_what_jtc_refuses(context):
    rig = _run(rigs.SimPositionRig(context, 'joint_trajectory'))
    try:
        node = rig.node
        reference = node.mode.servo.reference.copy()
        q = rig.q_start
        beyond = np.r_[q[:3], 10.0, q[4:]]
        first_bad = joint_trajectory(0, MS, np.vstack([beyond, q + 0.02]))
        stale = joint_trajectory(0, MS, np.tile(q + 0.02, (2, 1)))
        stale.header.stamp.sec, stale.header.stamp.nanosec = divmod(
            node.sim.t_ns - 2 * node.mode._command_timeout_ns - 2 * MS, 10 ** 9)
        negative = joint_trajectory(0, MS, np.atleast_2d(q + 0.02))
        negative.points[0].time_from_start = Duration(sec=-1)
        nan_velocity = joint_trajectory(0, MS, np.tile(q + 0.02, (2, 1)))
        nan_velocity.points[1].velocities = [float('nan')] * 6
        for msg in (first_bad, stale, negative, nan_velocity):
            rig.deliver(rig.topic, msg)
        assert rig.reasons(rig.topic) == {'out of range': 1, 'trajectory ends in the past': 1,
                                          'negative time_from_start': 1,
                                          'non-finite velocities': 1}
        np.testing.assert_array_equal(node.mode.servo.reference, reference)
        assert any(kv.key == f'rejected[{rig.topic}: out of range]'
                   for kv in node.diagnostics.status().values)
        assert rig.recovered()
    finally:
        rig.close()


def test_viz_neither_redraws_a_duplicate_stamp_nor_draws_off_the_image(context):
    rig = _run(rigs.VizRig(context))
    try:
        last = rigs.frame_ns(rig.n - 1)
        drawn_before = len(rig.drawn)
        rig.deliver(contract.JOINT_STATES, joint_state(last, Q0, np.zeros(6)))
        assert rig.reasons(contract.JOINT_STATES)['duplicate stamp'] == 1
        assert not rig.spin_until(lambda: len(rig.drawn) > drawn_before, deadline_s=0.3)
        for topic, msg in rig.off_image():
            rig.deliver(topic, msg)
        assert rig.reasons(contract.FEATURES)['features off the image'] == 1
        assert rig.node.measured is None
        right = camera_infos(rig.camera.intrinsics, 0)[1]
        right.width, right.height = 640, 480  # a lens of its own, not the left's pair
        rig.deliver(contract.RIGHT_INFO, right)
        assert rig.reasons(contract.RIGHT_INFO)['camera_info size mismatch'] == 1
        assert rig.recovered() and rig.non_finite == []
    finally:
        rig.close()


def test_feature_node_counts_a_duplicate_joint_state(context):
    rig = _run(rigs.FeatureRig(context))
    try:
        assert rig.recovered()  # a second frame: one stamp to go back to
        last = rigs.frame_ns(rig.n - 1)
        rig.deliver(contract.JOINT_STATES, joint_state(last, Q0, np.zeros(6)))
        rig.deliver(contract.JOINT_STATES, joint_state(last - MS, Q0, np.zeros(6)))
        assert rig.reasons(contract.JOINT_STATES) == {'duplicate stamp': 1,
                                                      'stamp went back': 1}
        assert rig.recovered()
    finally:
        rig.close()


def test_feature_node_files_rejections_under_the_zed_names(context):
    from ibvs_vision.feature_node import FeatureNode
    remaps = {contract.LEFT_IMAGE: contract.ZED_LEFT_IMAGE,
              contract.RIGHT_IMAGE: contract.ZED_RIGHT_IMAGE,
              contract.LEFT_INFO: contract.ZED_LEFT_INFO,
              contract.RIGHT_INFO: contract.ZED_RIGHT_INFO}
    args = ['--ros-args'] + [a for old, new in remaps.items() for a in ('-r', f'{old}:={new}')]
    node = FeatureNode(context=context, cli_args=args,
                       parameter_overrides=[Parameter('use_sim_time', value=True)])
    rig = Rig(context, node, node._diag)
    try:
        assert contract.ZED_LEFT_IMAGE in rig.topics and contract.LEFT_IMAGE not in rig.topics
        image = image_msg(np.zeros((4, 4, 3), dtype=np.uint8), 0)
        image.encoding = '16UC1'
        rig.deliver(contract.ZED_LEFT_IMAGE, image)
        info = camera_infos(rigs.default_camera('VGA').intrinsics, 0)[1]
        info.width = 0
        rig.deliver(contract.ZED_RIGHT_INFO, info)
        rig.deliver(contract.ZED_RIGHT_IMAGE, image_msg(np.zeros((4, 4, 3), np.uint8), 0))
        rig.deliver(contract.ZED_RIGHT_IMAGE, image_msg(np.zeros((4, 4, 3), np.uint8), 0))
        assert sum(rig.reasons(contract.ZED_LEFT_IMAGE).values()) == 1
        assert rig.reasons(contract.ZED_RIGHT_INFO)['bad camera_info size'] == 1
        assert rig.reasons(contract.ZED_RIGHT_IMAGE)['duplicate stamp'] == 1
        keys = [kv.key for kv in node._diag.status().values if kv.key.startswith('rejected[')]
        assert not [k for k in keys if '/stereo/' in k], keys
    finally:
        rig.close()
