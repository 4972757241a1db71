"""
sim_node in an rclpy executor with a stand-in controller (docs/design.md §3 and §4).

Each test has its own rclpy Context (and ROS domain); the simulator and the stand-in share a
SingleThreadedExecutor, and every wait is a spin_once loop on a condition with a deadline.
"""

import os
import subprocess
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from ibvs_common import contract
from ibvs_common.conversions import joint_state, pose_matrix, read_joint_path, stamp_ns
from ibvs_common.params import ParameterError
from ibvs_model import look_at, paper, StereoIntrinsics
from ibvs_sim.sim_node import SimNode
from ibvs_sim.world import World
from ibvs_testing.fixtures import spin_until
from nav_msgs.msg import Path
import numpy as np
import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, JointState
from trajectory_msgs.msg import JointTrajectory


class StandIn(Node):
    """
    A stand-in joint controller: answers each /joint_states with one effort command.

    The default answer is gravity compensation from its own PyBullet model of the robot
    (encoder angles; d_q = 0 here), plus ``extra`` torque; ``answer = False`` stops it.
    """

    def __init__(self, context):
        super().__init__('stand_in', context=context)
        self.model = World(render=False)
        self.extra = np.zeros(6)
        self.answer = True
        self.override = None
        self.sent = 0
        self.unanswered = 0
        self.rec = {name: [] for name in ('clock', 'joints', 'left', 'right', 'left_info',
                                          'right_info', 'tool', 'frame_joints', 'pose',
                                          'diagnostics', 'joint_path')}
        self.pub = self.create_publisher(JointState, contract.EFFORT_COMMANDS,
                                         contract.RELIABLE)
        self.create_subscription(JointState, contract.JOINT_STATES, self._on_joints,
                                 contract.RELIABLE)
        self.create_subscription(Clock, contract.CLOCK,
                                 lambda m: self.rec['clock'].append(stamp_ns(m.clock)),
                                 contract.RELIABLE)
        for key, msg_type, topic in (('left', Image, contract.LEFT_IMAGE),
                                     ('right', Image, contract.RIGHT_IMAGE),
                                     ('left_info', CameraInfo, contract.LEFT_INFO),
                                     ('right_info', CameraInfo, contract.RIGHT_INFO)):
            self.create_subscription(msg_type, topic, lambda m, k=key: self.rec[k].append(m),
                                     contract.IMAGES)
        self.create_subscription(Path, contract.TOOL_PATH,
                                 lambda m: self.rec['tool'].extend(m.poses), contract.RELIABLE)
        self.create_subscription(JointState, contract.FRAME_JOINT_STATES,
                                 lambda m: self.rec['frame_joints'].append(m),
                                 contract.RELIABLE)
        self.create_subscription(JointTrajectory, contract.JOINT_PATH,
                                 lambda m: self.rec['joint_path'].append(m), contract.RELIABLE)
        self.create_subscription(PoseStamped, contract.STEREO_POSE,
                                 lambda m: self.rec['pose'].append(m), contract.LATCHED)
        self.create_subscription(DiagnosticArray, contract.DIAGNOSTICS,
                                 lambda m: self.rec['diagnostics'].append(m), 10)

    def destroy_node(self):
        self.model.close()
        return super().destroy_node()

    def _on_joints(self, msg):
        self.rec['joints'].append(msg)
        if not self.answer:
            self.unanswered += 1
            return
        if self.override is not None:
            cmd = self.override(msg)
        else:
            q = np.asarray(msg.position)
            tau = self.model.inverse_dynamics(q, np.asarray(msg.velocity), np.zeros(6))
            cmd = joint_state(msg.header.stamp, effort=tau + self.extra)
        self.pub.publish(cmd)
        self.sent += 1

    def stop_and_settle(self, executor, sim):
        """Stop answering; spin until the simulator waits on a state this node left unanswered."""
        self.answer = False
        self.unanswered = 0
        spin_until(executor, lambda: self.unanswered >= 1 and self.last_stamp() == sim.sim.t_ns
                   and self.rec['clock'] and self.rec['clock'][-1] == sim.last_clock_ns)

    def last_stamp(self):
        joints = self.rec['joints']
        return stamp_ns(joints[-1].header.stamp) if joints else None


