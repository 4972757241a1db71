"""
A cell session's bag, as ``ibvs cell`` records it, read by ``ibvs analyse``.

A real cell has no simulator's truth: its tool poses are the kinematics of /joint_states,
and its bag's times the wall clock's (no /clock). A rehearsal's bag that carries its teach
record has the true tool pose where the tool was taught as its target.
"""

from ibvs_analysis import analysis
from ibvs_bringup.recorder import Recorder
from ibvs_common import contract
from ibvs_common.conversions import joint_state, path_msg
from ibvs_model import forward_kinematics, inverse_kinematics, paper
from ibvs_testing.fixtures import spin_until
from nav_msgs.msg import Path
import numpy as np
import pytest
from rclpy.node import Node
from sensor_msgs.msg import JointState
import yaml

MS = 1_000_000


def record(path, context, executor_of, custom, messages, wall_clock):
    """Record ``messages`` [(topic, kind, msg)] as ibvs cell's recorder does; close it."""
    recorder = Recorder(path, context=context, include_per_step=True, custom_data=custom,
                        wall_clock=wall_clock)
    talker = Node(f'talker_{path.name}', context=context)
    executor = executor_of(recorder, talker)
    pubs = {topic: talker.create_publisher(kind, topic, contract.RELIABLE)
            for topic, kind, _ in messages}
    spin_until(executor, lambda: all(p.get_subscription_count() for p in pubs.values()),
               what='discovery')
    for topic, _, msg in messages:
        pubs[topic].publish(msg)
    spin_until(executor, lambda: sum(recorder.counts[t] for t in pubs) == len(messages),
               what='messages')
    recorder.close()


def test_a_cells_bag_is_analysed_from_the_kinematics_of_its_joint_states(
        tmp_path, context, executor_of):
    target = paper.target_pose()
    q_target = inverse_kinematics(target)
    qs = [q_target + np.radians(0.5) * (1.0 - k / 9.0) for k in range(10)]
    params = {'target_position': target[:3, 3].tolist(),
              'target_rotation': target[:3, :3].ravel().tolist()}
    stamp0 = 1_700_000_000 * 10 ** 9  # the wall clock's stamps
    record(tmp_path / 'bag', context, executor_of, {analysis.PARAMS_KEY: yaml.safe_dump(params)},
           [(contract.JOINT_STATES, JointState, joint_state(stamp0 + k * 4 * MS, q))
            for k, q in enumerate(qs)], wall_clock=True)
    meta = yaml.safe_load((tmp_path / 'bag' / 'metadata.yaml').read_text())
    assert meta['rosbag2_bagfile_information']['starting_time'][
        'nanoseconds_since_epoch'] > stamp0 // 2, 'the messages at their wall time, not 0'
    run, metrics = analysis.analyse_bag(tmp_path / 'bag')
    assert metrics['tool_pose_source'] == 'joint_states' and 'target_source' not in metrics
    first = forward_kinematics(qs[0])
    assert metrics['initial_position_error_m'] == np.linalg.norm(first[:3, 3] - target[:3, 3])
    assert metrics['final_position_error_m'] < 1e-9
    assert metrics['sim_duration_s'] == pytest.approx(9 * 0.004, abs=1e-6)  # epoch floats


def test_a_rehearsals_bag_is_compared_with_the_true_pose_taught(tmp_path, context, executor_of):
    true_target = paper.target_pose()
    model_target = forward_kinematics(inverse_kinematics(true_target) - np.radians(0.2))
    params = {'target_position': model_target[:3, 3].tolist(),
              'target_rotation': model_target[:3, :3].ravel().tolist()}
    teach = {analysis.TRUE_TOOL_POSE_KEY: true_target.tolist()}
    poses = [(k * MS, true_target) for k in range(5)]
    record(tmp_path / 'bag', context, executor_of,
           {analysis.PARAMS_KEY: yaml.safe_dump(params),
            analysis.TEACH_KEY: yaml.safe_dump(teach)},
           [(contract.TOOL_PATH, Path, path_msg(poses))], wall_clock=False)
    _, metrics = analysis.analyse_bag(tmp_path / 'bag')
    assert metrics['target_source'] == 'teach' and 'tool_pose_source' not in metrics
    assert metrics['final_position_error_m'] == 0.0
