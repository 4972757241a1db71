"""
``ibvs video RUN_DIR``: a film of a whole recorded run, H.264 in an MP4 a browser plays.

Each film frame shows, above a status band:

- on the left, the left and the right camera image, one above the other, each with the
  published features p_I (green +, light for marker 1, dark for marker 2) and the target
  features p_bar (red + in a circle, white-edged) drawn at the panel's own scale (so they
  stay legible), and a magnifier (lower right) of the markers' region: the camera's pixels
  around them enlarged, the crosses drawn after the enlargement (the magnifier never
  magnifies the drawing);
- on the right, half the width, a 3D view of the cell drawn from the bag's /tf and
  /tf_static at the frame's stamp (links, tool, markers, camera, the target's tool axis and
  the tool's path so far, from the run's 1 ms tool poses), as RViz would show it;
- the status band: sim time, the film's speed, the position and tool-axis errors against the
  success criterion (:data:`.convergence.SUCCESS`), the feature mode, and a legend.

The images are the camera's own: recorded (/stereo/*/image_raw or the ZED topics: ``ibvs run
--images``), else rendered again from the run's joint states (``/ibvs/joint_path``) by the
run's own simulator (:func:`ibvs_sim.replay.replayed_frames`: the same renderer, camera
effects and random draws; the same images to the bit, which tests/test_video.py checks
against recorded ones), so that a run that makes its film (``make demo``, ``ibvs run
--video``) need not carry 160 MB of images a simulated second through DDS into its bag
while it runs. A run recorded with ``--overlays`` and no camera images has the feature
node's overlay images: the film then shows those (their drawing included, in the
magnifier too).

Time: the film shows the whole run, sim time mapped to film time by a :class:`TimeMap`
(default :data:`DEFAULT_TIME_MAP`: a quarter of real time for the first second, where the
arm moves, then real time); each camera frame stays on screen until the next one's time.
Encoded with PyAV (FFmpeg's libx264, yuv420p, ``+faststart``) at :data:`FPS` frames per
second: H.264 in MP4 is what browsers and GitHub's preview play.
"""

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
import math
from pathlib import Path
import time

import cv2
from ibvs_common import contract
from ibvs_common.conversions import stamp_ns
from ibvs_viz import scene
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
import numpy as np
from numpy.typing import NDArray
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores
from scipy.spatial.transform import Rotation

from .convergence import SUCCESS

#: Height (px) of each camera panel; the two panels stack to the 3D view's height.
PANEL_HEIGHT = 360
#: Height (px) of the status band under the panels.
BAND_HEIGHT = 72
#: The film's frame rate (frames per film second).
FPS = 30
#: The magnifier: this many image pixels (at 1280 px width) each side of the markers' mean,
#: drawn INSET_PX wide in the panel's lower right corner.
ZOOM_HALF_PX = 45
INSET_PX = 150
#: H.264 encoder and its options: constant quality; yuv420p, the format browsers decode.
CODEC = 'libx264'
CODEC_OPTIONS = {'crf': '23', 'preset': 'medium'}
PIXEL_FORMAT = 'yuv420p'
#: The chain drawn as the arm, from the base to the flange.
ARM_FRAMES = (contract.BASE_FRAME,) + tuple(f'link_{i}' for i in range(1, 7)) + ('tool0',)
#: The camera image topics a film can show, in order of preference, by side.
RAW_TOPICS = ({contract.LEFT_IMAGE: 0, contract.RIGHT_IMAGE: 1},
              {contract.ZED_LEFT_IMAGE: 0, contract.ZED_RIGHT_IMAGE: 1})
OVERLAY_TOPICS = {contract.DEBUG_LEFT_IMAGE: 0, contract.DEBUG_RIGHT_IMAGE: 1}
#: Colours (RGB) of the drawing: as :mod:`ibvs_vision.overlay` draws them.
FEATURE_RGB = ((0, 255, 0), (0, 170, 0))
TARGET_RGB = (255, 0, 0)
TEXT_RGB = (255, 255, 255)


