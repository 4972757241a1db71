"""
A teach pair without markers: the feature node says so on /diagnostics, the runner reads it.

The feature node publishes its status at once with ``contract.TEACH_FAILED`` (the why) and
ERROR; the runner's :class:`~ibvs_experiments.runner.Monitor` names the node and the why,
which :func:`~ibvs_experiments.runner.watch` ends the run on (:class:`TeachFailed`).
"""

from types import SimpleNamespace

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from ibvs_common import contract
from ibvs_common.conversions import camera_infos, image_msg, pose_stamped
from ibvs_experiments.runner import EXIT_NODE_DIED, EXIT_TEACH_FAILED, Monitor, TeachFailed
from ibvs_model import look_at, paper, StereoIntrinsics
from ibvs_testing.fixtures import spin_until
from ibvs_vision.feature_node import FeatureNode
import numpy as np
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, Image


def test_a_teach_pair_without_markers_is_said_at_once_and_read_by_the_runner(context):
    node = FeatureNode(context=context, parameter_overrides=[
        Parameter('target_features_source', value='taught')])
    harness = Node('harness', context=context)
    monitor = Monitor(harness, SimpleNamespace(), None)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(harness)
    try:
        intrinsics = StereoIntrinsics.zed2('HD720')
        pubs = {topic: harness.create_publisher(kind, topic, qos) for topic, kind, qos in (
            (contract.LEFT_INFO, CameraInfo, contract.IMAGES),
            (contract.RIGHT_INFO, CameraInfo, contract.IMAGES),
            (contract.STEREO_POSE, PoseStamped, contract.LATCHED),
            (contract.TEACH_LEFT_IMAGE, Image, contract.LATCHED),
            (contract.TEACH_RIGHT_IMAGE, Image, contract.LATCHED))}
        spin_until(executor, lambda: all(p.get_subscription_count() for p in pubs.values()),
                   what='discovery')
        pubs[contract.STEREO_POSE].publish(
            pose_stamped(look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT), 0))
        left, right = camera_infos(intrinsics, 0)
        pubs[contract.LEFT_INFO].publish(left)
        pubs[contract.RIGHT_INFO].publish(right)
        blank = np.full((intrinsics.height, intrinsics.width, 3), 90, dtype=np.uint8)
        pubs[contract.TEACH_LEFT_IMAGE].publish(image_msg(blank, 0))
        pubs[contract.TEACH_RIGHT_IMAGE].publish(image_msg(blank, 0))
        spin_until(executor, lambda: monitor.teach_failed() is not None,
                   what="the runner's monitor reading the failed teach")
        who, why = monitor.teach_failed()
        assert who == 'feature_node' and why == node._diag.values[contract.TEACH_FAILED]
        assert 'marker' in why
        assert node._diag.level == DiagnosticStatus.ERROR
        said = str(TeachFailed(who, why, 0.0))
        assert said.startswith('teach failed at sim time 0.000 s: feature_node') and why in said
        assert EXIT_TEACH_FAILED not in (0, 1, 2, EXIT_NODE_DIED, 4, 5, 130)
    finally:
        executor.shutdown()
        node.destroy_node()
        harness.destroy_node()
