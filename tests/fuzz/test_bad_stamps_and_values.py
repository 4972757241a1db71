"""
Bad stamps and out-of-range values into the nodes, one test each, on the fuzz rigs (:mod:`.rigs`).

Each test sends inputs a node must not act on and checks what must hold instead: rejected
and counted under its topic, never stored, and the node still acting on the next valid
input.
"""

from ibvs_common import contract
from ibvs_common.conversions import (camera_infos, joint_state, joint_trajectory, read_joints,
                                     stamp_ns)
import numpy as np
from std_msgs.msg import Header

from . import rigs
from .cases import poses
from .harness import stamp
from .rigs import CAMERA_NS, MS, Q0


def _run(rig):
    rig.setup()
    assert rig.recovered()
    return rig


def test_sim_node_rejects_an_absurd_effort_and_keeps_stepping(context):
    rig = _run(rigs.SimRig(context))
    try:
        for effort in (1e308, 1e15):
            t = rig.node.sim.t_ns
            rig.deliver(contract.EFFORT_COMMANDS,
                        joint_state(t, effort=np.r_[effort, np.zeros(5)]))
        assert rig.reasons(contract.EFFORT_COMMANDS)['effort out of range'] == 2
        assert np.all(np.isfinite(rig.node.sim.encoders()[0]))
        assert rig.recovered()
    finally:
        rig.close()