class NoImages(ValueError):
    """The bag has no camera or overlay images: record the run with --images (or --video)."""


#: The old name of :class:`NoImages` (``ibvs video`` of a run without images).
NoOverlays = NoImages


@dataclass(frozen=True)
class TimeMap:
    """
    Sim time to film time: ``segments`` of (until sim s, speed), speed 1 = real time.

    Each segment runs from the previous one's end (0 for the first) to ``until``; the last
    segment's ``until`` is inf. Speed 0.25 shows a sim second in four film seconds.
    """

    segments: tuple[tuple[float, float], ...] = ((1.0, 0.25), (math.inf, 1.0))

    def __post_init__(self) -> None:
        """Check the segments: positive finite speeds, increasing ends, the last open."""
        ends = [float(u) for u, _ in self.segments]
        speeds = [float(s) for _, s in self.segments]
        if not self.segments or not math.isinf(ends[-1]):
            raise ValueError('a time map needs segments ending with an open one (until inf)')
        if any(not (math.isfinite(s) and s > 0.0) for s in speeds):
            raise ValueError(f'time map speeds must be finite and > 0, got {speeds}')
        if any(not b > a for a, b in zip([0.0] + ends, ends)):
            raise ValueError(f'time map segment ends must increase from 0, got {ends}')

    @classmethod
    def parse(cls, text: str) -> 'TimeMap':
        """
        Return the map of ``'SPEED@UNTIL_S,...,SPEED'``: '0.25@1,1' = 0.25x to 1 s, then 1x.

        Raises ValueError, with what is wrong, for malformed text.
        """
        segments = []
        parts = [p.strip() for p in text.split(',')]
        for i, part in enumerate(parts):
            speed, _, until = part.partition('@')
            try:
                segment = (float(until) if until else math.inf, float(speed))
            except ValueError:
                raise ValueError(f'time map {text!r}: {part!r} is not SPEED or SPEED@UNTIL_S')
            if (i < len(parts) - 1) != bool(until):
                raise ValueError(f'time map {text!r}: every segment but the last needs '
                                 '@UNTIL_S, the last none')
            segments.append(segment)
        return cls(tuple(segments))

    def film_s(self, sim_s: float) -> float:
        """Return the film time (s) at which sim time ``sim_s`` is shown."""
        out, start = 0.0, 0.0
        for until, speed in self.segments:
            if sim_s <= until:
                return out + (sim_s - start) / speed
            out += (until - start) / speed
            start = until
        return out

    def speed_at(self, sim_s: float) -> float:
        """Return the speed (film time per sim time, inverted) at sim time ``sim_s``."""
        return next(speed for until, speed in self.segments if sim_s < until)

    def describe(self) -> str:
        """Return the map in words: '0.25x real time to 1 s, then 1x'."""
        words = [f'{s:g}x real time to {u:g} s' if math.isfinite(u) else f'{s:g}x'
                 for u, s in self.segments]
        return ', then '.join(words)


DEFAULT_TIME_MAP = TimeMap()


@dataclass
class Frame:
    """One camera frame of the bag: its stamp, images, poses, features and status."""

    t_ns: int
    left: NDArray[np.uint8]
    right: NDArray[np.uint8]
    poses: dict
    features: NDArray[np.float64] | None
    mode: str
    #: Whether the images are the camera's own (False: the feature node's overlays).
    raw: bool


def _matrix(transform):
    t, r = transform.translation, transform.rotation
    tf = np.eye(4)
    tf[:3, :3] = Rotation.from_quat([r.x, r.y, r.z, r.w]).as_matrix()
    tf[:3, 3] = (t.x, t.y, t.z)
    return tf


def frame_poses(local: Mapping[str, tuple[str, NDArray[np.float64]]]
                ) -> dict[str, NDArray[np.float64]]:
    """Return {frame: T_frame^base_link} from {child: (parent, T_child^parent)}."""
    out = {contract.BASE_FRAME: np.eye(4)}

    def pose(frame):
        if frame not in out:
            parent, tf = local[frame]
            out[frame] = pose(parent) @ tf
        return out[frame]
    for frame in local:
        pose(frame)
    return out


