"""
A real-cell run's bag: one publisher of /robot_description, and the arm's frames are ABB's.

viz_node publishes neither a second /robot_description nor its own (DH) link frames beside
the ones robot_state_publisher publishes from ABB's URDF. One run of
``real_cell`` (``ibvs run real_cell --duration 1``) through the installed graph; its bag's
metadata lists, per topic, the QoS of each publisher the recorder saw
(``offered_qos_profiles``, ibvs_bringup.recorder: one entry per publisher), and its /tf,
composed with /tf_static as a tf listener does, is checked against
:func:`ibvs_model.abb_urdf.link_poses` at four joint states of the run.
"""

from pathlib import Path

from ibvs_analysis import analysis, video
from ibvs_common import contract
from ibvs_common.conversions import stamp_ns
from ibvs_experiments import runner
from ibvs_model import abb_urdf, IRB4600
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores
import yaml

DURATION_S = 1.0
#: The frames of ABB's URDF (robot_state_publisher's), moving and fixed.
ARM_FRAMES = set(abb_urdf.LINK_NAMES) | {c for _, _, c, *_ in abb_urdf.ABB_FIXED_JOINTS}


@pytest.fixture(scope='module')
def run_dir(installed_workspace, tmp_path_factory):
    out = tmp_path_factory.mktemp('real_cell')
    runner.run_scenario('real_cell', out, duration_s=DURATION_S, figures=False,
                        progress=lambda *_: None)
    return out


def _metadata_topics(bag):
    meta = yaml.safe_load((Path(bag) / 'metadata.yaml').read_text())
    return {t['topic_metadata']['name']: t
            for t in meta['rosbag2_bagfile_information']['topics_with_message_count']}


def _publishers(entry):
    offered = entry['topic_metadata']['offered_qos_profiles']
    if isinstance(offered, str):  # rosbag2 before version 9 kept a YAML string
        offered = yaml.safe_load(offered) or []
    return offered


def test_one_publisher_of_the_description_and_of_the_arms_frames(run_dir):
    topics = _metadata_topics(run_dir / 'bag')
    assert len(_publishers(topics[contract.ROBOT_DESCRIPTION])) == 1
    assert topics[contract.ROBOT_DESCRIPTION]['message_count'] == 1
    assert len(_publishers(topics[contract.TF])) == 1  # robot_state_node alone
    # the rosbags reader sees the same offered QoS: depth 1, transient local
    with AnyReader([run_dir / 'bag'], default_typestore=get_typestore(Stores.ROS2_JAZZY)) \
            as reader:
        conns = [c for c in reader.connections if c.topic == contract.ROBOT_DESCRIPTION]
        assert len(conns) == 1
        (qos,) = conns[0].ext.offered_qos_profiles
        assert qos.durability.name == 'TRANSIENT_LOCAL' and qos.reliability.name == 'RELIABLE'
        params = IRB4600.scaled(1.0, 1.0)
        for _, _, raw in reader.messages(connections=conns):
            text = reader.deserialize(raw, conns[0].msgtype).data
            assert text == abb_urdf.robot_description(params)


def test_arm_frames_in_tf_are_abbs_at_four_joint_states(run_dir):
    bag = run_dir / 'bag'
    run = analysis.load_run(bag)
    d_q = np.radians(run.params['disturbance_deg'])
    params = IRB4600.scaled(run.params['l2_scale'], run.params['l4_scale'])
    t, q, *_ = analysis.load_joints(bag)
    by_ns = {int(round(ti * 1e9)): qi for ti, qi in zip(t, q)}
    tf, static = [], {}
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic in (contract.TF, contract.TF_STATIC)]
        for conn, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == contract.TF:
                tf.append(msg)
            else:
                children = {t_.child_frame_id for t_ in msg.transforms}
                # Nobody but robot_state_node publishes an arm frame, fixed or moving: a
                # static message holds ABB's fixed joints alone (its) or none (viz_node's,
                # sent whole again once the camera is known).
                assert not children & ARM_FRAMES or children == {'base', 'flange', 'tool0'}
                static.update((t_.child_frame_id, (t_.header.frame_id,
                                                   video._matrix(t_.transform)))
                              for t_ in msg.transforms)
    assert {'base', 'flange', 'tool0', 'screwdriver', 'marker_1', 'marker_2'} <= set(static)
    moving = {t_.child_frame_id for m in tf for t_ in m.transforms}
    assert moving == set(abb_urdf.LINK_NAMES)
    matched = [m for m in tf if stamp_ns(m.transforms[0].header.stamp) in by_ns]
    assert len(matched) >= 4
    picks = [matched[i] for i in np.linspace(0, len(matched) - 1, 4).round().astype(int)]
    assert len({stamp_ns(m.transforms[0].header.stamp) for m in picks}) == 4
    for msg in picks:
        q_true = by_ns[stamp_ns(msg.transforms[0].header.stamp)] + d_q
        local = {t_.child_frame_id: (t_.header.frame_id, video._matrix(t_.transform))
                 for t_ in msg.transforms}
        poses = video.frame_poses({**static, **local})
        expected = abb_urdf.link_poses(q_true, params)
        for frame in abb_urdf.LINK_NAMES + ('flange', 'tool0'):
            np.testing.assert_allclose(poses[frame][:3, 3], expected[frame][:3, 3],
                                       atol=1e-6, err_msg=frame)
            np.testing.assert_allclose(poses[frame][:3, :3], expected[frame][:3, :3],
                                       atol=1e-6, err_msg=frame)
