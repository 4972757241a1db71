"""
sim_node's real camera in an executor: published noise, calibrated camera, lost frames.

The lost-frame test closes the lockstep with the real joint controller and a stand-in for
the vision chain that answers every frame it receives (as the feature node and adaptive
feedback do, one q_feedback per frame with images): the graph must keep stepping past
every frame the camera loses.
"""


from geometry_msgs.msg import PoseStamped
from ibvs_common import contract
from ibvs_common.conversions import joint_state, joint_trajectory, pose_matrix, stamp_ns
from ibvs_common.params import ParameterError
from ibvs_control.joint_controller_node import JointControllerNode
from ibvs_sim import markers
from ibvs_sim.camera_effects import error_transform
from ibvs_sim.node_params import SimConfig
from ibvs_sim.sim_node import SimNode
from ibvs_sim.simulator import Simulator
from ibvs_testing.fixtures import spin_until as shared_spin_until
import numpy as np
import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory

DEADLINE_S = 120.0
#: The frames of the node's start pose without camera effects, drawn here.
VGA = SimConfig.make(resolution='VGA')


def _overrides(**values):
    values.setdefault('resolution', 'VGA')
    values.setdefault('disturbance_deg', [0.0] * 6)
    return [Parameter(k, value=v) for k, v in values.items()]


class Vision(Node):
    """
    Stand-in for feature node + adaptive feedback: q_feedback 0 for every frame with images.

    With ``q0`` it also publishes a feedforward trajectory that holds q0, for the joint
    controller. It records what it hears.
    """

    def __init__(self, context, q0=None):
        super().__init__('vision_stand_in', context=context)
        self.rec = {'info': [], 'lost': [], 'left': [], 'pose': [], 'joints': []}
        self.fb = self.create_publisher(JointState, contract.Q_FEEDBACK, contract.RELIABLE)
        self.create_subscription(CameraInfo, contract.LEFT_INFO, self._on_info,
                                 contract.IMAGES)
        self.create_subscription(Image, contract.LEFT_IMAGE,
                                 lambda m: self.rec['left'].append(m), contract.IMAGES)
        self.create_subscription(Image, contract.RIGHT_IMAGE, lambda m: None,
                                 contract.IMAGES)
        self.create_subscription(Header, contract.FRAME_LOST,
                                 lambda m: self.rec['lost'].append(stamp_ns(m.stamp)),
                                 contract.RELIABLE)
        self.create_subscription(PoseStamped, contract.STEREO_POSE,
                                 lambda m: self.rec['pose'].append(m), contract.LATCHED)
        self.create_subscription(JointState, contract.JOINT_STATES,
                                 lambda m: self.rec['joints'].append(m), contract.RELIABLE)
        self.ff = None
        if q0 is not None:
            self.ff = self.create_publisher(JointTrajectory, contract.FEEDFORWARD_TRAJECTORY,
                                            contract.LATCHED)
            self.ff.publish(joint_trajectory(0, 1_000_000, [q0]))

    def _on_info(self, msg):
        self.rec['info'].append(msg)
        self.fb.publish(joint_state(msg.header.stamp, position=np.zeros(6)))


def spin_until(executor, condition, deadline_s=DEADLINE_S):
    shared_spin_until(executor, condition, deadline_s)


@pytest.fixture
def graph(context):
    """Yield a function: (sim, vision, executor) with the real joint controller."""
    made = []

    def build(**params):
        sim = SimNode(context=context, parameter_overrides=_overrides(**params))
        vision = Vision(context, sim.sim.encoders()[0])
        controller = JointControllerNode(context=context, parameter_overrides=[
            Parameter(k, value=params[k]) for k in ('camera_rate_hz', 'feedback_latency_s')
            if k in params])
        executor = SingleThreadedExecutor(context=context)
        for node in (sim, vision, controller):
            executor.add_node(node)
        made.append((executor, (controller, vision, sim)))
        return sim, vision, controller, executor

    yield build
    for executor, nodes in made:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()


def test_published_images_carry_the_set_noise(graph):
    stddev = 0.02
    sim, vision, _, executor = graph(image_noise_stddev=stddev, camera_seed=3)
    spin_until(executor, lambda: vision.rec['left'])
    msg = vision.rec['left'][0]
    assert stamp_ns(msg.header.stamp) == 0
    published = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.width, 3)
    # The same frame without noise: frame 0 shows the start pose, rendered alike.
    clean = Simulator(VGA)
    try:
        _, (truth, _), _ = clean.take_frame()
    finally:
        clean.close()
    # Pixels 5 sigma away from black and white: no clipping there.
    margin = 5.0 * stddev * 255.0
    inside = (truth >= margin) & (truth <= 255.0 - margin)
    assert inside.mean() > 0.5
    diff = (published.astype(float) - truth)[inside] / 255.0
    assert abs(diff.std() / stddev - 1.0) < 0.05
    assert abs(diff.mean()) < 5.0 * stddev / np.sqrt(diff.size)