def image_rgb(msg) -> NDArray[np.uint8]:
    """Return a sensor_msgs/Image (rgb8, bgr8, rgba8, bgra8, mono8) as (H, W, 3) RGB."""
    channels = {'rgb8': 3, 'bgr8': 3, 'rgba8': 4, 'bgra8': 4, 'mono8': 1}.get(msg.encoding)
    if channels is None:
        raise ValueError(f'image encoding {msg.encoding!r} is not one a film shows')
    array = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.step)
    array = array[:, :channels * msg.width].reshape(msg.height, msg.width, channels)
    if msg.encoding == 'mono8':
        return np.repeat(array, 3, axis=2)
    if msg.encoding.startswith('bgr'):
        return np.ascontiguousarray(array[:, :, 2::-1])
    return np.ascontiguousarray(array[:, :, :3])


def image_topics(bag_path: str | Path) -> tuple[dict[str, int], bool]:
    """
    Return ({image topic: side}, raw) of the images a film of the bag shows.

    The camera's own images where the bag has both sides (``raw`` True), else the feature
    node's overlays, else ({}, True): the camera's images rendered again from the run's
    joint states (:func:`replayed_images`). Raises :class:`NoImages` when the bag has
    none of these.
    """
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([Path(bag_path)], default_typestore=typestore) as reader:
        have = {c.topic for c in reader.connections if c.msgcount}
    for topics in RAW_TOPICS:
        if set(topics) <= have:
            return topics, True
    if set(OVERLAY_TOPICS) <= have:
        return OVERLAY_TOPICS, False
    if contract.JOINT_PATH in have:
        return {}, True
    raise NoImages(f'{bag_path}: no camera images ({contract.LEFT_IMAGE}), no overlays '
                   f'({contract.DEBUG_LEFT_IMAGE}) and no joint states to render them from '
                   f'({contract.JOINT_PATH}); record the run with `ibvs run --images`')


def replayed_images(bag_path: str | Path) -> Iterator[tuple[int, NDArray[np.uint8],
                                                            NDArray[np.uint8]]]:
    """
    Yield (stamp ns, left RGB, right RGB) of each frame of the run, rendered again.

    From the run's parameters and its joint states on ``/ibvs/joint_path``
    (:func:`ibvs_sim.replay.replayed_frames`); frames the camera lost are left out, as
    the run published none.
    """
    from ibvs_common.conversions import read_joint_path
    from ibvs_sim.replay import replayed_frames
    from .analysis import load_run
    params = load_run(Path(bag_path)).params
    stamps, encoders = [], []
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([Path(bag_path)], default_typestore=typestore) as reader:
        conns = [c for c in reader.connections if c.topic == contract.JOINT_PATH]
        for conn, _, raw_msg in reader.messages(connections=conns):
            t, q, _, _ = read_joint_path(reader.deserialize(raw_msg, conn.msgtype))
            stamps.append(t)
            encoders.append(q)
    stamps, encoders = np.concatenate(stamps), np.concatenate(encoders)
    order = np.argsort(stamps, kind='stable')
    for t_ns, images, lost in replayed_frames(params, stamps[order], encoders[order]):
        if not lost:
            yield t_ns, images[0], images[1]


