"""``ibvs calibrate`` end to end: the offline simulator, a cell's recording, its files."""

from ibvs_bringup import scenario
from ibvs_common.shared_params import camera_pose_from
from ibvs_experiments import calibrate, cli
from ibvs_model import default_camera, handeye, StereoCamera
from ibvs_sim.camera_effects import calibrated_pose
from ibvs_testing.fixtures import spin_until
import numpy as np
import pytest

ERROR = ['-p', 'camera_pose_error_xyz_m:=[0.006,-0.008,0.0]',
         '-p', 'camera_pose_error_rpy_deg:=[0.6,0.0,-0.8]']


def calibrated_camera_pose(path):
    """Return the 4x4 camera pose of a result file, read as ``ibvs`` reads a parameter file."""
    return camera_pose_from(scenario.load_parameters(path, what='parameter file'))


def within(reference, pose, mm, deg):
    shift, angle = handeye.pose_difference(reference, pose)
    return np.linalg.norm(shift) * 1e3 < mm and angle < deg


def test_the_offline_simulator_recovers_a_camera_error_of_10_mm_and_1_deg(tmp_path, capsys):
    out = tmp_path / 'camera_pose.yaml'
    assert cli.main(['calibrate', '-n', '6', *ERROR, '-o', str(out)]) == 0
    printed = capsys.readouterr().out
    assert 'from 6 poses' in printed and '-p camera_pose:=[' in printed
    assert 'error against the true camera' in printed and 'residual' in printed
    true = default_camera('HD720').pose_C_O  # the simulator's camera_eye and camera_look_at
    assert within(true, calibrated_camera_pose(out), 1.0, 0.1)
    assert out.read_text().startswith(calibrate.MARKER)
    # The -p text printed is the file's value.
    text = printed.split('-p camera_pose:=')[1].split()[0]
    assert np.allclose(camera_pose_from({'camera_pose': scenario.parse_override(
        f'camera_pose:={text}')[1]}), calibrated_camera_pose(out), atol=1e-8)


def test_poses_drawn_to_a_file_are_the_ones_calibrated_from(tmp_path, capsys):
    poses = tmp_path / 'poses.yaml'
    assert cli.main(['calibrate', '-n', '4', '--seed', '3', *ERROR,
                     '--draw-poses', str(poses)]) == 0
    assert 'wrote 4 poses' in capsys.readouterr().out
    joints = calibrate.read_poses(poses)
    true = default_camera('HD720')
    nominal = StereoCamera(true.intrinsics, calibrated_pose(true.pose_C_O, (0.006, -0.008, 0.0),
                                                            (0.6, 0.0, -0.8)))
    assert np.allclose(joints, handeye.draw_poses(nominal, 4, 3), atol=1e-7)
    out = tmp_path / 'result.yaml'
    assert cli.main(['calibrate', '--poses', str(poses), *ERROR, '-o', str(out)]) == 0
    assert f'the poses file {poses}' in capsys.readouterr().out
    assert within(true.pose_C_O, calibrated_camera_pose(out), 1.0, 0.1)


def test_files_it_did_not_write_are_never_replaced(tmp_path, capsys):
    mine = tmp_path / 'mine.yaml'
    mine.write_text('camera_pose: [1, 2, 3]\n')
    assert cli.main(['calibrate', '-n', '3', '-o', str(mine)]) == 2
    err = capsys.readouterr().err
    assert err.startswith('error:') and 'did not write it' in err and '--force' in err
    assert mine.read_text() == 'camera_pose: [1, 2, 3]\n'
    link = tmp_path / 'link.yaml'
    link.symlink_to(mine)
    assert cli.main(['calibrate', '-n', '3', '-o', str(link), '--force']) == 2
    assert 'symbolic link' in capsys.readouterr().err
    assert cli.main(['calibrate', '-n', '3', '-o', str(mine), '--force']) == 0
    assert mine.read_text().startswith(calibrate.MARKER)
    assert cli.main(['calibrate', '-n', '3', '-o', str(mine)]) == 0  # its own: replaced
    poses = tmp_path / 'poses.yaml'
    poses.write_text('joints_deg: []\n')
    assert cli.main(['calibrate', '--draw-poses', str(poses)]) == 2
    assert 'did not write it' in capsys.readouterr().err


def test_bad_commands_end_with_an_error_line_and_code_2(tmp_path, capsys):
    out = str(tmp_path / 'x.yaml')
    for argv, words in (
            (['-p', 'camera_pose_eror_xyz_m:=[0.01,0,0]'],
             "did you mean 'camera_pose_error_xyz_m'"),
            (['-p', 'camera_pose_error_xyz_m:=[0.9,0,0]'], 'camera_pose_error_xyz_m'),
            (['-p', 'camera_pose:=[0,0,0,0,0,0,2]'], 'quaternion'),
            (['-n', '2'], 'at least 3'),
            (['--bag', str(tmp_path / 'nobag')], 'no bag at'),
            (['--bag', str(tmp_path), '--poses', 'p.yaml'], 'not with'),
            (['--poses', str(tmp_path / 'none.yaml')], 'cannot read the poses file')):
        assert cli.main(['calibrate', *argv, '-o', out]) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith('error:') and words in err and 'Traceback' not in err, err
    assert not (tmp_path / 'x.yaml').exists()


