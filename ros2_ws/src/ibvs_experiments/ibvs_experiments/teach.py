"""
``ibvs teach``: the taught target as a command, recorded on a cell and published for it.

With the tool held at the target (on a cell the operator jogs the arm there; in the
rehearsal the simulator starts there, ``sim_node -p start_at_target:=true``), ``ibvs teach
[-o DIR]`` takes from the camera's topics (the ZED wrapper's, as ``ibvs cell`` names them,
:func:`ibvs_bringup.cell_checks.camera_topics`) ``teach_frames`` consecutive stereo pairs (a
left and a right image of one stamp) while every arm joint of /joint_states stays within
``--still-tol-deg`` (:data:`ibvs_model.handeye.STILL_TOL_RAD`, the calibration's rule of a
still arm) over their span, and averages them pixel by pixel
(:class:`ibvs_common.teach.FrameMean`, the rule of the simulator's own teach pair). A joint
that moves starts the frames again.

It writes the folder (:func:`.output_dir.claim`: a new or empty folder, or one that an
``ibvs`` command wrote; never another) with:

- ``left.png``, ``right.png``: the mean pair, 8-bit RGB;
- ``teach.yaml`` (:data:`RECORD`): the joints (by name, rad; the means over the frames'
  span, and their spread), the stamps of the first and last frame, the frames averaged,
  each lens's camera_info, the camera's topics and encoding, the target (below) and, where
  the simulator's /ibvs/tool_path is there (a rehearsal), the true flange pose
  ``true_tool_pose`` (:data:`ibvs_analysis.analysis.TRUE_TOOL_POSE_KEY`);
- ``target.yaml`` (:data:`TARGET_FILE`): a parameter file of ``target_position`` and
  ``target_rotation``, the nominal forward kinematics of the recorded joints. That is the
  pose the encoders will read when the images match the taught ones: the cell's target
  and its taught pair then agree by construction (the feedforward goes where the feedback
  converges), whatever the encoders' offsets. ``ibvs cell --teach DIR`` takes it; by hand,
  one more ``--params-file``.

``ibvs teach --publish DIR`` publishes a recorded pair latched (transient local, as the
feature node reads it) on /stereo/teach/{left,right}/image_raw until SIGINT, for a graph
started by hand; ``ibvs cell --teach DIR`` publishes it from its own process
(:func:`publish_pair`). The ROS domain is the cell's (``ROS_DOMAIN_ID``, else 0), as
``ibvs cell``'s; no lock is taken: it only listens, or publishes one latched pair.
"""

import argparse
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import sys
import time
from typing import Any

from ibvs_bringup.cell_checks import camera_topics, CellError
from ibvs_common import contract
from ibvs_common.teach import FrameMean, TEACH_FRAMES
from ibvs_model import handeye
import numpy as np
from numpy.typing import NDArray
import yaml

#: The record's file and the target's parameter file in a teach folder.
RECORD = 'teach.yaml'
TARGET_FILE = 'target.yaml'
IMAGES = {'left': 'left.png', 'right': 'right.png'}
#: What a teach writes into its folder, by name (an earlier teach's are replaced).
WRITES = (RECORD, TARGET_FILE, *IMAGES.values())
#: The first line of the files ``ibvs teach`` writes.
MARKER = '# written by ibvs teach'
#: Where ``ibvs teach`` writes without ``-o``: a folder per teach.
TEACH_DIR = Path('results') / 'teach'
#: The frames ``ibvs teach`` averages by default (the simulator's own ``teach_frames``
#: defaults to one frame: its rehearsal runs have always taught on one).
DEFAULT_FRAMES = 10
#: Wall seconds the camera and the arm have to give the frames (``--timeout``).
TIMEOUT_S = 30.0
#: Exit code when the frames did not come in time (the cell's topics, as ``ibvs cell``'s).
EXIT_NO_FRAMES = 5
#: Stereo pairs waiting for their other image: older ones are dropped.
MAX_PENDING = 8
#: Joint states kept before the first frame of a teach (ns): more than a camera's latency.
KEEP_NS = 2_000_000_000