def read_frames(bag_path: str | Path) -> Iterator[Frame]:
    """
    Yield each stereo frame of the bag that has both images and a /tf message, in order.

    The poses compose /tf_static with the /tf message of the frame's stamp (the viz node
    publishes one per frame joint state, stamped as the frame). Two passes over the bag:
    the transforms, features and statuses first, then the images one pair at a time (a
    run's images do not fit in memory at HD720).
    """
    sides, raw = image_topics(bag_path)
    typestore = get_typestore(Stores.ROS2_JAZZY)
    static, dynamic, features, modes = {}, {}, {}, {}
    with AnyReader([Path(bag_path)], default_typestore=typestore) as reader:
        conns = [c for c in reader.connections if c.topic in (
            contract.TF, contract.TF_STATIC, contract.FEATURES, contract.FEATURE_STATUS)]
        for conn, _, raw_msg in reader.messages(connections=conns):
            msg = reader.deserialize(raw_msg, conn.msgtype)
            if conn.topic == contract.FEATURES:
                features[stamp_ns(msg.header.stamp)] = np.array(
                    [[p.x, p.y, p.z] for p in msg.polygon.points]).ravel()
            elif conn.topic == contract.FEATURE_STATUS:
                values = {kv.key: kv.value for s in msg.status for kv in s.values}
                modes[stamp_ns(msg.header.stamp)] = values.get('mode', 'unknown')
            else:
                local = {t.child_frame_id: (t.header.frame_id, _matrix(t.transform))
                         for t in msg.transforms}
                if conn.topic == contract.TF_STATIC:
                    static.update(local)
                elif msg.transforms:
                    # Two publishers stamp /tf alike (robot_state_node: the links;
                    # viz_node: the tool frames on tool0): a stamp's frames are both's,
                    # in whichever order the bag holds them.
                    dynamic.setdefault(stamp_ns(msg.transforms[0].header.stamp),
                                       {}).update(local)
    pairs = _recorded_pairs(bag_path, sides) if sides else replayed_images(bag_path)
    for t_ns, left, right in pairs:
        if t_ns not in dynamic:
            continue
        found = features.get(t_ns)
        yield Frame(t_ns, left, right, frame_poses({**static, **dynamic[t_ns]}),
                    found if found is not None and found.size == 6 else None,
                    modes.get(t_ns, 'unknown'), raw)


def _recorded_pairs(bag_path, sides):
    """Yield (stamp ns, left, right) of the bag's image pairs on ``sides``' topics."""
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([Path(bag_path)], default_typestore=typestore) as reader:
        conns = [c for c in reader.connections if c.topic in sides]
        pending = {}
        for conn, _, raw_msg in reader.messages(connections=conns):
            msg = reader.deserialize(raw_msg, conn.msgtype)
            t_ns = stamp_ns(msg.header.stamp)
            pair = pending.setdefault(t_ns, [None, None])
            pair[sides[conn.topic]] = image_rgb(msg)
            if pair[0] is not None and pair[1] is not None:
                del pending[t_ns]
                yield t_ns, pair[0], pair[1]


def count_frames(bag_path: str | Path) -> int:
    """Return how many frames the film of the bag can show (at most: for its progress)."""
    sides, _ = image_topics(bag_path)
    left = next((topic for topic, side in sides.items() if side == 0), contract.TF)
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([Path(bag_path)], default_typestore=typestore) as reader:
        return sum(c.msgcount for c in reader.connections if c.topic == left)