def test_future_q_feedback_is_not_stored_and_cannot_fill_the_buffer(context):
    rig = _run(rigs.JointControllerRig(context))
    try:
        node = rig.node
        for n in range(1, 1101):  # a paced stream, each on the frame grid, far ahead
            rig.deliver(contract.Q_FEEDBACK, joint_state(
                rigs.frame_ns(n + 100_000), np.zeros(6)))
        assert rig.reasons(contract.Q_FEEDBACK)['stamp in the future'] == 1100
        assert len(node.mode._lockstep.feedback) <= 2
        for _ in range(3 * CAMERA_NS // MS):  # past three frames: new q_feedbacks get in
            assert rig.recovered()
        assert rig.reasons(contract.Q_FEEDBACK)['buffer full'] == 0
    finally:
        rig.close()


def _stalls_on_bad_stamps(rig):
    try:
        t = rig.next_ns()
        for bad in (stamp(t // 10 ** 9, 4_000_000_000), stamp(2 ** 31 - 1)):
            msg = joint_state(0, Q0, np.zeros(6))
            msg.header.stamp = bad
            rig.deliver(contract.JOINT_STATES, msg)
        nan = joint_state(0, np.full(6, np.nan), np.zeros(6))
        nan.header.stamp = stamp(2 ** 31 - 1)  # rejected for its value, yet its stamp counted
        rig.deliver(contract.JOINT_STATES, nan)
        reasons = rig.reasons(contract.JOINT_STATES)
        assert reasons['malformed stamp'] == 1 and reasons['stamp in the future'] == 2
        for _ in range(3):
            assert rig.recovered()
    finally:
        rig.close()


def test_bad_stamps_do_not_stall_the_adaptive_feedback(context):
    _stalls_on_bad_stamps(_run(rigs.AdaptiveFeedbackRig(context)))


def test_bad_stamps_do_not_stall_the_feature_node(context):
    _stalls_on_bad_stamps(_run(rigs.FeatureRig(context)))


def test_a_far_future_first_state_does_not_start_the_feedforward(context):
    rig = rigs.FeedforwardRig(context)
    try:
        far = joint_state(0, Q0, np.zeros(6))
        far.header.stamp = stamp(2 ** 31 - 1)
        rig.deliver(contract.JOINT_STATES, far)  # /clock not yet: time unknown, taken as 0
        assert rig.reasons(contract.JOINT_STATES)['stamp in the future'] == 1
        assert rig.spin_until(rig.valid_step())
        assert stamp_ns(rig.trajectories[0].header.stamp) == 0
    finally:
        rig.close()


def test_feedforward_refuses_states_beyond_the_travel_and_keeps_listening(context):
    rig = rigs.FeedforwardRig(context)
    try:
        for q in (np.full(6, 1e308), np.r_[100.0, Q0[1:]], np.r_[Q0[:5], -1e6]):
            rig.deliver(contract.JOINT_STATES, joint_state(0, q, np.zeros(6)))
        assert rig.reasons(contract.JOINT_STATES)['position out of range'] == 3
        assert rig.recovered()  # still listening, nothing published
        assert rig.spin_until(rig.valid_step())
        points = np.array([p.positions for p in rig.trajectories[0].points])
        assert np.all(np.isfinite(points))
    finally:
        rig.close()


def test_joint_controller_refuses_bad_trajectory_stamps(context):
    rig = _run(rigs.JointControllerRig(context))
    try:
        for bad in (stamp(-5), stamp(0, 4_000_000_000), stamp(2 ** 31 - 1)):
            msg = joint_trajectory(0, MS, np.tile(Q0, (5, 1)))
            msg.header.stamp = bad
            rig.deliver(contract.FEEDFORWARD_TRAJECTORY, msg)
        assert sum(rig.reasons(contract.FEEDFORWARD_TRAJECTORY).values()) == 3
        assert rig.node.mode._trajectory[0] == 0  # the good one still holds
        assert rig.recovered()
    finally:
        rig.close()


def test_joint_controller_never_publishes_a_non_finite_effort(context):
    rig = _run(rigs.JointControllerRig(context))
    try:
        t = rig.next_ns()
        rig.deliver(contract.JOINT_STATES, joint_state(t, np.full(6, 1e308), np.zeros(6)))
        rig.deliver(contract.JOINT_STATES, joint_state(t, Q0, np.full(6, 1e308)))
        huge = np.tile(Q0, (5, 1))
        huge[:, 0] = 1e308
        rig.deliver(contract.FEEDFORWARD_TRAJECTORY, joint_trajectory(0, MS, huge))
        for _ in range(5):
            assert rig.recovered()
        assert all(np.all(np.isfinite(read_joints(m, 'effort'))) for m in rig.efforts)
        assert rig.reasons(contract.JOINT_STATES)['position out of range'] == 1
        assert rig.reasons(contract.FEEDFORWARD_TRAJECTORY)['positions out of range'] == 1
    finally:
        rig.close()


def test_joint_controller_counts_off_grid_frame_stamps(context):
    rig = _run(rigs.JointControllerRig(context))
    try:
        off_grid = rigs.frame_ns(1) + 1
        rig.deliver(contract.Q_FEEDBACK, joint_state(off_grid, np.zeros(6)))
        rig.deliver(contract.FRAME_LOST, Header(stamp=stamp(0, off_grid)))
        assert rig.reasons(contract.Q_FEEDBACK)['off the frame grid'] == 1
        assert rig.reasons(contract.FRAME_LOST)['off the frame grid'] == 1
    finally:
        rig.close()


def test_feature_node_counts_minor_inputs_under_their_topic(context):
    rig = _run(rigs.FeatureRig(context))
    try:
        left, _ = camera_infos(rig.camera.intrinsics, 0)
        left.width = left.height = 100000
        rig.deliver(contract.LEFT_INFO, left)
        (_, _, looking_away), = [c for c in poses(contract.STEREO_POSE, rig.camera.pose_C_O)
                                 if c[0] == 'camera looking away']
        rig.deliver(contract.STEREO_POSE, looking_away()[0])
        neg = joint_state(0, Q0, np.zeros(6))
        neg.header.stamp = stamp(-1)
        rig.deliver(contract.JOINT_STATES, neg)
        rig.deliver(contract.JOINT_STATES, joint_state(rig.next_ns(), np.full(6, 1e308)))
        assert rig.reasons(contract.LEFT_INFO)['bad camera_info size'] == 1
        assert rig.reasons(contract.STEREO_POSE)['camera looks away from the robot'] == 1
        assert rig.reasons(contract.JOINT_STATES)['negative time'] == 1
        assert rig.reasons(contract.JOINT_STATES)['position out of range'] == 1
        keys = [kv.key for kv in rig.diagnostics.status().values
                if kv.key.startswith('rejected[')]
        assert all(k.startswith('rejected[/') or k.startswith('rejected[stereo frame: ')
                   for k in keys), keys
        assert rig.recovered()
    finally:
        rig.close()


def test_fuzz_sim_node_refuses_a_trajectory_command_bad_anywhere(context):
    rig = _run(rigs.SimPositionRig(context, 'joint_trajectory'))
    try:
        reference = rig.node.mode.servo.reference.copy()
        rows = np.tile(rig.q_start, (3, 1))
        rows[0, 2] = np.nan  # the last point, the one the drive takes, is good
        rig.deliver(rig.topic, joint_trajectory(0, MS, rows))
        ragged = joint_trajectory(0, MS, np.tile(rig.q_start, (3, 1)))
        ragged.points[1].positions = [0.0] * 5
        rig.deliver(rig.topic, ragged)
        for bad in (stamp(-5), stamp(0, 4_000_000_000), stamp(2 ** 31 - 1)):
            msg = rig.command(rig.q_start + 0.02)
            msg.header.stamp = bad
            rig.deliver(rig.topic, msg)
        reasons = rig.reasons(rig.topic)
        assert reasons['non-finite positions'] == 1 and reasons['wrong positions length'] == 1
        assert reasons['negative time'] == 1 and reasons['malformed stamp'] == 1
        assert reasons['stamp in the future'] == 1
        np.testing.assert_array_equal(rig.node.mode.servo.reference, reference)
        assert rig.recovered()
    finally:
        rig.close()


def test_fuzz_a_far_future_joint_state_does_not_stop_the_viz_markers(context):
    rig = _run(rigs.VizRig(context))
    try:
        far = joint_state(0, Q0, np.zeros(6))
        far.header.stamp = stamp(2 ** 31 - 1)
        rig.deliver(contract.JOINT_STATES, far)
        rig.deliver(contract.JOINT_STATES, joint_state(rig.next_ns(), np.full(6, 1e6)))
        reasons = rig.reasons(contract.JOINT_STATES)
        assert reasons['stamp in the future'] == 1 and reasons['position out of range'] == 1
        for _ in range(3):  # the next frames are still drawn, not refused as going back
            assert rig.recovered()
        assert rig.reasons(contract.JOINT_STATES)['stamp went back'] == 0
        assert rig.published_finite()
    finally:
        rig.close()


def test_fuzz_viz_counts_camera_inputs_under_their_topic(context):
    rig = _run(rigs.VizRig(context))
    try:
        left, _ = camera_infos(rig.camera.intrinsics, 0)
        left.width = left.height = 100000
        rig.deliver(contract.LEFT_INFO, left)
        (_, _, looking_away), = [c for c in poses(contract.STEREO_POSE, rig.camera.pose_C_O)
                                 if c[0] == 'camera looking away']
        rig.deliver(contract.STEREO_POSE, looking_away()[0])
        assert rig.reasons(contract.LEFT_INFO)['bad camera_info size'] == 1
        assert rig.reasons(contract.STEREO_POSE)['camera looks away from the robot'] == 1
        assert rig.node._camera is not None  # the good camera still drawn
        assert rig.recovered()
    finally:
        rig.close()