class TeachError(ValueError):
    """A teach that cannot be done, or a folder that is not a teach record (in words)."""


# ------------------------------------------------------------------------- the frames

@dataclass
class Collector:
    """
    The frames of a teach as they come (no ROS): pairs, their mean, the still joints.

    Feed :meth:`image` (a side's RGB pixels and stamp), :meth:`joints` (a /joint_states'
    stamp and the six arm angles) and :meth:`tool` (the simulator's true flange pose);
    :meth:`result` is None until ``frames`` pairs were averaged and a joint state stamped
    at or after the last of them came, then the :class:`Taught`. A pair whose span saw a
    joint move more than ``still_tol_rad`` is dropped with the frames before it
    (:attr:`restarts`, :attr:`last_motion`).
    """

    frames: int
    still_tol_rad: float = handeye.STILL_TOL_RAD
    mean: FrameMean = field(default_factory=FrameMean)
    stamps: list = field(default_factory=list)
    restarts: int = 0
    last_motion: str = ''
    _pending: dict = field(default_factory=dict)
    _states: list = field(default_factory=list)
    _tool: Any = None
    _last_stamp: int | None = None

    def image(self, side: str, stamp_ns: int, pixels: NDArray[np.uint8]) -> None:
        """Take one image; a pair of one stamp, newer than the last taken, is averaged."""
        if self.mean.count >= self.frames:
            return
        entry = self._pending.setdefault(int(stamp_ns), {})
        entry[side] = pixels
        if len(entry) < 2:
            while len(self._pending) > MAX_PENDING:
                self._pending.pop(min(self._pending))
            return
        del self._pending[int(stamp_ns)]
        if self._last_stamp is not None and stamp_ns <= self._last_stamp:
            return  # older than the frames taken: not consecutive
        self._last_stamp = int(stamp_ns)
        self.mean.add((entry['left'], entry['right']))
        self.stamps.append(int(stamp_ns))

    def joints(self, stamp_ns: int, q: NDArray[np.float64]) -> None:
        """Take one joint state (the six arm joints, contract order)."""
        self._states.append((int(stamp_ns), np.asarray(q, dtype=float)))
        # Kept: from KEEP_NS before the first frame taken (or before the newest state while
        # none is), so that the state just before a frame that comes late is still there.
        since = (self.stamps[0] if self.stamps else int(stamp_ns)) - KEEP_NS
        while self._states and self._states[0][0] < since:
            self._states.pop(0)

    def tool(self, pose: NDArray[np.float64]) -> None:
        """Take the simulator's true flange pose (4x4): a rehearsal's truth."""
        self._tool = np.asarray(pose, dtype=float)

    def _span(self):
        """Return the joint states that bracket and fall within the frames' span."""
        first, last = self.stamps[0], self.stamps[-1]
        before = [s for s in self._states if s[0] < first][-1:]
        inside = [s for s in self._states if first <= s[0] <= last]
        after = [s for s in self._states if s[0] > last][:1]
        return before + inside + after

    def result(self) -> 'Taught | None':
        """Return the taught pair and joints once complete and still (class docstring)."""
        if self.mean.count < self.frames or \
                not any(t >= self.stamps[-1] for t, _ in self._states):
            return None
        span = self._span()
        q = np.array([s[1] for s in span])
        spread = q.max(axis=0) - q.min(axis=0)
        if spread.max() > self.still_tol_rad:
            j = int(np.argmax(spread))
            self.last_motion = (f'joint_{j + 1} moved {math.degrees(spread[j]):.4f} deg over '
                                f'the {self.frames} frames (still: within '
                                f'{math.degrees(self.still_tol_rad):.4g} deg)')
            self.restarts += 1
            self.mean, self.stamps, self._last_stamp = FrameMean(), [], None
            return None
        left, right = self.mean.mean()
        return Taught(left, right, q.mean(axis=0), spread, len(span), tuple(self.stamps),
                      self._tool)


