"""
sim_node free-running with the position drive, in an rclpy executor (docs/design.md §4).

A test node sends forward_command_controller commands; every wait is a spin loop on a
condition with a deadline that only guards against a hang (the pace is real_time_factor's,
and no assertion depends on wall-clock time).
"""

from ibvs_common import contract
from ibvs_common.params import ParameterError
from ibvs_sim.sim_node import SimNode
from ibvs_testing.fixtures import spin_until
import numpy as np
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

REVERSED = [f'joint_{i}' for i in range(6, 0, -1)]


class Commander(Node):
    """Sends position commands and records /joint_states."""

    def __init__(self, context, images=False):
        super().__init__('commander', context=context)
        self.joints = []
        self.images = []
        self.pub = self.create_publisher(Float64MultiArray, contract.POSITION_COMMANDS,
                                         contract.RELIABLE)
        self.create_subscription(JointState, contract.JOINT_STATES, self.joints.append,
                                 contract.RELIABLE)
        if images:
            for topic in (contract.ZED_LEFT_IMAGE, contract.ZED_RIGHT_IMAGE):
                self.create_subscription(Image, topic, self.images.append, contract.ZED_IMAGES)
            self.infos = []
            for topic in (contract.ZED_LEFT_INFO, contract.ZED_RIGHT_INFO):
                self.create_subscription(CameraInfo, topic, self.infos.append,
                                         contract.ZED_IMAGES)

    def send(self, values):
        self.pub.publish(Float64MultiArray(data=[float(v) for v in values]))

    def q(self):
        return np.asarray(self.joints[-1].position)


@pytest.fixture
def cell(context, executor_of):
    def build(images=False, **params):
        values = {'resolution': 'VGA', 'disturbance_deg': [0.0] * 6,
                  'publish_images': images,
                  'command_interface': 'position',
                  'real_time_factor': 1.0, 'joints': REVERSED, 'render_supersampling': 1,
                  'render_marker_supersampling': 1}
        values.update(params)
        sim = SimNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in values.items()])
        commander = Commander(context, images)
        return sim, commander, executor_of(sim, commander)
    return build


def test_tracks_commands_in_the_controllers_joint_order_and_rejects_bad_ones(cell):
    sim, cmd, executor = cell(command_timeout_s=10.0)  # one command: never stale here
    spin_until(executor, lambda: len(cmd.joints) > 5, what='free-running /joint_states')
    q0 = sim.sim.q_start
    target = q0.copy()
    target[0] += 0.05  # joint_1: the LAST value in the reversed order
    for bad in ([0.0] * 5, [float('nan')] + list(target[::-1][1:]),
                list(target[::-1][:-1]) + [10.0]):
        cmd.send(bad)
    cmd.send(target[::-1])
    spin_until(executor, lambda: abs(cmd.q()[0] - target[0]) < 1e-5, what='joint_1 to move')
    np.testing.assert_allclose(cmd.q()[1:], q0[1:], atol=1e-12)
    rejected = sim.diagnostics.rejections
    topic = contract.POSITION_COMMANDS
    assert rejected[f'{topic}: wrong length'] == 1
    assert rejected[f'{topic}: not finite'] == 1
    assert rejected[f'{topic}: out of range'] == 1
    # Stamps advance on their own, on the physics grid: nobody is waited for (a reader that
    # falls behind loses the oldest states of its queue, as on a real cell).
    stamps = np.diff([m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec
                      for m in cmd.joints])
    assert np.all(stamps > 0) and np.all(stamps % sim.sim.dt_ns == 0)


