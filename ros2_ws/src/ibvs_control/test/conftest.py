"""
Fixtures of the ibvs_control tests: the shared ones (ibvs_testing), the joint controller's rigs.

The rigs import IBVS packages, which ibvs_testing (the bottom of the tests, imported by every
package's tests) must not: they are defined here, beside the tests that use them, and reached
through fixtures (a test module cannot import its directory's modules under pytest's
``--import-mode=importlib``).

- :func:`controller_rig`: a test node publishing on a joint controller's inputs, and the
  executor of both once the controller has discovered them (:class:`ControllerRig`);
- :func:`position_cell`: the position joint controller on sim time, fed and read as a cell
  would (:class:`PositionCell`).
"""

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from ibvs_common import contract
from ibvs_common.conversions import camera_infos, joint_state, joint_trajectory, ns_stamp
from ibvs_control.joint_controller_node import JointControllerNode
from ibvs_model import default_camera, inverse_kinematics, paper
from ibvs_testing.fixtures import context, spin_until  # noqa: F401
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, JointState, TimeReference
from std_msgs.msg import Float64MultiArray, Int8
from trajectory_msgs.msg import JointTrajectory

MS = 1_000_000
Q0 = inverse_kinematics(paper.scenario_start_pose(1))
CAMERA = default_camera('VGA')
#: The camera's frame period (30 Hz).
FRAME_NS = 33_333_333

#: A joint controller's inputs as a cell publishes them: topic: (message type, QoS).
INPUTS = {
    contract.CLOCK: (Clock, contract.RELIABLE),
    contract.LEFT_INFO: (CameraInfo, contract.IMAGES),
    contract.JOINT_STATES: (JointState, contract.RELIABLE),
    contract.Q_FEEDBACK: (JointState, contract.RELIABLE),
    contract.FEEDFORWARD_TRAJECTORY: (JointTrajectory, contract.LATCHED),
    contract.FEEDBACK_STATUS: (Int8, contract.LATCHED),
}
#: What a second publisher (:meth:`PositionCell.rogue_on`) may publish on, by topic.
ROGUE_KINDS = {topic: kind for topic, (kind, _) in INPUTS.items()} | {
    contract.POSITION_COMMANDS: Float64MultiArray}


class ControllerRig:
    """
    A joint controller node, a test node publishing on its inputs, and their executor.

    Parameters
    ----------
    context : rclpy.context.Context
        The test's context.
    name : str
        The test node's name.
    topics : iterable of str
        The inputs (keys of :data:`INPUTS`) the test node publishes on, in ``pubs``.
    parameters : dict
        The controller's parameters (name: value).

    """

    def __init__(self, context, name, topics, parameters):  # noqa: F811 (the fixture's name)
        self.context = context
        self.node = JointControllerNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in parameters.items()])
        self.test = Node(name, context=context)
        self.pubs = {topic: self.test.create_publisher(INPUTS[topic][0], topic, INPUTS[topic][1])
                     for topic in topics}
        self.executor = None

    def record(self, kind, topic, qos=contract.RELIABLE):
        """Return the list that the messages on ``topic`` are appended to as they come."""
        received = []
        self.test.create_subscription(kind, topic, received.append, qos)
        return received

    def spin_up(self):
        """Return the executor of both nodes, once the controller has every publisher's topic."""
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.executor.add_node(self.test)
        spin_until(self.executor,
                   lambda: all(p.get_subscription_count() for p in self.pubs.values()),
                   what='discovery')
        return self.executor

    def close(self):
        if self.executor is not None:
            self.executor.shutdown()
        self.node.destroy_node()
        self.test.destroy_node()