@dataclass(frozen=True)
class Taught:
    """A teach's pair (RGB uint8), joints (rad, contract order) and what they came with."""

    left: NDArray[np.uint8]
    right: NDArray[np.uint8]
    joints: NDArray[np.float64]
    spread: NDArray[np.float64]
    joint_states: int
    stamps: tuple
    true_tool_pose: NDArray[np.float64] | None = None


# ---------------------------------------------------------------------- the record

def target_of(joints: Sequence[float]) -> dict[str, list[float]]:
    """
    Return ``target_position`` and ``target_rotation`` of the flange at ``joints`` (rad).

    The nominal IRB 4600's forward kinematics (eq. 7), the model every node plans with;
    rounded to 12 significant digits, which :func:`ibvs_model.paper.target_pose` reads back
    as the same rotation.
    """
    from ibvs_model import forward_kinematics
    pose = forward_kinematics(np.asarray(joints, dtype=float))
    return {'target_position': [float(f'{v:.12g}') for v in pose[:3, 3]],
            'target_rotation': [float(f'{v:.12g}') for v in pose[:3, :3].ravel()]}


def info_dict(msg: Any) -> dict[str, Any]:
    """Return a CameraInfo's calibration as plain YAML values."""
    return {'frame_id': msg.header.frame_id, 'width': int(msg.width),
            'height': int(msg.height), 'distortion_model': msg.distortion_model,
            'd': [float(v) for v in msg.d], 'k': [float(v) for v in msg.k],
            'r': [float(v) for v in msg.r], 'p': [float(v) for v in msg.p]}


def record_of(taught: Taught, infos: Mapping[str, Any], topics: Mapping[str, str],
              encoding: str) -> dict[str, Any]:
    """Return the teach record (:data:`RECORD`'s content) of ``taught``."""
    from ibvs_analysis.analysis import TRUE_TOOL_POSE_KEY
    out = {
        'frames': len(taught.stamps),
        'first_stamp_ns': int(taught.stamps[0]), 'last_stamp_ns': int(taught.stamps[-1]),
        'joints': {name: float(v) for name, v in zip(contract.JOINT_NAMES, taught.joints)},
        'joints_deg': [round(math.degrees(v), 9) for v in taught.joints],
        'joint_spread_rad': [float(v) for v in taught.spread],
        'joint_states': int(taught.joint_states),
        **target_of(taught.joints),
        'camera_topics': dict(topics), 'encoding': encoding,
        'camera_info': {side: dict(info) for side, info in infos.items()},
    }
    if taught.true_tool_pose is not None:
        out[TRUE_TOOL_POSE_KEY] = [[float(v) for v in row] for row in taught.true_tool_pose]
    return out


def target_text(record: Mapping[str, Any], source: str) -> str:
    """Return :data:`TARGET_FILE`: the target of ``record`` as a parameter file."""
    def values(key):
        return '[' + ', '.join(repr(float(v)) for v in record[key]) + ']'
    return '\n'.join([
        MARKER, f'# the target of {source}: the forward kinematics of the joints recorded with '
        'its pair', '/**:', '  ros__parameters:',
        f'    target_position: {values("target_position")}',
        f'    target_rotation: {values("target_rotation")}', ''])


def write(claim: Any, taught: Taught, record: Mapping[str, Any]) -> Path:
    """Write the teach folder of ``claim`` (:func:`.output_dir.claim`): pair, record, target."""
    import cv2
    folder = claim.path
    claim.remove(WRITES)
    for side, pixels in (('left', taught.left), ('right', taught.right)):
        if not cv2.imwrite(str(folder / IMAGES[side]), cv2.cvtColor(pixels, cv2.COLOR_RGB2BGR)):
            raise TeachError(f'cannot write {folder / IMAGES[side]}')
    (folder / RECORD).write_text(f'{MARKER}: the stereo pair of the tool held at the target '
                                 f'({", ".join(IMAGES.values())})\n'
                                 + yaml.safe_dump(dict(record), sort_keys=False))
    (folder / TARGET_FILE).write_text(target_text(record, f'{folder / RECORD}'))
    return folder