class ArmView:
    """A matplotlib 3D view of the cell, redrawn for each frame into an RGB array."""

    def __init__(self, height_px: int = 2 * PANEL_HEIGHT, width_px: int | None = None) -> None:
        """Make the figure (``width_px`` defaults to 8/9 of the height: half the film)."""
        width_px = width_px or int(round(height_px * 16 / 18))
        self.figure = Figure(figsize=(width_px / 100.0, height_px / 100.0), dpi=100)
        self.canvas = FigureCanvasAgg(self.figure)
        self.axes = self.figure.add_subplot(projection='3d')
        self.figure.subplots_adjust(left=0.0, right=1.0, bottom=0.02, top=0.95)
        self.path = []

    def draw(self, t_s: float, poses: Mapping[str, NDArray[np.float64]],
             path: NDArray[np.float64] | None = None) -> NDArray[np.uint8]:
        """
        Return the view (H, W, 3) uint8 of the frame poses ``poses`` at time ``t_s``.

        ``path``: the tool's positions (N, 3) so far (the run's 1 ms steps); without it, the
        tool frames of the views drawn so far (one per camera frame).
        """
        ax = self.axes
        ax.cla()
        arm = np.array([poses[f][:3, 3] for f in ARM_FRAMES if f in poses])
        ax.plot(*arm.T, '-o', color='0.35', lw=6, ms=5, label='arm (joints)')
        tool = poses.get('tool0')
        if tool is not None:
            self.path.append(tool[:3, 3])
        path = np.array(self.path) if path is None else path
        if len(path):
            ax.plot(*np.asarray(path).T, color='goldenrod', lw=2, label='tool path')
        for k, colour in ((1, 'red'), (2, 'blue')):
            if f'marker_{k}' in poses:
                ax.scatter(*poses[f'marker_{k}'][:3, 3], color=colour, s=30,
                           label=f'marker {k}')
        if scene.TARGET_FRAME in poses:
            target = poses[scene.TARGET_FRAME]
            ax.quiver(*(target[:3, 3] - 0.4 * target[:3, 2]), *(0.4 * target[:3, 2]),
                      color='green', lw=2, label='target tool axis')
        if contract.CAMERA_FRAME in poses:
            cam = poses[contract.CAMERA_FRAME]
            ax.scatter(*cam[:3, 3], color='black', marker='s', s=40, label='camera')
            ax.plot(*np.array([cam[:3, 3], cam[:3, 3] + 0.5 * cam[:3, 2]]).T, color='black',
                    lw=1.5)
        ax.set_xlim(-1.0, 2.5)
        ax.set_ylim(-1.75, 1.75)
        ax.set_zlim(-0.5, 2.5)
        ax.set_box_aspect((3.5, 3.5, 3.0))
        ax.view_init(elev=22, azim=-60)
        ax.set_xlabel('x [m]')
        ax.set_ylabel('y [m]')
        ax.set_zlabel('z [m]')
        ax.legend(loc='upper left', fontsize=10, framealpha=0.8)
        ax.set_title(f'cell, base frame: sim t = {t_s:.3f} s', fontsize=12)
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[:, :, :3].copy()


def _plus(image, u, v, arm, colour, thickness=1):
    u, v = int(round(u)), int(round(v))
    cv2.line(image, (u - arm, v), (u + arm, v), colour, thickness)
    cv2.line(image, (u, v - arm), (u, v + arm), colour, thickness)


def _annotate(image, points, targets, scale, offset=(0.0, 0.0), arm=8):
    """
    Draw the features (+) and targets (+ in a circle) onto ``image`` in place.

    ``points``, ``targets``: (2, 2) image coordinates (u, v) of the markers or None;
    drawn at ``(p - offset) * scale``.
    """
    if targets is not None:
        for u, v in (np.asarray(targets) - offset) * scale:
            if np.isfinite(u) and np.isfinite(v):
                # a white halo first: the red target stays visible on the red marker
                for colour, width in ((TEXT_RGB, 3), (TARGET_RGB, 1)):
                    _plus(image, u, v, arm, colour, width)
                    cv2.circle(image, (int(round(u)), int(round(v))), int(1.4 * arm), colour,
                               width)
    if points is not None:
        for k, (u, v) in enumerate((np.asarray(points) - offset) * scale):
            if np.isfinite(u) and np.isfinite(v):
                _plus(image, u, v, arm, FEATURE_RGB[k], 2 if k == 0 else 1)


def _side_points(values, side):
    if values is None:
        return None
    return np.asarray(values, dtype=float).reshape(2, 3)[:, [side, 2]]