class PositionCell(ControllerRig):
    """
    The position joint controller and what a cell would send it and read from it.

    The controller runs on sim time (its command timer fires only when the test moves
    /clock), with a 0.3 s frame timeout. The test node publishes every input of
    :data:`INPUTS` and records the commands (``commands``: the positions of each, the first
    point's of a trajectory; ``command_msgs``: the messages), /ibvs/servo_status, the
    controller's /diagnostics and /ibvs/frame_latency.

    Parameters
    ----------
    context : rclpy.context.Context
        The test's context.
    command_type : str
        ``position_command_type``: 'forward_command' or 'joint_trajectory'.
    **parameters
        More parameters of the controller, or other values of the ones above.

    """

    def __init__(self, context, command_type='forward_command',  # noqa: F811 (as above)
                 **parameters):
        values = {'command_interface': 'position', 'use_sim_time': True,
                  'frame_timeout_s': 0.3, 'position_command_type': command_type}
        values.update(parameters)
        super().__init__(context, 'cell', INPUTS, values)
        self.command_msgs, self.commands, self.status, self.diagnostics = [], [], [], []
        if command_type == 'forward_command':
            topic, kind, positions = (contract.POSITION_COMMANDS, Float64MultiArray,
                                      lambda m: m.data)
        else:
            topic, kind, positions = (contract.TRAJECTORY_COMMANDS, JointTrajectory,
                                      lambda m: m.points[0].positions)

        def record(msg):
            self.command_msgs.append(msg)
            self.commands.append(np.asarray(positions(msg)))

        self.test.create_subscription(kind, topic, record, contract.RELIABLE)
        self.test.create_subscription(Int8, contract.SERVO_STATUS,
                                      lambda m: self.status.append(m.data), contract.LATCHED)
        self.test.create_subscription(
            DiagnosticArray, contract.DIAGNOSTICS,
            lambda m: self.diagnostics.extend(s for s in m.status
                                              if s.name.startswith('joint_controller_node')),
            10)
        self.latency = self.record(TimeReference, contract.FRAME_LATENCY)
        self.spin_up()
        self.measured = Q0.copy()
        self.next_frame = None
        self.rogue = None

    def close(self):
        super().close()
        if self.rogue is not None:
            self.rogue.destroy_node()

    def clock(self, t_ns):
        self.pubs[contract.CLOCK].publish(Clock(clock=ns_stamp(t_ns)))

    def frame(self, t_ns, q_feedback=None):
        """Publish the camera frame exposed at ``t_ns``: its camera_info and q_feedback."""
        self.pubs[contract.LEFT_INFO].publish(camera_infos(CAMERA.intrinsics, t_ns)[0])
        self.pubs[contract.Q_FEEDBACK].publish(
            joint_state(t_ns, np.zeros(6) if q_feedback is None else q_feedback))
        self.next_frame = t_ns + FRAME_NS

    def tick(self, t_ns, inputs=True):
        """One command period: the arm where it was told, 30 Hz frames; one command."""
        if inputs:
            self.pubs[contract.JOINT_STATES].publish(
                joint_state(t_ns, self.measured, np.zeros(6)))
            if self.next_frame is None or t_ns >= self.next_frame:
                self.frame(t_ns)
        count = len(self.commands)
        self.clock(t_ns)
        spin_until(self.executor, lambda: len(self.commands) > count,
                   what=f'the command at {t_ns} ns')
        # the contract's joint order (no 'joints' given): no permutation
        self.measured = self.commands[-1].copy()

    def start(self, t0_ns, target):
        """Move the clock to ``t0_ns``, send the feedforward to ``target`` and every input."""
        self.clock(t0_ns)  # first: a stamp far ahead of the node's time is refused
        spin_until(self.executor,
                   lambda: self.node.get_clock().now().nanoseconds == t0_ns, what='/clock')
        self.pubs[contract.FEEDFORWARD_TRAJECTORY].publish(joint_trajectory(t0_ns, MS, [target]))
        self.pubs[contract.JOINT_STATES].publish(joint_state(t0_ns, Q0, np.zeros(6)))
        self.frame(t0_ns)
        spin_until(self.executor, lambda: not self.node.mode._watch.missing(),
                   what='every input once')

    def spin_to_status(self, code):
        spin_until(self.executor, lambda: self.status and self.status[-1] == code,
                   what=code.name)

    def rejected(self, reason):
        """Return how many inputs the controller refused for a ``reason`` of these words."""
        return sum(n for key, n in self.node.diagnostics.rejections.items() if reason in key)

    def said(self, *words):
        """Return whether a WARN on /diagnostics says every one of ``words``."""
        return any(s.level == DiagnosticStatus.WARN and all(w in s.message for w in words)
                   for s in self.diagnostics)

    def rogue_on(self, topic):
        """Bring a node of its own with a publisher on ``topic`` (it sends nothing)."""
        self.rogue = Node('rogue', context=self.context)
        self.rogue.create_publisher(ROGUE_KINDS[topic], topic, contract.RELIABLE)

    def rogue_off(self):
        self.rogue.destroy_node()
        self.rogue = None


@pytest.fixture
def controller_rig(context):  # noqa: F811 (the fixture's name)
    """
    Yield make(name, topics, **parameters): a :class:`ControllerRig`, not yet spun up.

    Every rig made is closed after the test.
    """
    made = []

    def make(name, topics, **parameters):
        made.append(ControllerRig(context, name, topics, parameters))
        return made[-1]

    yield make
    for rig in made:
        rig.close()


@pytest.fixture
def position_cell(context):  # noqa: F811 (the fixture's name)
    """
    Yield make(command_type='forward_command', **parameters): a :class:`PositionCell`.

    Every cell made is closed after the test.
    """
    made = []

    def make(command_type='forward_command', **parameters):
        made.append(PositionCell(context, command_type, **parameters))
        return made[-1]

    yield make
    for cell in made:
        cell.close()