def read(folder: str | Path) -> tuple[dict[str, Any], NDArray[np.uint8], NDArray[np.uint8]]:
    """
    Return (record, left, right) of a teach folder; :class:`TeachError` if it is not one.

    The images must be the size of the record's camera_info.
    """
    import cv2
    folder = Path(folder)
    path = folder / RECORD
    try:
        record = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise TeachError(f'{folder} is no teach folder: cannot read {path} ({exc.strerror}); '
                         'record one with ibvs teach -o DIR') from None
    except yaml.YAMLError as exc:
        raise TeachError(f'{path} is not YAML: {exc}') from None
    keys = ('joints', 'target_position', 'target_rotation', 'camera_info', 'last_stamp_ns')
    if not isinstance(record, dict) or any(k not in record for k in keys):
        raise TeachError(f'{path} is no teach record (expected the keys {", ".join(keys)})')
    pixels = {}
    for side, name in IMAGES.items():
        image = cv2.imread(str(folder / name), cv2.IMREAD_COLOR)
        if image is None:
            raise TeachError(f'{folder / name}: missing or not an image')
        pixels[side] = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
        info = record['camera_info'].get(side, {})
        size = (info.get('width'), info.get('height'))
        if (image.shape[1], image.shape[0]) != size:
            raise TeachError(f'{folder / name} is {image.shape[1]} x {image.shape[0]}, its '
                             f'camera_info {size[0]} x {size[1]}')
    return record, pixels['left'], pixels['right']


@dataclass(frozen=True)
class Recorded:
    """A teach folder as read (:func:`load`): its record and its pair (RGB uint8)."""

    folder: Path
    record: dict
    left: NDArray[np.uint8]
    right: NDArray[np.uint8]

    def publish(self, node: Any) -> tuple[Any, Any]:
        """Publish the pair latched from ``node`` (:func:`publish_pair`)."""
        return publish_pair(node, self.record, self.left, self.right)


def load(folder: str | Path) -> Recorded:
    """Return the teach folder ``folder`` (:func:`read`); :class:`TeachError` if not one."""
    return Recorded(Path(folder), *read(folder))


def target_overrides(record: Mapping[str, Any]) -> dict[str, list[float]]:
    """Return the parameters a teach record sets: its target (:data:`TARGET_FILE`)."""
    return {key: [float(v) for v in record[key]]
            for key in ('target_position', 'target_rotation')}


# ------------------------------------------------------------------------ ROS plumbing

def publish_pair(node: Any, record: Mapping[str, Any], left: NDArray[np.uint8],
                 right: NDArray[np.uint8]) -> tuple[Any, Any]:
    """
    Publish a recorded pair latched on /stereo/teach/{left,right}/image_raw from ``node``.

    rgb8, stamped with the last frame's stamp, each with its lens's frame id; returns the
    two publishers (keep them: the pair is there while they live).
    """
    from ibvs_common.conversions import image_msg
    from sensor_msgs.msg import Image
    pubs = []
    for topic, side, pixels in ((contract.TEACH_LEFT_IMAGE, 'left', left),
                                (contract.TEACH_RIGHT_IMAGE, 'right', right)):
        pub = node.create_publisher(Image, topic, contract.LATCHED)
        frame = record['camera_info'].get(side, {}).get('frame_id', '')
        pub.publish(image_msg(pixels, int(record['last_stamp_ns']), 'rgb8', frame))
        pubs.append(pub)
    return tuple(pubs)