def camera_panel(image: NDArray[np.uint8], side: int, features: NDArray[np.float64] | None,
                 target: NDArray[np.float64] | None, raw: bool,
                 height: int = PANEL_HEIGHT) -> NDArray[np.uint8]:
    """
    Return one camera image as a film panel ``height`` px high, annotated and magnified.

    The image is scaled first and the crosses drawn at the panel's scale (``raw``; an
    overlay image has its own drawing). The magnifier takes the image's own pixels around
    the markers (``ZOOM_HALF_PX`` each side at 1280 px width), enlarges them to
    ``INSET_PX`` and then draws the crosses on the enlargement at their enlarged place.
    """
    full_h, full_w = image.shape[:2]
    scale = height / full_h
    panel = cv2.resize(image, (int(round(full_w * scale)), height),
                       interpolation=cv2.INTER_AREA)
    points, targets = _side_points(features, side), _side_points(target, side)
    if raw:
        _annotate(panel, points, targets, scale)
    centre = points if points is not None else targets
    if centre is not None and np.all(np.isfinite(centre)):
        half = int(ZOOM_HALF_PX * max(1.0, full_w / 1280.0))
        u, v = centre.mean(axis=0)
        u0 = int(np.clip(round(u) - half, 0, full_w - 2 * half))
        v0 = int(np.clip(round(v) - half, 0, full_h - 2 * half))
        zoom = INSET_PX / (2 * half)
        inset = cv2.resize(image[v0:v0 + 2 * half, u0:u0 + 2 * half], (INSET_PX, INSET_PX),
                           interpolation=cv2.INTER_NEAREST)
        if raw:
            _annotate(inset, points, targets, zoom, offset=(u0 - 0.5 + 0.5 / zoom,
                                                            v0 - 0.5 + 0.5 / zoom), arm=10)
        top, left = panel.shape[0] - INSET_PX - 6, panel.shape[1] - INSET_PX - 6
        panel[top:top + INSET_PX, left:left + INSET_PX] = inset
        cv2.rectangle(panel, (left - 1, top - 1), (left + INSET_PX, top + INSET_PX),
                      TEXT_RGB, 1)
        cv2.rectangle(panel, (int(u0 * scale), int(v0 * scale)),
                      (int((u0 + 2 * half) * scale), int((v0 + 2 * half) * scale)), TEXT_RGB, 1)
        _text(panel, f'x{zoom * full_h / height:.1f}', (left + 4, top + 16), 0.45)
    _text(panel, ('left' if side == 0 else 'right') + ' camera', (6, 18), 0.55)
    return panel


def _text(image, text, origin, size, colour=TEXT_RGB, thickness=1):
    """Put ``text`` at ``origin`` on a dark box (legible on any background)."""
    (w, h), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, size, thickness)
    x, y = origin
    cv2.rectangle(image, (x - 3, y - h - 3), (x + w + 3, y + base + 1), (0, 0, 0), -1)
    cv2.putText(image, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, size, colour, thickness,
                cv2.LINE_AA)


def _fitted(text, width, size, thickness=1):
    """Return the font size <= ``size`` at which ``text`` fits ``width`` px."""
    w = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, size, thickness)[0][0]
    return size if w <= width else size * width / w


def status_band(width: int, status: str, legend: Sequence[tuple[str, tuple]],
                height: int = BAND_HEIGHT) -> NDArray[np.uint8]:
    """Return the band (height, width, 3): the status line, then the legend, both fitted."""
    band = np.full((height, width, 3), 30, np.uint8)
    margin = 10
    size = _fitted(status, width - 2 * margin, 0.7, 2)
    cv2.putText(band, status, (margin, 28), cv2.FONT_HERSHEY_SIMPLEX, size, TEXT_RGB, 2,
                cv2.LINE_AA)
    words = '   '.join(text for text, _ in legend)
    size = _fitted(words, width - 2 * margin - 30 * len(legend), 0.6)
    x = margin
    for text, colour in legend:
        _plus(band, x + 8, 54, 8, colour, 2)
        x += 24
        cv2.putText(band, text, (x, 60), cv2.FONT_HERSHEY_SIMPLEX, size, TEXT_RGB, 1,
                    cv2.LINE_AA)
        x += cv2.getTextSize(text + '   ', cv2.FONT_HERSHEY_SIMPLEX, size, 1)[0][0]
    return band