@pytest.fixture
def write_bag(context, executor_of):
    """Return write(path, [(topic, rclpy message)]): a bag recorded as a run's recorder does."""
    from ibvs_bringup.recorder import KNOWN_TOPICS, LATCHED_TOPICS, message_class, Recorder
    from ibvs_common import contract
    from rclpy.node import Node

    def write(path, messages):
        recorder = Recorder(path, context=context, include_per_step=True)
        talker = Node(f'talker_{path.name}', context=context)
        executor = executor_of(recorder, talker)
        topics = {t for t, _ in messages}
        pubs = {topic: talker.create_publisher(
            message_class(KNOWN_TOPICS[topic]), topic,
            contract.LATCHED if topic in LATCHED_TOPICS else contract.RELIABLE)
            for topic in topics}
        spin_until(executor, lambda: all(p.get_subscription_count() for p in pubs.values()),
                   what='discovery')
        for k, (topic, msg) in enumerate(messages):
            pubs[topic].publish(msg)
            if k % 50 == 0:  # let the recorder keep up
                executor.spin_once(timeout_sec=0.0)
        spin_until(executor, lambda: sum(recorder.counts[t] for t in topics) == len(messages),
                   what='messages')
        recorder.close()
    return write


def test_a_recording_of_the_arm_held_at_poses_gives_the_camera(tmp_path, capsys, write_bag):
    from ibvs_common import contract
    from ibvs_common.conversions import (camera_infos, feature_status_msg, features_msg,
                                         FeatureStatus, joint_state, pose_stamped)
    true = default_camera('HD720')
    nominal = calibrated_pose(true.pose_C_O, (0.006, -0.008, 0.0), (0.6, 0.0, -0.8))
    holds = handeye.draw_poses(StereoCamera(true.intrinsics, nominal), 5, seed=1)
    rng = np.random.default_rng(7)
    rate, hold_s, move_s = 100, 1.0, 0.3
    joint_t, joint_q, now = [], [], 0.0
    for i, pose in enumerate(holds):  # held, then moved to the next in a straight line
        joint_t += [now + k / rate for k in range(int(hold_s * rate))]
        joint_q += [pose] * int(hold_s * rate)
        now += hold_s
        if i + 1 < len(holds):
            steps = int(move_s * rate)
            joint_t += [now + k / rate for k in range(steps)]
            joint_q += [pose + (holds[i + 1] - pose) * (k + 1) / steps for k in range(steps)]
            now += move_s
    joint_t, joint_q = np.array(joint_t), np.array(joint_q)
    ns = [int(round(t * 1e9)) for t in joint_t]
    messages = [(contract.STEREO_POSE, pose_stamped(nominal, 0))]
    messages += list(zip((contract.LEFT_INFO, contract.RIGHT_INFO),
                         camera_infos(true.intrinsics, 0)))
    frame_ns = range(0, ns[-1], 33_333_333)
    for stamp in frame_ns:
        q = np.array([np.interp(stamp * 1e-9, joint_t, joint_q[:, i]) for i in range(6)])
        p = true.project(handeye.marker_points([q])[0]).reshape(6)
        moving = not any(np.allclose(q, h) for h in holds)
        if moving and stamp % 2:  # the detector missed it: an estimate from a wrong model
            p, mode, reason = p + 20.0, contract.FEATURE_ESTIMATED, 'marker 1 not found'
        else:
            p, mode, reason = p + rng.normal(0.0, 0.003, 6), contract.FEATURE_MEASURED, \
                contract.FEATURE_MEASURED
        messages.append((contract.FEATURES, features_msg(p, stamp)))
        messages.append((contract.FEATURE_STATUS, feature_status_msg(
            FeatureStatus(mode, mode, reason, 0.0, 'roi'), stamp)))
    # As joint_state_broadcaster publishes them: its own order, with a track's joint too.
    names = [*reversed(contract.JOINT_NAMES), 'track_joint']
    messages += [(contract.JOINT_STATES, joint_state(stamp, [*q[::-1], 0.5], names=names))
                 for stamp, q in zip(ns, joint_q)]
    bag = tmp_path / 'bag'
    write_bag(bag, messages)
    out = tmp_path / 'camera_pose.yaml'
    assert cli.main(['calibrate', '--bag', str(bag), '-o', str(out)]) == 0
    printed = capsys.readouterr().out
    assert '5 still poses' in printed and 'correction to the nominal camera: 10.0' in printed
    assert within(true.pose_C_O, calibrated_camera_pose(out), 0.1, 0.01)
    assert f'the bag {bag}' in out.read_text()
    # A recording with too few still poses says what a pose needs.
    short = tmp_path / 'short'
    write_bag(short, [m for m in messages if m[0] != contract.JOINT_STATES]
              + [(contract.JOINT_STATES, joint_state(stamp, q))
                 for stamp, q in zip(ns[:150], joint_q[:150])]
              + [(contract.JOINT_STATES, joint_state(ns[150], [np.nan] * 6))])
    assert cli.main(['calibrate', '--bag', str(short), '-o', str(out)]) == 2
    assert 'hold the arm still' in capsys.readouterr().err