def _rgb(msg):
    """Return an Image's pixels as RGB (the feature node's reading, alpha dropped)."""
    from ibvs_vision.imageconv import image_array
    pixels, encoding = image_array(msg)
    return np.ascontiguousarray(pixels[:, :, ::-1]) if encoding == 'bgr8' else pixels


def _domain():
    """Put the process on the cell's domain (ROS_DOMAIN_ID, else ROS's default 0)."""
    from ibvs_bringup import domains
    if domains.domain_id() is None:
        os.environ[domains.DOMAIN_ENV] = '0'
    return domains.domain_id()


def collect(camera_name: str, frames: int, timeout_s: float, still_tol_rad: float,
            print_line: Callable[[str], None] = print,
            stop: Callable[[], bool] = lambda: False
            ) -> tuple[Taught | None, dict[str, Any], dict[str, str], str, list[str]]:
    """
    Take the frames from the cell's topics: (taught or None, infos, topics, encoding, missing).

    ``missing``: the topics that gave no message, when the frames did not come within
    ``timeout_s`` of wall time (or ``stop()`` said so).
    """
    from ibvs_common import dds
    from ibvs_common.conversions import InputError, pose_matrix, read_joints, stamp_ns
    from nav_msgs.msg import Path as PathMsg
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from sensor_msgs.msg import CameraInfo, Image, JointState

    zed = camera_topics(camera_name)
    topics = {'left': zed[contract.LEFT_IMAGE], 'right': zed[contract.RIGHT_IMAGE]}
    info_topics = {'left': zed[contract.LEFT_INFO], 'right': zed[contract.RIGHT_INFO]}
    collector = Collector(frames, still_tol_rad)
    infos, heard, encoding = {}, set(), ['']
    dds.configure()
    context = rclpy.context.Context()
    rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('ibvs_teach', context=context, parameter_overrides=[])
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)

    def on_image(side, msg):
        heard.add(topics[side])
        try:
            pixels = _rgb(msg)
        except InputError as exc:
            print_line(f'  {topics[side]}: image refused ({exc.reason}: {exc.detail})')
            return
        encoding[0] = msg.encoding
        collector.image(side, stamp_ns(msg.header.stamp), pixels)

    def on_info(side, msg):
        heard.add(info_topics[side])
        infos.setdefault(side, info_dict(msg))

    def on_joints(msg):
        heard.add(contract.JOINT_STATES)
        try:
            collector.joints(stamp_ns(msg.header.stamp), read_joints(msg))
        except InputError:
            pass

    def on_tool(msg):
        if msg.poses:
            collector.tool(pose_matrix(msg.poses[-1].pose))

    try:
        for side in ('left', 'right'):
            node.create_subscription(Image, topics[side], lambda m, s=side: on_image(s, m),
                                     contract.IMAGES)
            node.create_subscription(CameraInfo, info_topics[side],
                                     lambda m, s=side: on_info(s, m), contract.CAMERA_INFO)
        node.create_subscription(JointState, contract.JOINT_STATES, on_joints,
                                 contract.RELIABLE)
        node.create_subscription(PathMsg, contract.TOOL_PATH, on_tool, contract.RELIABLE)
        print_line(f'ibvs teach: ROS_DOMAIN_ID {os.environ.get("ROS_DOMAIN_ID")}; taking '
                   f'{frames} stereo pairs of the still tool from {topics["left"]}, '
                   f'{topics["right"]} and {contract.JOINT_STATES} (up to {timeout_s:g} s)')
        deadline = time.monotonic() + timeout_s
        restarts = 0
        while time.monotonic() < deadline and not stop():
            executor.spin_once(timeout_sec=0.05)
            if collector.restarts != restarts:
                restarts = collector.restarts
                print_line(f'  the arm moved ({collector.last_motion}): taking the frames '
                           'again')
            taught = collector.result() if len(infos) == 2 else None
            if taught is not None:
                return taught, infos, topics, encoding[0], []
        wanted = [*topics.values(), *info_topics.values(), contract.JOINT_STATES]
        missing = [t for t in wanted if t not in heard]
        if not missing:
            missing = [f'{frames} still stereo pairs ({collector.mean.count} taken'
                       + (f'; {collector.last_motion}' if collector.last_motion else '')
                       + '; every image pair with one stamp, and a /joint_states stamped at '
                       'or after the last: one clock for the camera and the arm)']
        return None, infos, topics, encoding[0], missing
    finally:
        executor.shutdown()
        node.destroy_node()
        context.try_shutdown()


