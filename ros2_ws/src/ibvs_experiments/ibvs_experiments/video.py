"""
``ibvs video RUN_DIR``: a film of a recorded run, one frame per camera frame.

Each video frame puts the feature node's two overlay images (/ibvs/debug/{left,right}/image,
:mod:`ibvs_vision.overlay`; recorded by ``ibvs run --overlays`` or ``--video``) side by
side with a 3D view of the arm drawn from the bag's /tf and /tf_static at the frame's stamp
(what RViz would show: links, tool, markers, the camera and its lenses' fields of view, the
target and the tool's path so far). Written with OpenCV's VideoWriter ('mp4v', at the
camera's frame rate) to ``RUN_DIR/video.mp4``; the 3D view is drawn with matplotlib (Agg).
"""

from collections.abc import Callable, Iterator, Mapping
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

#: Height (px) of each panel of the video; the overlays are scaled to it.
PANEL_HEIGHT = 360
#: The zoomed inset of each overlay: this many image pixels around the markers' features,
#: drawn INSET_PX wide in the panel's lower right corner (the markers are small at 2.4 m).
ZOOM_HALF_PX = 45
INSET_PX = 160
FOURCC = 'mp4v'
#: The chain drawn as the arm, from the base to the flange.
ARM_FRAMES = (contract.BASE_FRAME,) + tuple(f'link_{i}' for i in range(1, 7)) + ('tool0',)


class NoOverlays(ValueError):
    """The bag has no overlay images: the run was not recorded with --overlays / --video."""


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


def read_frames(bag_path: str | Path
                ) -> Iterator[tuple[int, NDArray[np.uint8], NDArray[np.uint8],
                                    dict[str, NDArray[np.float64]]]]:
    """
    Yield (stamp ns, left rgb, right rgb, {frame: T^base_link}) of each overlaid frame.

    Each overlay gets a zoomed inset of its markers (:func:`_with_inset`) when the frame's
    /ibvs/features is in the bag.

    The poses compose /tf_static with the /tf message of the frame's stamp (the viz node
    publishes one per frame joint state, stamped as the frame). Two passes over the bag:
    the transforms first, then the images one pair at a time (a run's images do not fit in
    memory at HD720).
    """
    typestore = get_typestore(Stores.ROS2_JAZZY)
    static, dynamic, features = {}, {}, {}
    with AnyReader([Path(bag_path)], default_typestore=typestore) as reader:
        conns = [c for c in reader.connections
                 if c.topic in (contract.TF, contract.TF_STATIC, contract.FEATURES)]
        for conn, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == contract.FEATURES:
                features[stamp_ns(msg.header.stamp)] = np.array(
                    [[p.x, p.y, p.z] for p in msg.polygon.points]).ravel()
                continue
            local = {t.child_frame_id: (t.header.frame_id, _matrix(t.transform))
                     for t in msg.transforms}
            if conn.topic == contract.TF_STATIC:
                static.update(local)
            elif msg.transforms:
                dynamic[stamp_ns(msg.transforms[0].header.stamp)] = local
        sides = {contract.DEBUG_LEFT_IMAGE: 0, contract.DEBUG_RIGHT_IMAGE: 1}
        conns = [c for c in reader.connections if c.topic in sides]
        if not conns:
            raise NoOverlays(f'{bag_path}: no {contract.DEBUG_LEFT_IMAGE} images; record the '
                             'run with `ibvs run --overlays` (or --video)')
        pending = {}
        for conn, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            array = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.step)
            array = array[:, :3 * msg.width].reshape(msg.height, msg.width, 3)
            t_ns = stamp_ns(msg.header.stamp)
            pair = pending.setdefault(t_ns, [None, None])
            pair[sides[conn.topic]] = array
            if pair[0] is not None and pair[1] is not None:
                del pending[t_ns]
                if t_ns in dynamic:
                    left, right = pair
                    if t_ns in features and features[t_ns].size == 6:
                        left, right = (_with_inset(image, side, features[t_ns])
                                       for image, side in ((left, 'left'), (right, 'right')))
                    yield t_ns, left, right, frame_poses({**static, **dynamic[t_ns]})


def count_frames(bag_path: str | Path) -> int:
    """Return how many left overlay images the bag holds (the video's frame count)."""
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([Path(bag_path)], default_typestore=typestore) as reader:
        return sum(c.msgcount for c in reader.connections
                   if c.topic == contract.DEBUG_LEFT_IMAGE)


