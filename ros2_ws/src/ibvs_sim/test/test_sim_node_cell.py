"""
sim_node free-running as a real cell's components, in an rclpy executor.

/joint_states at joint_state_broadcaster's own rate and phase with extra joints, no
/stereo/joint_states, each frame delivered feedback_latency_s after its exposure and stamped
with it, a camera outage, and the factor held while servoing. Every wait is a spin loop on a
condition with a deadline that only guards against a hang; no assertion depends on
wall-clock time.
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

MS = 1_000_000


def _ns(msg):
    return msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec


class Cell(Node):
    """Records /joint_states, /stereo/joint_states and the frames with the sim time of arrival."""

    def __init__(self, context, sim):
        super().__init__('cell', context=context)
        self.sim = sim
        self.joints, self.frame_joints, self.images, self.infos = [], [], [], []
        self.pub = self.create_publisher(Float64MultiArray, contract.POSITION_COMMANDS,
                                         contract.RELIABLE)
        self.create_subscription(JointState, contract.JOINT_STATES, self.joints.append,
                                 contract.RELIABLE)
        self.create_subscription(JointState, contract.FRAME_JOINT_STATES,
                                 self.frame_joints.append, contract.RELIABLE)
        self.create_subscription(Image, contract.LEFT_IMAGE, self._on_image, contract.IMAGES)
        self.create_subscription(CameraInfo, contract.LEFT_INFO,
                                 lambda m: self.infos.append(_ns(m)), contract.IMAGES)
        self.create_subscription(Image, contract.RIGHT_IMAGE, lambda m: None, contract.IMAGES)
        self.create_subscription(CameraInfo, contract.RIGHT_INFO, lambda m: None,
                                 contract.IMAGES)

    def _on_image(self, msg):
        # (exposure stamp, the simulator's sim time when it reached us)
        self.images.append((_ns(msg), self.sim.sim.t_ns))


@pytest.fixture
def cell(context, executor_of):
    def build(**params):
        values = {'resolution': 'VGA', 'disturbance_deg': [0.0] * 6, 'publish_images': False,
                  'command_interface': 'position',
                  'real_time_factor': 1.0, 'render_supersampling': 1,
                  'render_marker_supersampling': 1, 'command_timeout_s': 10.0}
        values.update(params)
        sim = SimNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in values.items()])
        node = Cell(context, sim)
        return sim, node, executor_of(sim, node)
    return build


def test_joint_states_at_the_broadcasters_rate_and_phase_with_extra_joints(cell):
    sim, node, executor = cell(joint_state_rate_hz=250.0, joint_state_phase_s=0.001,
                               extra_joints=['track_1', 'positioner_1'], real_time_factor=0.2)
    spin_until(executor, lambda: len(node.joints) > 30, what='free-running /joint_states')
    stamps = np.array([_ns(m) for m in node.joints])
    # joint_state_broadcaster's cycle: every 4 ms from 1 ms, never a 1 kHz state between (a
    # reader that falls behind may lose the oldest of its queue: multiples of 4 ms then)
    assert stamps[0] == 1 * MS
    assert np.all(stamps % (4 * MS) == 1 * MS) and np.all(np.diff(stamps) > 0)
    assert np.median(np.diff(stamps)) == 4 * MS
    # 30 Hz frames on the 1 kHz grid (0, 34, 67, 100 ms, ...) never fall on one of them
    frames = np.array([sim.sim.camera_period_ns * n for n in range(300)])
    frames = -(-frames // sim.sim.dt_ns) * sim.sim.dt_ns
    assert not np.intersect1d(frames, stamps).size
    msg = node.joints[-1]
    assert list(msg.name) == list(contract.JOINT_NAMES) + ['track_1', 'positioner_1']
    assert list(msg.position[6:]) == [0.0, 0.0] and list(msg.velocity[6:]) == [0.0, 0.0]
    assert len(msg.position) == len(msg.velocity) == 8
    # the evaluation's batches keep every physics step, the arm's joints only
    assert all(len(s.name) == 6 for s in sim._joint_states)
    # a real cell has no /stereo/joint_states
    assert not node.frame_joints


def test_frames_come_feedback_latency_s_after_their_exposure_stamped_with_it(cell):
    sim, node, executor = cell(publish_images=True, feedback_latency_s=0.1,
                               min_camera_info_subscribers=1)
    spin_until(executor, lambda: len(node.images) >= 4, what='four delayed frames')
    for stamp, arrived in node.images:
        assert stamp % sim.sim.dt_ns == 0  # the exposure: the step it was rendered from
        assert arrived >= stamp + 100 * MS  # not before feedback_latency_s of sim time
    assert node.images[0][0] == 0
    # the frames exposed in the last 0.1 s are rendered and not yet out
    pending = [stamp for _, stamp, _, _ in sim._deliveries]
    assert pending and all(sim.sim.t_ns - s < 100 * MS for s in pending)
    assert sim.frames - sim.frames_published == len(pending)


@pytest.mark.parametrize('offset_ms', [33, -20])
def test_image_stamp_offset_s_shifts_every_stamp_from_the_exposure(cell, offset_ms):
    sim, node, executor = cell(publish_images=True, feedback_latency_s=0.1,
                               image_stamp_offset_s=offset_ms * 1e-3,
                               min_camera_info_subscribers=1)
    spin_until(executor, lambda: len(node.images) >= 4 and len(node.infos) >= 4,
               what='four frames')
    for stamp, arrived in node.images:
        exposure = stamp - offset_ms * MS
        assert exposure % sim.sim.dt_ns == 0 and exposure >= 0  # rendered at a step
        assert arrived >= exposure + 100 * MS  # delivered as without an offset
    assert sorted(s for s, _ in node.images) == sorted(node.infos)
    # a negative offset: the frame exposed at 0 would be stamped before 0, and is not taken
    assert (node.images[0][0] - offset_ms * MS == 0) == (offset_ms > 0)


def test_a_camera_outage_publishes_nothing_for_its_span(cell):
    sim, node, executor = cell(publish_images=True, camera_outage_s=[0.1, 0.2],
                               min_camera_info_subscribers=1)
    spin_until(executor, lambda: len(node.infos) >= 12 and len(node.images) >= 12,
               what='frames after the outage')
    stamps = np.array(node.infos)
    assert not np.any((stamps >= 100 * MS) & (stamps < 300 * MS))
    assert np.any(stamps < 100 * MS) and np.any(stamps >= 300 * MS)
    assert sorted(s for s, _ in node.images) == sorted(node.infos)
    # 100, 134, 167, 200, 234, 267 ms: six frames not taken, none counted as lost
    assert sim.frames_outage == 6 and sim.sim.frames_lost == 0
    assert sim.diagnostics.values['frames_outage'] == 6


def test_the_factor_held_while_servoing_is_measured_from_the_first_reference(cell):
    sim, node, executor = cell(real_time_factor=0.5)
    spin_until(executor, lambda: len(node.joints) > 3, what='free-running /joint_states')
    assert 'real_time_factor_servo_mean' not in sim.diagnostics.values  # no servoing yet
    node.pub.publish(Float64MultiArray(data=[float(v) for v in sim.sim.q_start]))
    spin_until(executor, lambda: sim.diagnostics.values.get('servo_windows', 0) >= 2,
               what='two 1 s windows of servoing', deadline_s=30.0)
    values = sim.diagnostics.values
    assert 0.0 < values['real_time_factor_servo_min_1s'] <= values['real_time_factor_servo_mean']
    assert values['real_time_factor_servo_mean'] <= 0.5 * 1.1  # never faster than set


def test_with_min_command_publishers_0_it_starts_uncommanded_and_holds_the_arm(
        context, executor_of):
    """The tool held at the target for ibvs teach: nobody commands, the arm stays there."""
    from ibvs_model import forward_kinematics, paper
    sim = SimNode(context=context, parameter_overrides=[Parameter(k, value=v) for k, v in {
        'resolution': 'VGA', 'publish_images': False, 'command_interface': 'position',
        'real_time_factor': 1.0, 'min_command_publishers': 0,
        'start_at_target': True, 'disturbance_deg': [0.0] * 6}.items()])
    listener = Node('listener', context=context)
    states = []
    listener.create_subscription(JointState, contract.JOINT_STATES, states.append,
                                 contract.RELIABLE)
    executor = executor_of(sim, listener)
    spin_until(executor, lambda: len(states) >= 20)
    q = np.array([s.position for s in states[-10:]])
    assert np.ptp(q, axis=0).max() == 0.0  # held, uncommanded
    pose = forward_kinematics(q[-1])
    assert np.linalg.norm(pose[:3, 3] - paper.target_pose()[:3, 3]) < 1e-9


@pytest.mark.parametrize('params, name', [
    ({'start_at_target': True, 'start_joints': [0.0] * 6}, 'start_at_target'),
    ({'command_interface': 'effort', 'camera_outage_s': [1.0, 0.5]},
     'camera_outage_s'),
    ({'extra_joints': ['joint_3']}, 'extra_joints'),
    ({'extra_joints': ['track_1', 'track_1']}, 'extra_joints'),
    ({'joint_state_rate_hz': 0.0}, 'joint_state_rate_hz'),
])
def test_what_a_mode_cannot_do_is_refused_naming_the_parameter(context, params, name):
    values = {'command_interface': 'position', 'publish_images': False,
              'resolution': 'VGA'}
    values.update(params)
    with pytest.raises(ParameterError, match=f"parameter '{name}'"):
        SimNode(context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in values.items()])


def test_lockstep_warns_about_what_only_free_running_uses(context, capfd):
    """Lockstep publishes /joint_states every step: a set joint_state_rate_hz is ignored."""
    sim = SimNode(context=context, parameter_overrides=[
        Parameter('publish_images', value=False), Parameter('resolution', value='VGA'),
        Parameter('joint_state_rate_hz', value=100.0),
        Parameter('camera_outage_s', value=[1.0, 0.0])])  # duration 0: no outage, accepted
    try:
        err = capfd.readouterr().err
        assert "parameter 'joint_state_rate_hz' = 100.0 is ignored in lockstep" in err
        assert 'real_time_factor' not in err  # at its default: nothing to say
        assert sim.mode.exposes(1_000_000_000)  # no outage
    finally:
        sim.destroy_node()