#: The legend of the status band: (words, colour) of each drawn symbol.
LEGEND = (('marker 1 feature p_I', FEATURE_RGB[0]), ('marker 2 feature p_I', FEATURE_RGB[1]),
          ('target features p_bar', TARGET_RGB),
          ('box: magnified region', TEXT_RGB))


class Film:
    """What the film needs beyond the frames: the run's errors, targets and time map."""

    def __init__(self, run_dir: str | Path, time_map: TimeMap = DEFAULT_TIME_MAP) -> None:
        """Read the run's tool poses, target features and duration from its bag."""
        from .analysis import load_run
        from .metrics import axis_angle_deg
        from .results import target_features
        run = load_run(Path(run_dir) / 'bag')
        self.time_map = time_map
        self.t_ns = np.round(run.t * 1e9).astype(np.int64)
        self.position = run.position
        self.position_error = np.linalg.norm(run.position - run.target[:3, 3], axis=1)
        self.axis_error = axis_angle_deg(run.rotation, run.target[:3, :3])
        self.target = target_features(run)
        self.end_s = float(run.run_info.get('duration_s') or run.t[-1])
        self.name = run.params.get('scenario_name') or 'run'
        self.view = ArmView()

    def errors_at(self, t_ns: int) -> tuple[float, float]:
        """Return the position (m) and axis (deg) errors of the latest step at ``t_ns``."""
        i = max(int(np.searchsorted(self.t_ns, t_ns, side='right')) - 1, 0)
        return float(self.position_error[i]), float(self.axis_error[i])

    def compose(self, frame: Frame) -> NDArray[np.uint8]:
        """Return the film frame (H, W, 3) RGB of one camera frame."""
        t_s = frame.t_ns * 1e-9
        images = np.vstack([camera_panel(frame.left, 0, frame.features, self.target,
                                         frame.raw),
                            camera_panel(frame.right, 1, frame.features, self.target,
                                         frame.raw)])
        step = int(np.searchsorted(self.t_ns, frame.t_ns, side='right'))
        view = self.view.draw(t_s, frame.poses, self.position[:max(step, 1)])
        view = cv2.resize(view, (view.shape[1], images.shape[0]))
        top = np.hstack([images, view])
        position, axis = self.errors_at(frame.t_ns)
        within = SUCCESS.within(position, axis)
        status = (f'{self.name}  sim t = {t_s:.3f} / {self.end_s:g} s  '
                  f'({self.time_map.speed_at(t_s):g}x real time)  position error '
                  f'{position * 1e3:.2f} mm  tool axis {axis:.3f} deg  '
                  f"[{'within' if within else 'outside'} {SUCCESS.describe()}]  "
                  f'features {frame.mode}')
        frame_rgb = np.vstack([top, status_band(top.shape[1], status, LEGEND)])
        return frame_rgb[:frame_rgb.shape[0] // 2 * 2, :frame_rgb.shape[1] // 2 * 2]


def _shown_for(time_map, t_s, next_s, end_s, fps):
    """Return the film frames a camera frame at ``t_s`` stays (to ``next_s`` or the end)."""
    first = round(time_map.film_s(t_s) * fps)
    if next_s is None:
        return max(round(time_map.film_s(end_s) * fps), first + 1) - first
    return max(round(time_map.film_s(next_s) * fps) - first, 0)


def film_frames(frames: Sequence[float], end_s: float, time_map: TimeMap, fps: float = FPS
                ) -> list[int]:
    """
    Return how many film frames each camera frame stays on screen.

    ``frames``: the camera frames' sim times (s), increasing; each is shown from its film
    time (:meth:`TimeMap.film_s`) to the next one's, the last to ``end_s``'s: the film
    covers the whole run. Counted on the film's frame grid, so the counts sum to the film's
    length whatever the speeds (a camera frame may get 0 at speeds above 1).
    """
    nexts = list(frames[1:]) + [None]
    return [_shown_for(time_map, t, n, end_s, fps) for t, n in zip(frames, nexts)]


def write_video(run_dir: str | Path, out_path: str | Path | None = None,
                time_map: TimeMap = DEFAULT_TIME_MAP, fps: int = FPS,
                progress: Callable[[str], None] = print) -> tuple[Path, int]:
    """
    Write the film of a run to ``RUN_DIR/video.mp4`` (or ``out_path``); return (path, frames).

    ``frames``: the film frames written; the camera frames stamped from the run's
    ``duration_s`` on (recorded while it stopped) are left out, as the metrics leave them
    out (:func:`.analysis.load_run`). Prints progress with an ETA. Raises
    :class:`NoImages` when the bag has neither camera nor overlay images.
    """
    import av
    run_dir = Path(run_dir)
    bag = run_dir / 'bag'
    out_path = Path(out_path or run_dir / 'video.mp4')
    total = count_frames(bag)
    film = Film(run_dir, time_map)
    stamps = []
    start = time.monotonic()
    written = 0
    container = av.open(str(out_path), mode='w', options={'movflags': '+faststart'})
    stream = None
    try:
        previous = None
        for n, frame in enumerate(read_frames(bag), start=1):
            if stamps and frame.t_ns * 1e-9 >= film.end_s:
                break  # recorded while the run was being stopped: not part of it
            stamps.append(frame.t_ns * 1e-9)
            if previous is not None:
                written += _emit(container, stream, previous,
                                 _shown_for(time_map, stamps[-2], stamps[-1], film.end_s, fps))
            image = film.compose(frame)
            if stream is None:
                stream = container.add_stream(CODEC, rate=Fraction(fps))
                stream.width, stream.height = image.shape[1], image.shape[0]
                stream.pix_fmt = PIXEL_FORMAT
                stream.options = dict(CODEC_OPTIONS)
            previous = image
            if n % 10 == 0 or n == total:
                progress(progress_line(n, total, time.monotonic() - start))
        if previous is None:
            raise NoImages(f'{bag}: no frame with both images and /tf')
        written += _emit(container, stream, previous,
                         _shown_for(time_map, stamps[-1], None, film.end_s, fps))
        progress(summary_line(len(stamps), written, fps))
        for packet in stream.encode():
            container.mux(packet)
    finally:
        container.close()
    return out_path, written


def progress_line(n: int, total: int, elapsed_s: float) -> str:
    """Return the progress of the ``n``-th camera frame of (at most) ``total``."""
    return (f'  video: camera frame {n}/{total}  {100.0 * n / max(total, 1):5.1f} %'
            f'  elapsed {elapsed_s:5.1f} s  ETA {elapsed_s / n * max(total - n, 0):5.1f} s')


def summary_line(camera_frames: int, film_frames: int, fps: int = FPS) -> str:
    """
    Return what the film is made of: its camera frames, each shown for film frames.

    The progress counts camera frames; the film has as many film frames as its length
    times ``fps`` (:func:`film_frames`), more than camera frames where it plays slowed.
    """
    return (f'  video: {camera_frames} camera frames, shown as {film_frames} film frames '
            f'({film_frames / fps:.1f} s at {fps} fps)')


def _emit(container, stream, image, count):
    """Encode ``image`` ``count`` times (its time on screen); return ``count``."""
    import av
    if count:
        frame = av.VideoFrame.from_ndarray(image, format='rgb24')
        for _ in range(count):
            for packet in stream.encode(frame):
                container.mux(packet)
    return count


def still(run_dir: str | Path, out_path: str | Path, sim_s: float | None = None) -> Path:
    """Write the film frame at sim time ``sim_s`` (default: mid-run) as a PNG; return it."""
    film = Film(run_dir)
    sim_s = film.end_s / 2 if sim_s is None else sim_s
    chosen = None
    for frame in read_frames(Path(run_dir) / 'bag'):
        if chosen is not None and frame.t_ns * 1e-9 > min(sim_s, film.end_s):
            break
        chosen = frame
    if chosen is None:
        raise NoImages(f'{run_dir}: no frame with both images and /tf')
    image = film.compose(chosen)
    cv2.imwrite(str(out_path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
    return Path(out_path)
