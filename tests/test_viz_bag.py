"""
A recorded run holds what a viewer needs, and what it holds is right.

/tf against the true flange pose, the overlays against /ibvs/features, and ``ibvs video``
makes a film of the whole run that a browser plays, with the camera's images recorded or
rendered again from the joint states, the same to the bit. One short run of scenario 1 through the
installed graph (``ibvs run --overlays --images``) is shared by the checks below.
"""

from pathlib import Path
import re
import shutil
import subprocess

from ibvs_analysis import video
from ibvs_common import contract
from ibvs_common.conversions import pose_matrix, stamp_ns
from ibvs_experiments import cli, runner
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
                        record_images=True, progress=lambda *_: None)
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
    drawn = set()
    for topic, side in ((contract.DEBUG_LEFT_IMAGE, 'left'),
                        (contract.DEBUG_RIGHT_IMAGE, 'right')):
        for msg in msgs[topic]:
            p = features[stamp_ns(msg.header.stamp)]
            image = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.width, 3)
            found = overlay.find_drawn_features(image, side, p)
            np.testing.assert_allclose(found, overlay.side_points(p, side), atol=1.0)
            drawn.add((side, stamp_ns(msg.header.stamp)))
    # every frame's features drawn on both sides, but for the last frame's overlays, which
    # the recorder may miss as the run stops (as the camera images, below)
    expected = {(side, t) for t in features for side in ('left', 'right')}
    last = max(features)
    assert expected - drawn <= {('left', last), ('right', last)}
    assert len(drawn) >= 6


def test_camera_images_rendered_again_from_the_joint_states_are_the_recorded_ones(run_dir):
    # What a film shows of a run recorded without its images (make demo, ibvs run --video).
    bag = run_dir / 'bag'
    recorded = {t: (left, right)
                for t, left, right in video._recorded_pairs(bag, video.RAW_TOPICS[0])}
    compared = 0
    for t_ns, left, right in video.replayed_images(bag):
        if t_ns in recorded:  # the bag may lack the last frame, recorded as the run stopped
            assert np.array_equal(left, recorded[t_ns][0]), f'left image at {t_ns} ns'
            assert np.array_equal(right, recorded[t_ns][1]), f'right image at {t_ns} ns'
            compared += 1
    assert compared == len(recorded) >= 3


@pytest.fixture(scope='module')
def film(run_dir):
    """Return the film of the run, written by ``ibvs video`` with the default time map."""
    assert cli.main(['video', str(run_dir)]) == 0
    return run_dir / 'video.mp4'


def test_film_is_h264_and_lasts_the_whole_run(run_dir, film):
    import av
    with av.open(str(film)) as container:
        stream = container.streams.video[0]
        assert stream.codec_context.name == 'h264'
        assert stream.codec_context.pix_fmt == 'yuv420p'
        frames = [f.to_ndarray(format='rgb24') for f in container.decode(stream)]
        duration_s = float(container.duration) / av.time_base
    # 0.11 s of sim time at a quarter of real time: 0.44 s of film, 13 frames at 30 / s
    expected = video.DEFAULT_TIME_MAP.film_s(DURATION_S)
    assert len(frames) == round(expected * video.FPS) == 13
    assert duration_s == pytest.approx(expected, abs=1.5 / video.FPS)
    assert video.count_frames(run_dir / 'bag') >= 3
    height, width = frames[0].shape[:2]
    assert height == 2 * video.PANEL_HEIGHT + video.BAND_HEIGHT
    # the 3D view (white background of matplotlib) takes at least a third of the width
    view = frames[0][:2 * video.PANEL_HEIGHT, width // 2:]
    assert view.mean() > 200 and width // 2 >= width / 3
    # the images change while the arm moves: the film is not a still
    assert np.abs(frames[-1].astype(int) - frames[0].astype(int)).mean() > 1.0


PLAYER = """<!doctype html><html><body>
<video id="v" src="video.mp4" muted autoplay playsinline></video><pre id="out">pending</pre>
<script>
const v = document.getElementById('v'), out = document.getElementById('out');
v.addEventListener('error', () => { out.textContent = 'error ' + (v.error && v.error.code); });
v.play().catch(e => { out.textContent = 'play failed ' + e; });
setTimeout(() => { out.textContent = 'readyState=' + v.readyState + ' currentTime='
  + v.currentTime + ' duration=' + v.duration; }, 300);
</script></body></html>
"""


def test_film_plays_in_headless_chromium(film):
    browser = shutil.which('chromium') or shutil.which('chromium-browser')
    if browser is None:
        pytest.skip('no chromium (Debian: apt-get install chromium)')
    page = film.parent / 'play.html'
    page.write_text(PLAYER)
    done = subprocess.run(
        [browser, '--headless', '--no-sandbox', '--disable-gpu',
         '--autoplay-policy=no-user-gesture-required', '--allow-file-access-from-files',
         '--virtual-time-budget=2000', '--dump-dom', page.as_uri()],
        capture_output=True, text=True, timeout=120)
    found = re.search(r'readyState=(\d) currentTime=([\d.e-]+) duration=([\d.e-]+)',
                      done.stdout)
    assert found, done.stdout[-2000:] + done.stderr[-2000:]
    ready, current, duration = int(found[1]), float(found[2]), float(found[3])
    assert ready >= 2, 'the browser decoded no frame'
    assert current > 0.0, 'the film did not play'
    assert duration == pytest.approx(video.DEFAULT_TIME_MAP.film_s(DURATION_S), abs=0.05)