def record_teach(args: argparse.Namespace) -> int:
    """Record a teach (module docstring) into ``args.out``; return the exit code."""
    from . import output_dir, runner
    frames = TEACH_FRAMES.check(args.teach_frames)
    out = Path(args.out) if args.out else output_dir.session_dir(TEACH_DIR)
    _domain()
    with runner.interruptible(deferred=True) as stop:
        claim = output_dir.claim(out)  # before the frames: a refused folder costs nothing
        try:
            taught, infos, topics, encoding, missing = collect(
                args.camera_name, frames, args.timeout, math.radians(args.still_tol_deg),
                stop=stop.is_set if stop is not None else (lambda: False))
            if stop is not None and stop.is_set():
                print('SIGINT: nothing recorded', file=sys.stderr)
                claim.release(WRITES)
                return 130
            if taught is None:
                for text in missing:
                    print(f'error: no {text}', file=sys.stderr)
                print(f'error: nothing recorded in {args.timeout:g} s: is the camera '
                      'publishing (video.publish_left_right true), the driver running, the arm '
                      'still?', file=sys.stderr)
                claim.release(WRITES)
                return EXIT_NO_FRAMES
            record = record_of(taught, infos, topics, encoding)
            write(claim, taught, record)
        finally:
            claim.release()
    print(f'wrote {out}: {", ".join(IMAGES.values())} (the mean of {frames} pairs, '
          f'{taught.joint_states} joint states, largest spread '
          f'{math.degrees(float(taught.spread.max())):.2g} deg), {RECORD}, {TARGET_FILE}')
    print('the target of the taught pose (forward kinematics of the recorded joints), for the '
          "cell's parameters under ros__parameters (ibvs cell --teach DIR sets it):")
    print('\n'.join(line for line in target_text(record, str(out / RECORD)).splitlines()
                    if line.lstrip().startswith('target_')))
    return 0


def publish(args: argparse.Namespace) -> int:
    """Publish a recorded pair latched until SIGINT (``ibvs teach --publish DIR``)."""
    from ibvs_common import dds
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from . import runner
    recorded = load(args.publish)
    _domain()
    with runner.interruptible(deferred=True) as stop:
        dds.configure()
        context = rclpy.context.Context()
        rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node('ibvs_teach', context=context, parameter_overrides=[])
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        try:
            pubs = recorded.publish(node)
            print(f'publishing {args.publish} latched on {pubs[0].topic_name} and '
                  f'{pubs[1].topic_name} (ROS_DOMAIN_ID {os.environ.get("ROS_DOMAIN_ID")}); '
                  f'its target: --params-file {Path(args.publish) / TARGET_FILE} after the '
                  "cell's; Ctrl-C stops", flush=True)
            while stop is None or not stop.is_set():
                executor.spin_once(timeout_sec=0.1)
        except KeyboardInterrupt:
            pass
        finally:
            executor.shutdown()
            node.destroy_node()
            context.try_shutdown()
    return 0


def main(args: argparse.Namespace) -> int:
    """Run ``ibvs teach`` (:mod:`.cli` parses its arguments); return the exit code."""
    from ibvs_common.params import ParameterError

    from . import output_dir
    try:
        if args.publish:
            return publish(args)
        return record_teach(args)
    except (TeachError, ParameterError, CellError, output_dir.OutputRefused) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
