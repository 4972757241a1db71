"""
robot_state_node: the simulated cell's robot_state_publisher, in ABB's frames.

On a cell, abb_ros2's bringup starts robot_state_publisher with ABB's URDF: it publishes
/robot_description and the arm's link frames, and Jazzy's controller manager reads its URDF
from that topic. In simulation this node stands in for it, and nothing else publishes those
(the viewers' node publishes only what a cell lacks: docs/visualisation.md). It is the
simulator's (``ibvs_bringup.graph``: ``sim_side``), so it does not run beside a real cell's
driver. What it publishes, as robot_state_publisher does (ros/robot_state_publisher 3.3.3,
rolling commit e0f77e62457ae01f8dbf3b5c4cc62d15fa36dfad, the newest the mirror holds: its
jazzy branch was not there to read; ``src/robot_state_publisher.cpp``):

- /robot_description (std_msgs/String), once at start, QoS depth 1, transient local,
  reliable (``rclcpp::QoS(1).transient_local()``, L132-135; ``contract.LATCHED``):
  :func:`ibvs_model.abb_urdf.robot_description` of the simulated arm (``l2_scale``,
  ``l4_scale``): ABB's joints and frames (abb_ros2 ``irb4600_60_205_macro.xacro``), our link
  solids, no tool (a cell's URDF has none of ours; the viewers' node puts the tool's frames
  on /tf_static);
- /tf_static, once at start, the fixed joints base_link -> base, link_6 -> flange,
  flange -> tool0, stamped with the node's clock (``publishFixedTransforms``, L279-298: the
  tf2_ros static broadcaster, transient local);
- /tf at each joint state: base_link -> link_1 -> ... -> link_6, the KDL segment pose
  ``origin * Rot(axis, q)`` (``publishTransforms``, L253-276), stamped with the joint
  state's stamp, in joint-name order (robot_state_publisher's std::map).

Differences, on purpose: the subscription is reliable (robot_state_publisher's is
SensorDataQoS, best effort, L144-148) and every accepted joint state is published (it
throttles to ``publish_frequency``, 20 Hz by default, L333-341), so that a bag holds the
frame of every joint state it reads (``ibvs run`` remaps /joint_states to
/stereo/joint_states: one per camera frame). The angles drawn are the true ones of the
simulated arm, encoder + ``disturbance_deg`` (d_q, eq. 30), so that tool0 is where the
camera sees it. Bad joint states are rejected with a logged reason and counted on
/diagnostics (as viz_node: :class:`ibvs_common.kit.Inputs`, the one stamp rule and order
per topic, with :func:`ibvs_common.conversions.read_joints`).
"""

from ibvs_common import contract
from ibvs_common.conversions import position_bounds, read_joints, transforms_msg
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.kit import config, forget_on_back, Inputs, publisher, subscription
from ibvs_common.node_main import run
from ibvs_common.sim_time import node_time_ns
from ibvs_model import abb_urdf
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from .node_params import RobotStateConfig

#: The node's typed configuration, built by ``ibvs run`` before any node starts.
CONFIG = RobotStateConfig
PARAMS = CONFIG.params()
#: tf2_ros's TransformBroadcaster QoS (DynamicBroadcasterQoS): depth 100.
TF_DEPTH = 100


class RobotStateNode(Node):
    """Publish the simulated arm's description and ABB's link frames (module docstring)."""

    def __init__(self, **kwargs):
        """Declare and check the parameters; publish the description and the fixed frames."""
        super().__init__('robot_state_node', **kwargs)
        self.config = c = config(self, RobotStateConfig)
        self._params = c.plant.robot
        self._d_q = c.plant.d_q
        self._last_joint_ns = None
        self._diag = Diagnostics(self, 'robot description and link frames')
        self._inputs = Inputs(self._diag, lambda: node_time_ns(self, self._last_joint_ns),
                              c.timing.frame_lead_ns)
        forget_on_back(self, self._inputs)
        self._diag.update(tf_published=0)
        self._diag.log_progress(lambda: None if not self._diag.values['tf_published'] else (
            f"/tf of {self._diag.values['tf_published']} joint states (last at "
            f'{self._last_joint_ns * 1e-9:.3f} s)'))
        description = publisher(self, String, contract.ROBOT_DESCRIPTION, contract.LATCHED)
        static = publisher(self, TFMessage, contract.TF_STATIC, contract.LATCHED)
        self._tf_pub = publisher(self, TFMessage, contract.TF, TF_DEPTH)
        self._joints_topic = subscription(self, JointState, contract.JOINT_STATES,
                                          self._on_joints, contract.RELIABLE).topic_name
        description.publish(String(data=abb_urdf.robot_description(self._params)))
        static.publish(transforms_msg(abb_urdf.fixed_transforms(),
                                      self.get_clock().now().to_msg()))

    def _on_joints(self, msg):
        got = self._inputs.read(self._joints_topic, msg,
                                lambda m: read_joints(m, bound=position_bounds()))
        if got is None:
            return
        self._last_joint_ns, q = got
        joints = abb_urdf.joint_transforms(q + self._d_q, self._params)
        self._tf_pub.publish(transforms_msg(joints, msg.header.stamp))
        self._diag.values['tf_published'] += 1


def main(args=None):
    """Run the node (``ros2 run ibvs_sim robot_state_node``)."""
    run(RobotStateNode, args=args, name='robot_state_node')


if __name__ == '__main__':
    main()
