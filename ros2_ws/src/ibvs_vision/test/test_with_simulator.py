"""
feature_node behind the real simulator (ibvs_sim.sim_node) in one executor, in lockstep.

A minimal stand-in controller answers every /joint_states with gravity compensation, so the
simulator steps at 1 kHz and publishes 30 Hz frames due at n * T_cam, rendered from the
first physics step at or after that time and stamped with it. At the scenario 1 start both
markers are in view: the node must publish exactly one measured p_I per frame, stamped with
the frame: the model projection of the TRUE angles the frame was rendered with (encoders +
d_q, the paper's disturbance) within the acceptance tolerance, pixels away from the
estimate F(q_T).
"""

import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PolygonStamped
from ibvs_common import contract
from ibvs_common.conversions import joint_state, read_features, read_joints, stamp_ns
from ibvs_model import paper
from ibvs_sim.sim_node import SimNode
from ibvs_sim.world import World
from ibvs_vision.feature_node import FeatureNode
import numpy as np
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

FRAMES = 6
T_CAM_NS = 33_333_333


class Holder(Node):
    """Answer each /joint_states with the torque that holds the arm; record the rest."""

    def __init__(self, context):
        super().__init__('holder', context=context)
        self.model = World(render=False)
        self.joints = {}
        self.features = []
        self.diagnostics = []
        self.pub = self.create_publisher(JointState, contract.EFFORT_COMMANDS,
                                         contract.RELIABLE)
        self.create_subscription(JointState, contract.JOINT_STATES, self._on_joints,
                                 contract.RELIABLE)
        self.create_subscription(PolygonStamped, contract.FEATURES, self.features.append,
                                 contract.RELIABLE)
        self.create_subscription(DiagnosticArray, contract.DIAGNOSTICS,
                                 lambda m: self.diagnostics.extend(
                                     s for s in m.status if s.name.startswith('feature')), 10)

    def destroy_node(self):
        self.model.close()
        return super().destroy_node()

    def _on_joints(self, msg):
        q = read_joints(msg)
        self.joints[stamp_ns(msg.header.stamp)] = q
        tau = self.model.inverse_dynamics(q, read_joints(msg, 'velocity'), np.zeros(6))
        self.pub.publish(joint_state(msg.header.stamp, effort=tau))


def test_one_measured_feature_message_per_simulated_frame(context, vga_model):
    sim = SimNode(context=context, parameter_overrides=[
        Parameter('resolution', value='VGA'), Parameter('scenario', value=1),
        Parameter('disturbance_deg', value=list(paper.DISTURBANCE_DEG)),
        Parameter('use_sim_time', value=True)])
    node = FeatureNode(context=context,
                       parameter_overrides=[Parameter('use_sim_time', value=True)])
    holder = Holder(context)
    executor = SingleThreadedExecutor(context=context)
    for n in (sim, node, holder):
        executor.add_node(n)
    try:
        end = time.monotonic() + 60.0
        while len(holder.features) < FRAMES:
            assert time.monotonic() < end, f'{len(holder.features)} feature messages'
            executor.spin_once(timeout_sec=0.05)
    finally:
        executor.shutdown()
        for n in (sim, node, holder):
            n.destroy_node()
    stamps = [stamp_ns(m.header.stamp) for m in holder.features]
    assert stamps == [-(-n * T_CAM_NS // 1_000_000) * 1_000_000 for n in range(FRAMES)]
    for stamp, msg in zip(stamps, holder.features):
        # The frame's encoder angles: the joint state with the image's stamp.
        q_encoder = holder.joints[stamp]
        truth = vga_model.features(q_encoder + np.radians(paper.DISTURBANCE_DEG))
        assert np.abs(read_features(msg) - truth).max() <= 0.3
        assert np.abs(read_features(msg) - vga_model.features(q_encoder)).max() > 1.0
    assert not any(kv.key.startswith('rejected[') for s in holder.diagnostics
                   for kv in s.values)
