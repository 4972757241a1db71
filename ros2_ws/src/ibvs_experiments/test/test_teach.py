"""``ibvs teach``'s parts without a graph: the frames of a still tool, the record, the target."""

from types import SimpleNamespace

from ibvs_bringup import scenario
from ibvs_common import contract
from ibvs_common.shared_params import target_from_parameters
from ibvs_common.teach import FrameMean
from ibvs_experiments import cli, output_dir, teach
from ibvs_model import forward_kinematics, inverse_kinematics, paper
import numpy as np
import pytest

MS = 1_000_000
Q = inverse_kinematics(paper.target_pose())


def pair(rng, shape=(6, 8, 3)):
    return tuple(rng.integers(0, 256, shape, dtype=np.uint8) for _ in range(2))


def feed(collector, rng, stamps, q=Q):
    """Give ``collector`` a pair at each stamp (ms) and joint states every 4 ms around them."""
    pairs = []
    for t in stamps:
        left, right = pair(rng)
        collector.joints((t - 2) * MS, q)
        collector.image('left', t * MS, left)
        collector.image('right', t * MS, right)
        pairs.append((left, right))
    return pairs


def test_the_pair_is_the_mean_of_consecutive_still_frames_with_their_joints():
    rng = np.random.default_rng(0)
    collector = teach.Collector(frames=3)
    pairs = feed(collector, rng, (33, 67, 100))
    assert collector.result() is None, 'no joint state at or after the last frame yet'
    collector.joints(102 * MS, Q)
    taught = collector.result()
    expected = FrameMean()
    for p in pairs:
        expected.add(p)
    assert np.array_equal(taught.left, expected.mean()[0])
    assert np.array_equal(taught.right, expected.mean()[1])
    assert taught.stamps == (33 * MS, 67 * MS, 100 * MS)
    np.testing.assert_allclose(taught.joints, Q, atol=1e-15)
    assert taught.joint_states == 4 and taught.spread.max() == 0.0


def test_a_lone_image_an_older_pair_and_a_moving_arm_are_not_taught():
    rng = np.random.default_rng(1)
    collector = teach.Collector(frames=2)
    collector.image('left', 10 * MS, pair(rng)[0])  # its right image never comes
    feed(collector, rng, (33,))
    collector.image('left', 20 * MS, pair(rng)[0])  # older than the pair taken
    collector.image('right', 20 * MS, pair(rng)[1])
    assert collector.stamps == [33 * MS]
    moved = Q + np.radians([0.0, 0.01, 0.0, 0.0, 0.0, 0.0])
    feed(collector, rng, (67,), moved)
    collector.joints(70 * MS, moved)
    assert collector.result() is None and collector.restarts == 1
    assert 'joint_2 moved 0.0100 deg' in collector.last_motion
    feed(collector, rng, (100, 133), moved)
    collector.joints(135 * MS, moved)
    taught = collector.result()
    assert taught is not None and taught.stamps == (100 * MS, 133 * MS)


def test_the_record_and_its_target_agree_with_the_joints_taught(tmp_path):
    rng = np.random.default_rng(2)
    collector = teach.Collector(frames=2)
    feed(collector, rng, (33, 67))
    collector.tool(forward_kinematics(Q))
    collector.joints(70 * MS, Q)
    taught = collector.result()
    info = {'frame_id': 'zed_left_camera_frame_optical', 'width': 8, 'height': 6}
    record = teach.record_of(taught, {'left': info, 'right': dict(info)},
                             {'left': contract.ZED_LEFT_IMAGE}, 'bgra8')
    claim = output_dir.claim(tmp_path / 'teach')
    try:
        teach.write(claim, taught, record)
    finally:
        claim.release()
    got = teach.load(tmp_path / 'teach')
    assert np.array_equal(got.left, taught.left) and np.array_equal(got.right, taught.right)
    assert got.record['joints'] == dict(zip(contract.JOINT_NAMES, Q.tolist()))
    # The target file is a parameter file whose target is the kinematics of those joints.
    params = scenario.load_parameters(tmp_path / 'teach' / teach.TARGET_FILE)
    target = target_from_parameters(params)
    np.testing.assert_allclose(target, forward_kinematics(Q), atol=1e-10)
    assert teach.target_overrides(got.record) == {k: params[k] for k in (
        'target_position', 'target_rotation')}
    np.testing.assert_allclose(got.record['true_tool_pose'], forward_kinematics(Q))
    # Another teach into the folder replaces its files; a folder of other files is refused.
    (tmp_path / 'mine').mkdir()
    (tmp_path / 'mine' / 'notes.txt').write_text('mine')
    with pytest.raises(output_dir.OutputRefused, match='notes.txt'):
        output_dir.claim(tmp_path / 'mine')


def test_a_folder_that_is_no_teach_record_is_refused_in_words(tmp_path, capsys):
    (tmp_path / 'empty').mkdir()
    with pytest.raises(teach.TeachError, match='no teach folder'):
        teach.load(tmp_path / 'empty')
    args = SimpleNamespace(publish=str(tmp_path / 'empty'))
    assert teach.main(args) == 2
    assert 'record one with ibvs teach' in capsys.readouterr().err


def test_teach_frames_out_of_range_is_refused_naming_the_parameter(tmp_path, capsys):
    assert cli.main(['teach', '-o', str(tmp_path / 't'), '--teach-frames', '0']) == 2
    assert "parameter 'teach_frames'" in capsys.readouterr().err
    assert not (tmp_path / 't').exists()


def test_nothing_on_the_domain_names_the_silent_topics_and_leaves_no_folder(tmp_path, capsys):
    assert cli.main(['teach', '-o', str(tmp_path / 't'), '--timeout', '2']) == \
        teach.EXIT_NO_FRAMES
    err = capsys.readouterr().err
    assert f'error: no {contract.ZED_LEFT_IMAGE}' in err and 'error: no /joint_states' in err
    assert not (tmp_path / 't').exists()