def test_two_runs_with_one_seed_publish_identical_images(context):
    images = []
    for _ in range(2):
        sim = SimNode(context=context, parameter_overrides=_overrides(
            image_noise_stddev=0.01, camera_seed=42))
        try:
            _, pair, _ = sim.sim.take_frame()
            images.append(pair)
        finally:
            sim.destroy_node()
    assert all(np.array_equal(a, b) for a, b in zip(*images))


def test_the_node_draws_with_opengl_and_says_on_which_device(context):
    """The one renderer, chosen by no parameter; its device on /diagnostics (render_device)."""
    sim = SimNode(context=context, parameter_overrides=_overrides())
    try:
        device = sim.sim.world.render_device
        assert sim.diagnostics.values['render_device'] == device.gl_renderer
        assert sim.diagnostics.values['render_hardware'] is device.hardware
        _, (left, right), _ = sim.sim.take_frame()
        # The scenario 1 start: both markers in both images.
        centres, _ = markers.marker_centres(left, right)
        assert np.all(np.isfinite(centres))
    finally:
        sim.destroy_node()
    physics = SimNode(context=context, parameter_overrides=_overrides(publish_images=False))
    try:
        assert physics.sim.world.renderer is None  # nothing drawn, no OpenGL loaded
        assert 'render_device' not in physics.diagnostics.values
    finally:
        physics.destroy_node()


def test_published_camera_differs_from_the_rendering_one_by_exactly_the_error(graph):
    xyz, rpy = [0.002, -0.001, 0.003], [0.1, 0.2, -0.3]
    sim, vision, _, executor = graph(camera_pose_error_xyz_m=xyz, camera_pose_error_rpy_deg=rpy,
                                     focal_length_error=1.02)
    spin_until(executor, lambda: vision.rec['pose'] and vision.rec['info'])
    published = pose_matrix(vision.rec['pose'][0].pose)
    rendering = sim.sim.camera.pose_C_O
    np.testing.assert_allclose(np.linalg.inv(rendering) @ published,
                               error_transform(xyz, rpy), atol=1e-9)
    info = vision.rec['info'][0]
    true = sim.sim.camera.intrinsics
    assert info.k[0] == pytest.approx(1.02 * true.fu, rel=1e-12)
    assert info.k[4] == pytest.approx(1.02 * true.fv, rel=1e-12)
    assert (info.k[2], info.k[5]) == (true.cu, true.cv)


def test_lost_frames_do_not_stall_the_lockstep(graph):
    """With 30 % of the frames lost the graph steps on; each frame has images or a notice."""
    steps = 1500
    # 150 frames; what is under test is which frames are lost, not what they show.
    sim, vision, controller, executor = graph(
        camera_rate_hz=100.0, frame_drop_probability=0.3, camera_seed=9,
        render_marker_supersampling=1)
    spin_until(executor, lambda: sim.sim.k >= steps)
    # Stop the lockstep (nobody answers any more) and collect what is still on its way.
    executor.remove_node(controller)
    frames = sim.sim.next_frame
    spin_until(executor, lambda: len(vision.rec['lost']) + len(vision.rec['info']) >= frames)
    assert sim.sim.next_frame == frames and frames >= steps // 10
    lost = vision.rec['lost']
    kept = [stamp_ns(m.header.stamp) for m in vision.rec['info']]
    assert sorted(lost + kept) == [n * 10_000_000 for n in range(frames)]
    assert not set(lost) & set(kept)
    assert sim.sim.frames_lost == len(lost)
    assert 0.15 * frames < len(lost) < 0.45 * frames
    # the joint controller answered every step, holding q_feedback through the lost frames
    assert controller.mode.commands >= steps and controller.mode.frames_lost > 0
    # and the arm, held on its start reference, stayed there
    q = np.array([m.position for m in vision.rec['joints']])
    assert np.abs(q - q[0]).max() < 1e-3


@pytest.mark.parametrize('params, name', [
    ({'image_noise_stddev': -0.01}, 'image_noise_stddev'),
    ({'image_noise_stddev': 0.6}, 'image_noise_stddev'),
    ({'frame_drop_probability': 0.95}, 'frame_drop_probability'),
    ({'camera_seed': -1}, 'camera_seed'),
    ({'camera_seed': 0.5}, 'camera_seed'),
    ({'camera_pose_error_xyz_m': [0.0, 0.0]}, 'camera_pose_error_xyz_m'),
    ({'camera_pose_error_xyz_m': [1.0, 0.0, 0.0]}, 'camera_pose_error_xyz_m'),
    ({'camera_pose_error_rpy_deg': [0.0, 20.0, 0.0]}, 'camera_pose_error_rpy_deg'),
    ({'focal_length_error': 0.0}, 'focal_length_error'),
    ({'target_features_source': 'guess'}, 'target_features_source'),
    ({'target_features_source': 'taught', 'publish_images': False},
     'target_features_source'),
])
def test_bad_camera_parameter_stops_the_node_naming_it(context, params, name):
    with pytest.raises(ParameterError) as info:
        SimNode(context=context, parameter_overrides=_overrides(**params))
    assert f"'{name}'" in str(info.value)