def _overrides(**values):
    return [Parameter(k, value=v) for k, v in values.items()]


@pytest.fixture
def graph(context, executor_of):
    """Return a function that builds (sim, stand-in, executor) with parameter overrides."""
    def build(**params):
        params.setdefault('resolution', 'VGA')
        params.setdefault('disturbance_deg', [0.0] * 6)
        sim = SimNode(context=context, parameter_overrides=_overrides(**params))
        stand_in = StandIn(context)
        return sim, stand_in, executor_of(sim, stand_in)

    return build


def test_lockstep_rates_and_stamps(graph):
    """/clock, /joint_states, images: configured rates, consistent stamps, one step each."""
    steps = 200
    sim, stand_in, executor = graph()
    period = 1_000_000
    frame = 33_333_333
    spin_until(executor, lambda: (stand_in.last_stamp() or 0) >= steps * period
               and len(stand_in.rec['right_info']) >= 7 and stand_in.rec['pose'])
    stand_in.stop_and_settle(executor, sim)
    rec = stand_in.rec
    t_end = stand_in.last_stamp()
    # Physics rate: one /joint_states per step, every step, in order; /clock at
    # clock_rate_hz (default 10 Hz: every hundredth step); the tool poses of every step, in
    # batches: when /clock says T, every pose stamped before T has been published.
    expected = list(range(0, t_end + 1, period))
    assert rec['clock'] == expected[::100]
    assert [stamp_ns(m.header.stamp) for m in rec['joints']] == expected
    spin_until(executor, lambda: rec['tool']
               and stamp_ns(rec['tool'][-1].header.stamp) == rec['clock'][-1] - period)
    assert [stamp_ns(m.header.stamp) for m in rec['tool']] == list(
        range(0, rec['clock'][-1], period))
    # One step per command: every /joint_states but the last was answered, once.
    assert stand_in.sent == len(expected) - 1 and sim.sim.k == len(expected) - 1
    # Camera rate: frame n due at n * T_cam, stamped with the step it is rendered from (the
    # first at or after), in both images and both CameraInfo.
    frames = [-(-n * frame // period) * period for n in range(t_end // frame + 1)]
    assert frames[:4] == [0, 34_000_000, 67_000_000, 100_000_000]
    for key in ('left', 'right', 'left_info', 'right_info', 'frame_joints'):
        assert [stamp_ns(m.header.stamp) for m in rec[key]] == frames, key
    # The joint state of each frame is that step's /joint_states.
    by_stamp = {stamp_ns(m.header.stamp): m for m in rec['joints']}
    for m in rec['frame_joints']:
        assert m == by_stamp[stamp_ns(m.header.stamp)]
    k = StereoIntrinsics.zed2('VGA')
    for image, frame_id in ((rec['left'][0], contract.LEFT_CAMERA_FRAME),
                            (rec['right'][0], contract.RIGHT_CAMERA_FRAME)):
        assert (image.width, image.height, image.encoding) == (k.width, k.height, 'rgb8')
        assert image.step == 3 * k.width and len(image.data) == 3 * k.width * k.height
        assert image.header.frame_id == frame_id
    assert list(rec['left_info'][0].k) == pytest.approx(list(k.K.ravel()))
    assert rec['right_info'][0].p[3] == pytest.approx(-k.fu * k.baseline)
    # The camera pose, latched.
    assert np.allclose(pose_matrix(rec['pose'][0].pose),
                       look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT))
    # Encoders at the true start (d_q = 0) and the arm held by gravity compensation.
    q0 = np.asarray(rec['joints'][0].position)
    assert np.allclose(q0, sim.sim.q_start, atol=1e-12)
    assert np.abs(np.asarray(rec['joints'][-1].position) - q0).max() < 1e-6
    assert np.allclose(pose_matrix(rec['tool'][0].pose), paper.scenario_start_pose(1),
                       atol=1e-7)


def test_joint_path_has_every_step_once_and_its_last_batch_at_the_end(graph):
    """/ibvs/joint_path: each step's /joint_states once, the same float64s, in batches."""
    period = 1_000_000
    sim, stand_in, executor = graph(publish_images=False)
    spin_until(executor, lambda: (stand_in.last_stamp() or 0) >= 250 * period)
    stand_in.stop_and_settle(executor, sim)
    rec = stand_in.rec
    assert rec['clock'][:3] == [0, 100 * period, 200 * period]

    def batched():
        return np.concatenate([read_joint_path(b)[0] for b in rec['joint_path']]).tolist()

    # Just before each /clock (T), one batch of the steps since the last one: [T - 0.1 s, T).
    spin_until(executor, lambda: rec['joint_path'] and batched()[-1] == rec['clock'][-1] - period)
    assert [stamp_ns(b.header.stamp) for b in rec['joint_path']] == rec['clock'][:-1]
    assert [len(b.points) for b in rec['joint_path']] == [100] * (len(rec['clock']) - 1)
    assert batched() == list(range(0, rec['clock'][-1], period))
    # The end of a run: the simulator, destroyed, publishes the steps since the last /clock.
    sim.destroy_node()
    spin_until(executor, lambda: batched()[-1] == stand_in.last_stamp())
    assert batched() == [stamp_ns(m.header.stamp) for m in rec['joints']]
    # The same values as the /joint_states of those steps, bit for bit.
    states = [read_joint_path(b) for b in rec['joint_path']]
    for k, field in ((1, 'position'), (2, 'velocity'), (3, 'effort')):
        assert np.concatenate([s[k] for s in states]).tobytes() == \
            np.array([getattr(m, field) for m in rec['joints']], dtype=float).tobytes(), field


def test_clock_at_its_rate_on_the_step_grid(graph):
    """/clock: the first step at or after each multiple of 1 / clock_rate_hz, once a step."""
    for rate, expected in ((300.0, [0, 4, 7, 10, 14, 17, 20]),
                           (5000.0, list(range(0, 21)))):
        sim, stand_in, executor = graph(publish_images=False, clock_rate_hz=rate)
        spin_until(executor, lambda: (stand_in.last_stamp() or 0) >= 20_000_000)
        stand_in.stop_and_settle(executor, sim)
        got = [t for t in stand_in.rec['clock'] if t <= 20_000_000]
        assert got == [ms * 1_000_000 for ms in expected], rate


def test_one_step_per_command_only_with_the_current_stamp(graph):
    sim, stand_in, executor = graph(publish_images=False)
    spin_until(executor, lambda: (stand_in.last_stamp() or 0) >= 5_000_000)
    stand_in.stop_and_settle(executor, sim)
    k = sim.sim.k
    t = sim.sim.t_ns
    stuck = len(stand_in.rec['joints'])
    # No command: no step, however long we spin (here 20 spins).
    for _ in range(20):
        executor.spin_once(timeout_sec=0.01)
    assert sim.sim.k == k and len(stand_in.rec['joints']) == stuck
    # Older and newer stamps are rejected and do not step.
    zeros = np.zeros(6)
    for stamp, reason in ((t - 1_000_000, 'stale stamp'), (t + 1_000_000, 'early stamp')):
        stand_in.pub.publish(joint_state(stamp, effort=zeros))
        key = f'{contract.EFFORT_COMMANDS}: {reason}'
        spin_until(executor, lambda key=key: sim.diagnostics.rejections[key] == 1)
        assert sim.sim.k == k
    # The current stamp steps exactly once, and its duplicate is then stale.
    for _ in range(2):
        stand_in.pub.publish(joint_state(t, effort=zeros))
    spin_until(executor, lambda: sim.diagnostics.rejections[
        f'{contract.EFFORT_COMMANDS}: stale stamp'] == 2 and stand_in.last_stamp() > t)
    assert sim.sim.k == k + 1
    assert stand_in.last_stamp() == t + 1_000_000


def test_waiting_for_a_stamp_is_logged(graph, capfd):
    """Each steady-clock tick without a step logs the stamp the simulator waits for."""
    sim, stand_in, executor = graph(publish_images=False)
    spin_until(executor, lambda: (stand_in.last_stamp() or 0) >= 3_000_000)
    stand_in.stop_and_settle(executor, sim)
    capfd.readouterr()
    sim.waiting.tick()  # the timer's tick: first after progress, then without
    sim.waiting.tick()
    err = capfd.readouterr().err
    assert f'waiting for {contract.EFFORT_COMMANDS} stamped {sim.sim.t_ns} ns' in err


def test_duration_s_stops_the_steps_at_that_sim_time_and_says_so(graph, capfd):
    """Started by hand with duration_s: steps [0, duration), the last batches and /clock."""
    period = 1_000_000
    sim, stand_in, executor = graph(publish_images=False, duration_s=0.025)
    spin_until(executor, lambda: sim.finished)
    for _ in range(20):  # no step after the end, however long it spins
        executor.spin_once(timeout_sec=0.01)
    rec = stand_in.rec
    assert sim.sim.t_ns == 25 * period and stand_in.last_stamp() == 24 * period
    spin_until(executor, lambda: rec['clock'] and rec['clock'][-1] == 25 * period)
    spin_until(executor, lambda: rec['tool'] and stamp_ns(rec['tool'][-1].header.stamp)
               == 24 * period)
    assert 'stopped at t = 0.025 s (duration_s 0.025)' in capfd.readouterr().err
    assert sim._progress().startswith('t = 0.025 s of 0.025 s (step 25), stopped at duration_s')
    sim.waiting.tick()  # finished: nothing to wait for, nothing said
    assert 'waiting' not in capfd.readouterr().err


def _bad(msg, kind):
    cmd = joint_state(msg.header.stamp, effort=np.zeros(6))
    if kind == 'nan':
        cmd.effort[2] = float('nan')
    elif kind == 'inf':
        cmd.effort[4] = float('-inf')
    elif kind == 'length':
        cmd.effort = [0.0] * 5
    elif kind == 'names':
        cmd.name = ['a', 'b', 'c', 'd', 'e', 'f']
    return cmd


def test_bad_commands_are_rejected_counted_and_the_arm_holds(graph):
    """Wrong length, NaN, inf, wrong names: rejected, on /diagnostics, arm held in place."""
    sim, stand_in, executor = graph(publish_images=False)
    # Let the arm move first (extra torque), so that holding is more than standing still.
    stand_in.extra = np.array([200.0, -300.0, 100.0, 20.0, -10.0, 1.0])
    spin_until(executor, lambda: (stand_in.last_stamp() or 0) >= 20_000_000)
    stand_in.stop_and_settle(executor, sim)
    moving = np.abs(np.asarray(stand_in.rec['joints'][-1].velocity)).max()
    assert moving > 1e-3
    kinds = ('nan', 'inf', 'length', 'names')
    reasons = ('non-finite effort', 'non-finite effort', 'wrong effort length',
               'missing joints')
    for kind in kinds:
        before = stand_in.rec['joints'][-1]
        stand_in.pub.publish(_bad(before, kind))
        spin_until(executor, lambda before=before: stand_in.rec['joints'][-1] is not before)
        after = stand_in.rec['joints'][-1]
        assert stamp_ns(after.header.stamp) == stamp_ns(before.header.stamp) + 1_000_000
        assert np.abs(np.asarray(after.position) - np.asarray(before.position)).max() < 1e-9
        assert np.abs(np.asarray(after.velocity)).max() < 1e-9
    counts = sim.diagnostics.rejections
    assert counts[f'{contract.EFFORT_COMMANDS}: non-finite effort'] == 2
    for reason in reasons[2:]:
        assert counts[f'{contract.EFFORT_COMMANDS}: {reason}'] == 1
    assert sim.mode.held_steps == 4

    def published():
        for msg in stand_in.rec['diagnostics']:
            for status in msg.status:
                values = {kv.key: kv.value for kv in status.values}
                if status.name.startswith('sim_node') and values.get('rejected_total') == '4':
                    return True
        return False
    spin_until(executor, published, deadline_s=10.0)


BAD_PARAMETERS = [
    ({'physics_rate_hz': -1000.0}, 'physics_rate_hz'),
    ({'camera_rate_hz': -30.0}, 'camera_rate_hz'),
    ({'physics_rate_hz': 50.0}, 'physics_rate_hz'),
    ({'camera_rate_hz': 2000.0}, 'camera_rate_hz'),
    ({'scenario': 4}, 'scenario'),
    ({'scenario': 1, 'l2_scale': 0.3, 'l4_scale': 0.3}, 'scenario'),
    ({'resolution': 'HD1080'}, 'resolution'),
    ({'renderer': 'opengl'}, 'renderer'),  # retired: refused, not ignored
    ({'renderer': 'egl'}, 'renderer'),
    ({'camera_eye': [1.0, 2.0, 3.0], 'camera_look_at': [1.0, 2.0, 3.0]}, 'camera_look_at'),
    ({'disturbance_deg': [0.1, 0.2]}, 'disturbance_deg'),
    ({'publish_images': 'yes'}, 'publish_images'),
    ({'duration_s': -1.0}, 'duration_s'),
]


@pytest.mark.parametrize('params, name', BAD_PARAMETERS,
                         ids=[n + str(i) for i, (_, n) in enumerate(BAD_PARAMETERS)])
def test_bad_parameter_stops_the_node_naming_it(context, params, name):
    with pytest.raises(ParameterError) as info:
        SimNode(context=context, parameter_overrides=_overrides(**params))
    assert f"'{name}'" in str(info.value)


def _env(domain_id):
    env = dict(os.environ)
    env['ROS_DOMAIN_ID'] = str(domain_id)
    env['PYTHONUNBUFFERED'] = '1'
    return env


def test_main_exits_with_code_2_and_names_the_parameter(domain_id):
    """As ``ros2 run ibvs_sim sim_node --ros-args -p camera_rate_hz:=2000.0`` would."""
    proc = subprocess.run(
        [sys.executable, '-m', 'ibvs_sim.sim_node', '--ros-args', '-p',
         'camera_rate_hz:=2000.0'],
        env=_env(domain_id), capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert "'camera_rate_hz'" in proc.stderr


def test_waiting_is_logged_once_a_second(domain_id):
    """Alone, the node says what it waits for (here: somebody to answer it)."""
    proc = subprocess.Popen(
        [sys.executable, '-m', 'ibvs_sim.sim_node', '--ros-args', '-p',
         'publish_images:=false'],
        env=_env(domain_id), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = []
    try:
        for line in proc.stdout:
            lines.append(line)
            if sum('waiting to start' in line for line in lines) >= 2:
                break
        waits = [line for line in lines if 'waiting to start' in line]
        assert len(waits) == 2, ''.join(lines)
        assert contract.EFFORT_COMMANDS in waits[0] and contract.JOINT_STATES in waits[0]
    finally:
        proc.send_signal(2)
        assert proc.wait(timeout=30) == 0


@pytest.mark.parametrize('param, topic, msg_type', [
    ('min_tool_path_subscribers', contract.TOOL_PATH, Path),
    ('min_joint_path_subscribers', contract.JOINT_PATH, JointTrajectory),
    ('min_frame_joint_state_subscribers', contract.FRAME_JOINT_STATES, JointState)])
def test_the_start_waits_for_the_subscribers_it_is_told_of(graph, param, topic, msg_type):
    # The stand-in subscribes the topic once; ask for one more, then add it.
    sim, stand_in, executor = graph(publish_images=False, **{param: 2})
    deadline = time.monotonic() + 3.0
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    assert not sim.started
    assert sim._missing() == [f'1 more subscriber(s) on {topic}']
    stand_in.create_subscription(msg_type, topic, lambda m: None, contract.RELIABLE)
    spin_until(executor, lambda: sim.started)
    spin_until(executor, lambda: stand_in.rec['tool'])
    assert stamp_ns(stand_in.rec['tool'][0].header.stamp) == 0
