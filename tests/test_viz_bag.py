"""
A recorded run holds what a viewer needs, and what it holds is right.

/tf against the true flange pose, the overlays against /ibvs/features, and ``ibvs video``
makes a film of every frame. One short run of scenario 1 through the installed graph
(``ibvs run --overlays``) is shared by the checks below.
"""

from pathlib import Path

import cv2
from ibvs_common import contract
from ibvs_common.conversions import pose_matrix, stamp_ns
from ibvs_experiments import cli, runner, video
from ibvs_vision import overlay
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores

#: Sim time of the run: four camera frames (0, 34, 67, 100 ms) and the first /clock batches.
DURATION_S = 0.11


@pytest.fixture(scope='module')
def run_dir(installed_workspace, tmp_path_factory):
    out = tmp_path_factory.mktemp('viz_run')
    runner.run_scenario('scenario1', out, duration_s=DURATION_S, record_overlays=True,
                        progress=lambda *_: None)
    return out


def read(bag, topics):
    """Return {topic: [message, ...]} of ``topics`` in the bag, in recording order."""
    out = {t: [] for t in topics}
    with AnyReader([Path(bag)], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic in topics]
        for conn, _, raw in reader.messages(connections=conns):
            out[conn.topic].append(reader.deserialize(raw, conn.msgtype))
    return out


def test_bag_holds_the_viewer_topics_with_jazzy_types(run_dir):
    with AnyReader([run_dir / 'bag']) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
    for topic, kind in ((contract.ROBOT_DESCRIPTION, 'std_msgs/msg/String'),
                        (contract.TF, 'tf2_msgs/msg/TFMessage'),
                        (contract.TF_STATIC, 'tf2_msgs/msg/TFMessage'),
                        (contract.MARKERS, 'visualization_msgs/msg/MarkerArray'),
                        (contract.DEBUG_LEFT_IMAGE, 'sensor_msgs/msg/Image'),
                        (contract.DEBUG_RIGHT_IMAGE, 'sensor_msgs/msg/Image')):
        assert types.get(topic) == kind, topic


def test_tool_frame_is_the_true_flange_pose(run_dir):
    msgs = read(run_dir / 'bag', {contract.TF, contract.TF_STATIC, contract.TOOL_PATH})
    truth = {stamp_ns(p.header.stamp): pose_matrix(p.pose)
             for path in msgs[contract.TOOL_PATH] for p in path.poses}
    static = {t.child_frame_id: (t.header.frame_id, video._matrix(t.transform))
              for m in msgs[contract.TF_STATIC] for t in m.transforms}
    checked = 0
    for msg in msgs[contract.TF]:
        t_ns = stamp_ns(msg.transforms[0].header.stamp)
        if t_ns not in truth:
            continue
        local = {t.child_frame_id: (t.header.frame_id, video._matrix(t.transform))
                 for t in msg.transforms}
        tool = video.frame_poses({**static, **local})['tool0']
        np.testing.assert_allclose(tool[:3, 3], truth[t_ns][:3, 3], atol=1e-6)
        np.testing.assert_allclose(tool[:3, :3], truth[t_ns][:3, :3], atol=1e-6)
        checked += 1
    assert checked >= 3


def test_overlays_draw_the_published_features(run_dir):
    msgs = read(run_dir / 'bag', {contract.FEATURES, contract.DEBUG_LEFT_IMAGE,
                                  contract.DEBUG_RIGHT_IMAGE})
    features = {stamp_ns(m.header.stamp): np.array([[p.x, p.y, p.z]
                                                    for p in m.polygon.points]).ravel()
                for m in msgs[contract.FEATURES]}
    checked = 0
    for topic, side in ((contract.DEBUG_LEFT_IMAGE, 'left'),
                        (contract.DEBUG_RIGHT_IMAGE, 'right')):
        for msg in msgs[topic]:
            p = features[stamp_ns(msg.header.stamp)]
            image = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.width, 3)
            found = overlay.find_drawn_features(image, side, p)
            np.testing.assert_allclose(found, overlay.side_points(p, side), atol=1.0)
            checked += 1
    assert checked == 2 * len(features) >= 6


def test_video_has_one_frame_per_camera_frame(run_dir):
    assert cli.main(['video', str(run_dir)]) == 0
    frames = video.count_frames(run_dir / 'bag')
    capture = cv2.VideoCapture(str(run_dir / 'video.mp4'))
    try:
        assert capture.isOpened()
        assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == frames >= 3
        ok, first = capture.read()
        assert ok and first.shape[0] == video.PANEL_HEIGHT
    finally:
        capture.release()