def test_a_stale_command_stops_and_holds_the_arm_and_says_so(cell):
    sim, cmd, executor = cell(command_timeout_s=0.05)
    spin_until(executor, lambda: len(cmd.joints) > 5, what='free-running /joint_states')
    target = sim.sim.q_start.copy()
    target[0] += 1.0  # far: the arm is still moving when the command goes stale
    cmd.send(target[::-1])
    spin_until(executor, lambda: sim.mode.servo.holding, what='the command to go stale')
    assert sim.diagnostics.values['command'] == 'stale'
    assert 'stale' in sim.diagnostics.message
    spin_until(executor, lambda: np.abs(sim.mode.servo.qd).max() < 1e-6, what='the arm to stop')
    held, k = sim.mode.servo.q.copy(), sim.sim.k
    spin_until(executor, lambda: sim.sim.k > k + 20, what='more steps')
    np.testing.assert_allclose(sim.mode.servo.q, held, atol=1e-6)
    assert abs(held[0] - sim.sim.q_start[0]) < 1.0  # stopped short of the old reference
    cmd.send(target[::-1])  # a fresh command: tracking again
    spin_until(executor, lambda: not sim.mode.servo.holding, what='tracking again')
    assert sim.diagnostics.values['command'] == 'tracking'


def test_zed_wrapper_topics_publish_what_the_wrapper_publishes(cell):
    sim, cmd, executor = cell(images=True, camera_topics='zed_wrapper')
    spin_until(executor, lambda: len(cmd.images) >= 2 and len(cmd.infos) >= 2,
               what='a stereo frame on the ZED topics')
    left = next(m for m in cmd.images if m.header.frame_id == contract.ZED_LEFT_FRAME)
    assert left.encoding == 'bgra8' and left.step == 4 * left.width
    right_info = next(m for m in cmd.infos if m.header.frame_id == contract.ZED_RIGHT_FRAME)
    k = sim.sim.calibrated_camera.intrinsics
    assert right_info.p[3] == pytest.approx(-k.fu * k.baseline)
    # frames stamped with their exposure: the physics step they were rendered from
    assert (left.header.stamp.sec * 10 ** 9 + left.header.stamp.nanosec) % sim.sim.dt_ns == 0


def test_joint_trajectory_commands_are_mapped_by_name_and_bad_names_refused(cell):
    sim, cmd, executor = cell(position_command_type='joint_trajectory', command_timeout_s=10.0)
    pub = cmd.create_publisher(JointTrajectory, contract.TRAJECTORY_COMMANDS,
                               contract.RELIABLE)
    spin_until(executor, lambda: len(cmd.joints) > 5 and pub.get_subscription_count(),
               what='free-running /joint_states')
    q0 = sim.sim.q_start
    target = q0.copy()
    target[2] -= 0.03  # joint_3

    def send(names, values):
        pub.publish(JointTrajectory(joint_names=names, points=[
            JointTrajectoryPoint(positions=[float(v) for v in values])]))

    scrambled = ['joint_3', 'joint_5', 'joint_1', 'joint_6', 'joint_2', 'joint_4']
    send(scrambled[:5] + ['joint_3'], target[[2, 4, 0, 5, 1, 3]])  # joint_3 twice
    send(scrambled, target[[2, 4, 0, 5, 1, 3]])  # another order: mapped by name
    spin_until(executor, lambda: abs(sim.mode.servo.q[2] - target[2]) < 1e-5, what='joint_3')
    np.testing.assert_allclose(np.delete(sim.mode.servo.q, 2), np.delete(q0, 2), atol=1e-12)
    assert sim.diagnostics.rejections[f'{contract.TRAJECTORY_COMMANDS}: wrong joint names'] == 1


@pytest.mark.parametrize('params, name', [
    ({'lockstep': False}, 'lockstep'),  # retired: the interface gives the time mode
    ({'joints': REVERSED[:5] + ['joint_6']}, 'joints'),
])
def test_bad_configurations_are_refused_naming_the_parameter(context, params, name):
    values = {'command_interface': 'position', 'publish_images': False,
              'resolution': 'VGA'}
    values.update(params)
    with pytest.raises(ParameterError, match=f"parameter '{name}'"):
        SimNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in values.items()])
