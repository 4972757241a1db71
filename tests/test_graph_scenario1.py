"""
The whole graph in one process, on one rclpy executor: the paper's scenario 1 end to end.

The five nodes of docs/design.md §1 are built with the scenario 1 parameters (as
``--params-file`` would give them) and share a SingleThreadedExecutor; the simulator advances
only as the controllers answer, so the run is the same however slow this machine is. The
true tool pose on /ibvs/tool_path must reach the target.
"""

import math

from ibvs_bringup import scenario
from ibvs_common import contract
from ibvs_common.conversions import pose_matrix, stamp_ns
from ibvs_control.adaptive_feedback_node import AdaptiveFeedbackNode
from ibvs_control.feedforward_node import FeedforwardNode
from ibvs_control.joint_controller_node import JointControllerNode
from ibvs_sim.sim_node import SimNode
from ibvs_vision.feature_node import FeatureNode
from nav_msgs.msg import Path
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

SIM_SECONDS = 1.0
#: The bounds after 1.0 s: the graph is within 1 mm well before (docs/results.md), and the
#: axis error still moves within a few hundredths of a degree. What is left is
#: the stereo measurement, and the tool axis is its weakest direction: 0.004 px of vertical
#: separation between the markers is 0.1 deg (ibvs_vision test_rendered). It holds because
#: the simulator renders the markers with 8 x 8 samples per pixel and the detector fills
#: the notches the rods cut into them.
POSITION_TOLERANCE_M = 1e-3
AXIS_TOLERANCE_DEG = 0.1


def overrides(params):
    return [Parameter(k, value=v) for k, v in params.items()] + \
        [Parameter('use_sim_time', value=True)]


def _tool_poses(context, params, seconds):
    """Run the five nodes on one executor for ``seconds`` of sim time; the true tool poses."""
    nodes = []
    executor = SingleThreadedExecutor(context=context)
    try:
        for cls in (FeatureNode, AdaptiveFeedbackNode, FeedforwardNode, JointControllerNode):
            nodes.append(cls(context=context, parameter_overrides=overrides(params)))
        nodes.append(SimNode(context=context, parameter_overrides=overrides(params)))
        for node in nodes:
            executor.add_node(node)
        poses = []
        nodes[0].create_subscription(
            Path, contract.TOOL_PATH,
            lambda m: poses.extend((stamp_ns(p.header.stamp), pose_matrix(p.pose))
                                   for p in m.poses),
            contract.RELIABLE)
        # No wall-clock deadline on the run itself: it is bounded by sim time, and a stall
        # (no sim progress for a long time) fails instead of hanging.
        # (Tool poses come in batches, one a /clock: progress is the simulator's step.)
        sim = nodes[-1].sim
        last_k, stalled = -1, 0
        while not poses or poses[-1][0] < seconds * 1e9:
            executor.spin_once(timeout_sec=0.5)
            stalled = stalled + 1 if sim.k == last_k else 0
            last_k = sim.k
            assert stalled < 240, f'the graph stalled at sim time {sim.t_ns * 1e-9:.3f} s'
    finally:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()
    return poses


def _target(params):
    target = np.eye(4)
    target[:3, 3] = params['target_position']
    target[:3, :3] = np.reshape(params['target_rotation'], (3, 3))
    return target


@pytest.mark.slow
def test_scenario1_through_the_graph_reaches_the_target(context):
    params = scenario.load_parameters('scenario1')
    params.pop('run_duration_s', None)
    poses = _tool_poses(context, params, SIM_SECONDS)
    target = _target(params)
    final = poses[-1][1]
    position_error = np.linalg.norm(final[:3, 3] - target[:3, 3])
    axis_error = math.degrees(math.acos(np.clip(final[:3, 2] @ target[:3, 2], -1.0, 1.0)))
    print(f'final position error {position_error * 1e3:.3f} mm, axis {axis_error:.4f} deg')
    assert position_error <= POSITION_TOLERANCE_M, \
        f'final position error {position_error * 1e3:.3f} mm'
    assert axis_error <= AXIS_TOLERANCE_DEG, f'final tool-axis error {axis_error:.4f} deg'
    # Stamps of the true pose advance by one physics step each: lockstep, no skipped step.
    stamps = np.array([s for s, _ in poses])
    assert np.all(np.diff(stamps) == 1_000_000), 'one tool pose per 1 ms physics step'


@pytest.mark.slow
def test_with_a_camera_latency_the_predicted_feedback_keeps_the_undelayed_response(context):
    # 0.1 s between a frame's exposure and its q_feedback acting (three frames at 30 Hz):
    # the feedback predicts each frame to then with the encoders (ibvs_control.prediction),
    # so the tool is within 1 mm from 0.75 s on and does not ring (the paper's law as
    # published: 1 mm only after 2 s, rippling by half a millimetre).
    params = scenario.load_parameters('scenario1')
    params.pop('run_duration_s', None)
    params['feedback_latency_s'] = 0.1
    poses = _tool_poses(context, params, 3.0)
    target = _target(params)
    t = np.array([s for s, _ in poses]) * 1e-9
    error = np.array([np.linalg.norm(m[:3, 3] - target[:3, 3]) for _, m in poses])
    assert error[t >= 0.75].max() <= 1e-3, f'{error[t >= 0.75].max() * 1e3:.3f} mm after 0.75 s'
    tail = error[t >= t[-1] - 0.5]
    assert tail.max() - tail.min() <= 1e-4, f'ripple {(tail.max() - tail.min()) * 1e3:.3f} mm'