class ArmView:
    """A matplotlib 3D view of the cell, redrawn for each frame into an RGB array."""

    def __init__(self, height_px: int = PANEL_HEIGHT, width_px: int | None = None) -> None:
        """Make the figure (``width_px`` defaults to 4/3 of the height)."""
        width_px = width_px or int(height_px * 4 / 3)
        self.figure = Figure(figsize=(width_px / 100.0, height_px / 100.0), dpi=100)
        self.canvas = FigureCanvasAgg(self.figure)
        self.axes = self.figure.add_subplot(projection='3d')
        self.path = []

    def draw(self, t_s: float, poses: Mapping[str, NDArray[np.float64]]) -> NDArray[np.uint8]:
        """Return the view (H, W, 3) uint8 of the frame poses ``poses`` at time ``t_s``."""
        ax = self.axes
        ax.cla()
        arm = np.array([poses[f][:3, 3] for f in ARM_FRAMES if f in poses])
        ax.plot(*arm.T, '-o', color='0.45', lw=4, ms=3)
        tool = poses.get('tool0')
        if tool is not None:
            self.path.append(tool[:3, 3])
            ax.plot(*np.array(self.path).T, color='goldenrod', lw=1)
        for k, colour in ((1, 'red'), (2, 'blue')):
            if f'marker_{k}' in poses:
                ax.scatter(*poses[f'marker_{k}'][:3, 3], color=colour, s=12)
        if scene.TARGET_FRAME in poses:
            target = poses[scene.TARGET_FRAME]
            ax.quiver(*(target[:3, 3] - 0.3 * target[:3, 2]), *(0.3 * target[:3, 2]),
                      color='green')
        if contract.CAMERA_FRAME in poses:
            cam = poses[contract.CAMERA_FRAME]
            ax.scatter(*cam[:3, 3], color='black', marker='s', s=20)
            ax.plot(*np.array([cam[:3, 3], cam[:3, 3] + 0.4 * cam[:3, 2]]).T, color='black',
                    lw=1)
        ax.set_xlim(-1.5, 2.5)
        ax.set_ylim(-2.0, 2.0)
        ax.set_zlim(-0.5, 2.5)
        ax.set_box_aspect((4, 4, 3))
        ax.set_xlabel('x [m]')
        ax.set_ylabel('y [m]')
        ax.set_zlabel('z [m]')
        ax.set_title(f't = {t_s:.3f} s', fontsize=9)
        self.canvas.draw()
        return np.asarray(self.canvas.buffer_rgba())[:, :, :3].copy()


def _with_inset(image, side, features):
    """Return ``image`` with the region around the markers, magnified, in a corner."""
    points = features.reshape(2, 3)[:, [0 if side == 'left' else 1, 2]]
    u, v = points.mean(axis=0)
    height, width = image.shape[:2]
    scale = max(1.0, width / 640.0)
    half = int(ZOOM_HALF_PX * scale)
    size = int(INSET_PX * scale)
    if not (np.isfinite(u) and np.isfinite(v)) or size >= min(height, width) // 2:
        return image
    u0 = int(np.clip(round(u) - half, 0, width - 2 * half))
    v0 = int(np.clip(round(v) - half, 0, height - 2 * half))
    zoom = cv2.resize(image[v0:v0 + 2 * half, u0:u0 + 2 * half], (size, size),
                      interpolation=cv2.INTER_NEAREST)
    out = image.copy()
    top, left = height - size - int(30 * scale), width - size - 4
    out[top:top + size, left:left + size] = zoom
    cv2.rectangle(out, (left - 1, top - 1), (left + size, top + size), (255, 255, 255), 1)
    cv2.rectangle(out, (u0, v0), (u0 + 2 * half, v0 + 2 * half), (255, 255, 255), 1)
    return out


def _scaled(image, height):
    width = int(round(image.shape[1] * height / image.shape[0]))
    return cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)


def write_video(run_dir: str | Path, out_path: str | Path | None = None,
                fps: float | None = None, progress: Callable[[str], None] = print
                ) -> tuple[Path, int]:
    """
    Write ``RUN_DIR/video.mp4`` (or ``out_path``) from the run's bag; return (path, frames).

    ``fps`` defaults to the run's ``camera_rate_hz`` (30). Prints progress with an ETA.
    Raises :class:`NoOverlays` when the bag has no overlay images.
    """
    from .analysis import load_run
    run_dir = Path(run_dir)
    bag = run_dir / 'bag'
    out_path = Path(out_path or run_dir / 'video.mp4')
    fps = fps or float(load_run(bag).params.get('camera_rate_hz', 30.0))
    total = count_frames(bag)
    view = ArmView()
    writer = None
    start = time.monotonic()
    n = 0
    try:
        for n, (t_ns, left, right, poses) in enumerate(read_frames(bag), start=1):
            panel = np.hstack([_scaled(left, PANEL_HEIGHT), _scaled(right, PANEL_HEIGHT),
                               view.draw(t_ns * 1e-9, poses)])
            if writer is None:
                writer = cv2.VideoWriter(str(out_path), cv2.VideoWriter_fourcc(*FOURCC), fps,
                                         (panel.shape[1], panel.shape[0]))
                if not writer.isOpened():
                    raise RuntimeError(f'OpenCV cannot write {out_path} with {FOURCC!r}')
            writer.write(cv2.cvtColor(panel, cv2.COLOR_RGB2BGR))
            if n % 10 == 0 or n == total:
                elapsed = time.monotonic() - start
                eta = elapsed / n * max(total - n, 0)
                progress(f'  video: frame {n}/{total}  {100.0 * n / max(total, 1):5.1f} %'
                         f'  elapsed {elapsed:5.1f} s  ETA {eta:5.1f} s')
    finally:
        if writer is not None:
            writer.release()
    return out_path, n


def still(run_dir: str | Path, out_path: str | Path, index: int | None = None) -> Path:
    """Write one video frame (the middle one by default) as a PNG; return its path."""
    bag = Path(run_dir) / 'bag'
    index = count_frames(bag) // 2 if index is None else index
    view = ArmView()
    for n, (t_ns, left, right, poses) in enumerate(read_frames(bag)):
        if n == index:
            break
        view.path.append(poses['tool0'][:3, 3])  # the tool's path up to that frame
    panel = np.hstack([_scaled(left, PANEL_HEIGHT), _scaled(right, PANEL_HEIGHT),
                       view.draw(t_ns * 1e-9, poses)])
    cv2.imwrite(str(out_path), cv2.cvtColor(panel, cv2.COLOR_RGB2BGR))
    return Path(out_path)
