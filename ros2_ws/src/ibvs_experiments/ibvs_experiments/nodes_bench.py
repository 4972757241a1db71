"""
The nodes alone against a real cell's clock: frame-to-command latency, for ``make bench``.

On a real cell nothing waits: the ZED 2 delivers 30 frames a second, the arm's driver
publishes /joint_states every 4 ms (EGM), and the feature, feedback, feedforward and
joint-controller nodes must turn each frame into a joint command in wall time. This bench
measures that with the real nodes and no simulator:

1. **Record** a real-cell run with its images (``ibvs run real_cell --images``, at the
   resolution asked): its bag holds the ZED wrapper's images and camera_info, the joint
   path, /stereo/pose and the taught target's images. A bag already at
   ``<out>/nodes_alone/<resolution>/bag`` is used again.
2. **Replay** it, in this process, as the camera and the arm's driver would publish it, at
   their real rates on the wall clock (``use_sim_time`` false): /joint_states every
   1 / ``command_rate_hz`` (4 ms), with the angles of the bag's joint path at the same time
   into the run, and a camera frame (both images and both camera_info) every 1/30 s. The
   stamps are the times each message is due (on the wall clock's 1 ms grid), not when the
   loaded machine got to publish it. The nodes' stamp rules are the simulator's (docs/
   design.md §4): a frame is stamped on the frame grid (n / 30 s, on the ``physics_rate_hz``
   grid: the joint controller refuses a q_feedback of another stamp) and the feature node
   takes the joint state of exactly its stamp; so each frame is stamped so and gets a joint
   state of its stamp just before it (a camera triggered by the arm's clock). The bag is
   replayed again from its start when it ends, as long as asked. /stereo/pose and the teach
   images are published once, latched. Frame k of the replay is the bag's frame k with the
   joint path at its exposure (its stamp less the recorded run's ``image_stamp_offset_s``),
   the replay's stamps being the exposures (the nodes start from no stamp offset, and the
   feature node's estimate stays within a millisecond of it). At another camera rate than
   the bag's (a ZED 2 gives 60 Hz at HD720 too) the bag plays that much faster, each frame
   in turn and the joint path (angles and speeds) scaled in time alike: what the camera
   would see of a move that much faster; the nodes get that rate as their
   ``camera_rate_hz``.
2a. **The parts of a run** (:func:`segment`): a real-cell run slews to the markers' view
   first (2 s of scenario 1, where a frame rarely holds both markers and the feature node
   searches the whole images and falls back to the model) and then servoes with both
   markers in view, where it spends the rest of the run and where the detector searches
   windows around the predicted markers. Each frame is classified by the detector itself
   (:func:`detectable_frames`: a full search of the pair, no budget), and 'servo' replays
   the frames from the start of the longest run of detectable frames to its end, 'lost'
   the frames before it, 'all' the whole bag: the hot path and the lost-marker path,
   measured apart.
3. **The nodes**: the four nodes of ``docs/real_cell.md`` "By hand", each its own process
   (``ros2 run``), with the bag's parameters but ``use_sim_time: false``, the ZED wrapper's
   topics remapped as the graph remaps them, DDS between them and to this process.

Measured from :data:`WARMUP_S` after the first joint command that used a frame (before it
the graph starts: the feedforward plans its trajectory, which the joint controller waits
for, and the detector makes its first full search): the wall time from the publication of
a frame's first image to the first joint command that uses it (the joint controller's
/ibvs/frame_latency: the command's stamp and the frame's), as mean, p95 and max, over the
frames used; the frames sent and used (a frame the nodes skip has no command of its own);
and the CPU time each node's process takes (user + system, /proc), per wall second and per
frame sent, and this process's (the stand-in camera and driver). The latency counts the
transfer of both images from this process to the feature node (DDS), which a camera driver
in a process of its own costs too. Before each replay, where the feature node's CPU goes a
frame (:func:`frame_split`: rclpy's deserialisation, the detector's stages, the node's own
handling of the messages), measured in a process of its own (``python -m
ibvs_experiments.nodes_bench split``).
"""

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
import os
from pathlib import Path
import threading
import time
from typing import Any

import numpy as np

#: Measurement starts this long (wall s) after the first joint command that used a frame:
#: the graph's start (the feedforward's trajectory, 60 s of it at 1 kHz, which the joint
#: controller waits for; the detector's first full search) is not a frame's latency.
WARMUP_S = 1.0
#: How long the nodes may take to subscribe (wall s) before the replay gives up.
START_TIMEOUT_S = 60.0
#: The parts of a recording that can be replayed (module docstring, step 2a).
SEGMENTS = ('servo', 'lost', 'all')
#: The fewest frames a segment replays: less is not a part of the run worth a measurement.
MIN_SEGMENT_FRAMES = 15
#: detectable_frames of each bag measured in this process, by its path.
_DETECTABLE = {}


@dataclass
class Recording:
    """What the replay sends, read from a real-cell bag (serialised rclpy messages)."""

    #: (left image, right image, left info, right info) of each frame, in order.
    frames: list
    #: The bag's joint path: times (s, from 0), angles and velocities (N, 6).
    joint_t: np.ndarray
    joint_q: np.ndarray
    joint_qd: np.ndarray
    #: Published once, latched: /stereo/pose and the teach images (topic -> message).
    latched: dict
    #: The recorded run's parameters.
    params: dict
    #: The images' (width, height).
    size: tuple
    #: The bag's camera rate (Hz): its frames are this far apart.
    rate_hz: float = 30.0
    #: Where the first frame's exposure is on the joint path (s from its start): the
    #: replay sends the joint states from there on with it.
    joint_offset_s: float = 0.0
    #: Each frame's exposure on the joint path (s from its start): its stamp less the
    #: recorded run's ``image_stamp_offset_s`` (the simulated camera's; 0 when none).
    exposures_s: np.ndarray | None = None
    #: The part of the bag (SEGMENTS) and its first frame's index in the bag.
    segment: str = 'all'
    first_frame: int = 0
    #: The bag it was read from.
    bag: str = ''


def read_recording(bag_path: str | Path) -> Recording:
    """Read a real-cell bag recorded with its images (module docstring, step 1)."""
    from geometry_msgs.msg import PoseStamped
    from ibvs_common import contract
    from ibvs_common.conversions import stamp_ns
    from rclpy.serialization import deserialize_message
    from rosbags.highlevel import AnyReader
    from sensor_msgs.msg import CameraInfo, Image
    import yaml

    from ibvs_analysis import analysis

    bag_path = Path(bag_path)
    meta = yaml.safe_load((bag_path / 'metadata.yaml').read_text())
    custom = meta.get('rosbag2_bagfile_information', {}).get('custom_data') or {}
    params = yaml.safe_load(custom.get(analysis.PARAMS_KEY, '{}')) or {}
    camera = (contract.ZED_LEFT_IMAGE, contract.ZED_RIGHT_IMAGE, contract.ZED_LEFT_INFO,
              contract.ZED_RIGHT_INFO)
    types = {contract.ZED_LEFT_IMAGE: Image, contract.ZED_RIGHT_IMAGE: Image,
             contract.ZED_LEFT_INFO: CameraInfo, contract.ZED_RIGHT_INFO: CameraInfo,
             contract.STEREO_POSE: PoseStamped, contract.TEACH_LEFT_IMAGE: Image,
             contract.TEACH_RIGHT_IMAGE: Image}
    by_stamp, latched = {}, {}
    with AnyReader([bag_path]) as reader:
        conns = [c for c in reader.connections if c.topic in types]
        for conn, _, raw in reader.messages(connections=conns):
            msg = deserialize_message(bytes(raw), types[conn.topic])
            if conn.topic in camera:
                stamp = stamp_ns(msg.header.stamp)
                by_stamp.setdefault(stamp, {})[conn.topic] = msg
            else:
                latched.setdefault(conn.topic, msg)
    complete = [(stamp, parts) for stamp, parts in sorted(by_stamp.items())
                if len(parts) == len(camera)]
    frames = [tuple(parts[t] for t in camera) for _, parts in complete]
    if not frames:
        raise ValueError(f'{bag_path}: no stereo frame on the ZED wrapper topics (record a '
                         'real-cell run with --images)')
    missing = [t for t in (contract.STEREO_POSE,) if t not in latched]
    if missing:
        raise ValueError(f'{bag_path}: no {", ".join(missing)}')
    joint_t, joint_q, joint_qd, *_ = analysis.load_joints(bag_path)
    if len(joint_t) < 2:
        raise ValueError(f'{bag_path}: no joint path')
    size = (int(frames[0][0].width), int(frames[0][0].height))
    # Each frame's exposure on the joint path: its stamp less the simulated camera's offset.
    exposures = np.array([stamp for stamp, _ in complete]) * 1e-9 \
        - float(params.get('image_stamp_offset_s', 0.0)) - joint_t[0]
    return Recording(frames, joint_t - joint_t[0], joint_q, joint_qd, latched, params, size,
                     rate_hz=float(params.get('camera_rate_hz', 30.0)),
                     joint_offset_s=float(exposures[0]), exposures_s=exposures,
                     bag=str(bag_path))


def detectable_frames(recording: Recording) -> np.ndarray:
    """
    Return whether the detector measures both markers in each frame of ``recording``.

    A full search of each pair (no prediction, no budget), OpenCV on one thread, with the
    camera of the bag's camera_info and /stereo/pose: what the frame holds, whatever the
    nodes' state when it comes.
    """
    import cv2
    from ibvs_common import contract
    from ibvs_common.conversions import camera_from_msgs
    from ibvs_vision.detector import StereoDetector
    from ibvs_vision.imageconv import image_array

    left_info, right_info = recording.frames[0][2:4]
    camera = camera_from_msgs(left_info, right_info, recording.latched[contract.STEREO_POSE])
    detector = StereoDetector(camera.intrinsics)
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        out = []
        for left, right, *_ in recording.frames:
            (left, encoding), (right, _) = image_array(left), image_array(right)
            out.append(detector.detect(left, right, encoding).ok)
    finally:
        cv2.setNumThreads(threads)
    return np.array(out, dtype=bool)


def segment_bounds(detectable: Sequence[bool], which: str) -> tuple[int, int]:
    """
    Return the frames [start, end) of part ``which`` of a run (module docstring, step 2a).

    ``detectable``: whether each frame is (:func:`detectable_frames`). 'servo': the longest
    run of detectable frames (the first of equal ones); 'lost': the frames before it;
    'all': every frame. A part with no frame gives (start, start).
    """
    n = len(detectable)
    if which == 'all':
        return 0, n
    if which not in SEGMENTS:
        raise ValueError(f'segment {which!r}: expected one of {SEGMENTS}')
    best, start = (0, 0), None
    for i, ok in enumerate(list(detectable) + [False]):
        if ok and start is None:
            start = i
        elif not ok and start is not None:
            if i - start > best[1] - best[0]:
                best = (start, i)
            start = None
    return best if which == 'servo' else (0, best[0])


def segment(recording: Recording, which: str,
            detectable: Sequence[bool] | None = None) -> Recording:
    """
    Return part ``which`` of ``recording`` (:data:`SEGMENTS`, :func:`segment_bounds`).

    Its frames, and its joint path from the first of them on; ``detectable`` as
    :func:`detectable_frames` returns it (computed when None). ValueError when the part has
    fewer than MIN_SEGMENT_FRAMES frames.
    """
    if which == 'all':
        return recording
    if detectable is None:
        detectable = detectable_frames(recording)
    start, end = segment_bounds(detectable, which)
    if end - start < MIN_SEGMENT_FRAMES:
        raise ValueError(f'the bag has {end - start} frames of its {which!r} part (fewer than '
                         f'{MIN_SEGMENT_FRAMES}; {int(np.sum(detectable))} of '
                         f'{len(detectable)} frames detectable): record a longer run')
    exposures = recording.exposures_s
    return replace(recording, frames=recording.frames[start:end],
                   exposures_s=None if exposures is None else exposures[start:end],
                   joint_offset_s=recording.joint_offset_s + start / recording.rate_hz
                   if exposures is None else float(exposures[start]),
                   segment=which, first_frame=start)


def process_cpu_s(group: int) -> float:
    """Return the CPU time (user + system, s) of the processes of process group ``group``."""
    total = 0
    for entry in os.listdir('/proc'):
        if not entry.isdigit():
            continue
        try:
            text = Path(f'/proc/{entry}/stat').read_text()
        except OSError:
            continue
        fields = text[text.rindex(')') + 2:].split()  # after 'pid (comm) '
        if int(fields[2]) == group:  # pgrp
            total += int(fields[11]) + int(fields[12])  # utime, stime
    return total / os.sysconf('SC_CLK_TCK')


def latency_stats(sent: dict[int, int], commands: Sequence[tuple[int, int]],
                  since_ns: int) -> dict[str, Any]:
    """
    Return the frame-to-command latency (ms) of the frames sent at or after ``since_ns``.

    ``sent``: frame stamp -> wall time its first image was published (ns); ``commands``:
    (command stamp, frame's exposure) of each /ibvs/frame_latency. The exposure is the
    frame's stamp less the feature node's stamp offset applied, which its estimate moves
    by fractions of a millisecond about the replay's zero (:func:`_node_params`): a command
    is the frame's whose stamp is nearest, within half the frames' spacing. A frame counts
    once, with its first command.
    """
    stamps = np.array(sorted(sent), dtype=np.int64)
    tolerance = int(np.diff(stamps).min()) // 2 if stamps.size > 1 else 0
    first = {}
    for command_ns, exposure_ns in commands:
        i = int(np.searchsorted(stamps, exposure_ns))
        near = [int(stamps[j]) for j in (i - 1, i) if 0 <= j < stamps.size]
        if not near:
            continue
        frame_ns = min(near, key=lambda t: abs(t - exposure_ns))
        if abs(frame_ns - exposure_ns) <= tolerance and sent[frame_ns] >= since_ns:
            first[frame_ns] = min(first.get(frame_ns, command_ns), command_ns)
    delays = np.array([(c - sent[f]) * 1e-6 for f, c in first.items()])
    frames = sum(1 for t in sent.values() if t >= since_ns)
    out = {'frames_sent': frames, 'frames_used': int(delays.size)}
    if delays.size:
        out.update(latency_mean_ms=float(delays.mean()),
                   latency_p95_ms=float(np.percentile(delays, 95)),
                   latency_max_ms=float(delays.max()))
    return out


class Replayer:
    """Publish a :class:`Recording` at the camera's and the driver's rates (docstring)."""

    def __init__(self, node: Any, recording: Recording, joint_rate_hz: float,
                 camera_rate_hz: float, physics_rate_hz: float) -> None:
        """Create the publishers on ``node`` with the graph's QoS."""
        from ibvs_common import contract
        from ibvs_common.conversions import ns_stamp
        from ibvs_model.urdf import JOINT_NAMES
        from sensor_msgs.msg import CameraInfo, Image, JointState

        self.recording = recording
        self.joint_period_ns = round(1e9 / joint_rate_hz)
        self.frame_period_ns = round(1e9 / camera_rate_hz)
        #: The bag's frame period (ns), and how much faster than recorded it plays: each of
        #: its frames in turn at the camera rate (module docstring).
        self.recorded_period_ns = round(1e9 / recording.rate_hz)
        self.speed = camera_rate_hz / recording.rate_hz
        self.step_ns = round(1e9 / physics_rate_hz)
        self.names = list(JOINT_NAMES)
        self.joint_pub = node.create_publisher(JointState, contract.JOINT_STATES,
                                               contract.RELIABLE)
        qos = contract.ZED_IMAGES
        self.camera_pubs = (node.create_publisher(Image, contract.ZED_LEFT_IMAGE, qos),
                            node.create_publisher(Image, contract.ZED_RIGHT_IMAGE, qos),
                            node.create_publisher(CameraInfo, contract.ZED_LEFT_INFO, qos),
                            node.create_publisher(CameraInfo, contract.ZED_RIGHT_INFO, qos))
        self.latched = []
        for topic, msg in recording.latched.items():
            pub = node.create_publisher(type(msg), topic, contract.LATCHED)
            pub.publish(msg)
            self.latched.append(pub)
        #: Frame stamp (ns) -> wall time (ns) its first image was published.
        self.sent = {}
        self._joint_state, self._ns_stamp = JointState, ns_stamp

    def readers(self) -> dict[str, int]:
        """Return the number of subscribers of /joint_states, the left image and its info."""
        return {'joint_states': self.joint_pub.get_subscription_count(),
                'image': self.camera_pubs[0].get_subscription_count(),
                'camera_info': self.camera_pubs[2].get_subscription_count()}

    def run(self, duration_s: float, stop: threading.Event) -> None:
        """Publish for ``duration_s`` of wall time (or until ``stop``), then return."""
        from ibvs_common.timing import frame_stamp_ns

        rec = self.recording
        cycle_ns = len(rec.frames) * self.recorded_period_ns
        joint_ns, frame_ns = self.joint_period_ns, self.frame_period_ns
        # The first frame's stamp is the start: frame k is the bag's frame k, shown with the
        # bag's joint path at k recorded frame periods into it (module docstring).
        frame_n = -(-(time.time_ns() + joint_ns) // frame_ns)
        first_n = frame_n
        start = frame_stamp_ns(frame_n, frame_ns, self.step_ns)
        end = start + int(duration_s * 1e9)
        joint_k = 0
        last = None
        while not stop.is_set():
            next_joint = start + joint_k * joint_ns
            next_frame = frame_stamp_ns(frame_n, frame_ns, self.step_ns)
            due = min(next_joint, next_frame)
            if due >= end:
                break
            wait = (due - time.time_ns()) * 1e-9
            if wait > 0:
                time.sleep(wait)
            if next_joint < next_frame:
                self._joint(next_joint, start, cycle_ns)
                last = next_joint
                joint_k += 1
                continue
            if last != next_frame:  # the arm's sample at the exposure (module docstring)
                self._joint(next_frame, start, cycle_ns)
                last = next_frame
            if next_joint == next_frame:
                joint_k += 1
            parts = rec.frames[(frame_n - first_n) % len(rec.frames)]
            stamp = self._time(next_frame)
            for msg in parts:
                msg.header.stamp = stamp
            self.sent[next_frame] = time.time_ns()
            for pub, msg in zip(self.camera_pubs, parts):
                pub.publish(msg)
            frame_n += 1

    def _time(self, t_ns):
        """Return ``t_ns`` as a builtin_interfaces Time."""
        return self._ns_stamp(t_ns)

    def _joint(self, t_ns, start, cycle_ns):
        """Publish the recorded joint state of ``t_ns - start`` into the cycle, stamped t_ns."""
        rec = self.recording
        into = (round((t_ns - start) * self.speed) % cycle_ns) * 1e-9 + rec.joint_offset_s
        i = max(int(np.searchsorted(rec.joint_t, into, side='right')) - 1, 0)
        msg = self._joint_state(name=self.names, position=[float(v) for v in rec.joint_q[i]],
                                velocity=[float(v) * self.speed for v in rec.joint_qd[i]])
        msg.header.stamp = self._time(t_ns)
        self.joint_pub.publish(msg)


def _node_params(recording: Recording, path: Path, camera_rate_hz: float) -> Path:
    """Write the nodes' parameters: the recorded run's, on the wall clock, at a camera rate."""
    from ibvs_bringup import scenario
    params = {k: v for k, v in recording.params.items() if k not in scenario.RUNNER_ONLY}
    params['use_sim_time'] = False
    params['camera_rate_hz'] = float(camera_rate_hz)
    # The replay stamps each frame at its exposure (a camera triggered by the arm's clock):
    # no stamp offset to start from; the feature node still estimates it, as on a cell.
    params['stamp_offset_initial_s'] = 0.0
    return scenario.write_parameters(params, path)


def replay(bag_path: str | Path | Recording, duration_s: float, out_dir: str | Path,
           progress: Callable[[str], None] = print,
           camera_rate_hz: float | None = None) -> dict[str, Any]:
    """
    Replay a real-cell bag into the nodes alone for ``duration_s`` of wall time; measure.

    ``bag_path``: the bag, or a :class:`Recording` read from one (a :func:`segment` of it);
    ``camera_rate_hz``: the camera rate replayed at (None: the bag's). Returns the
    measurements of the module docstring: latency (ms), frames sent and used, each node's
    CPU and this process's, the images' size, the wall time replayed.
    """
    from ibvs_bringup import domains
    from ibvs_bringup.graph import GRAPH

    from ibvs_bringup.cell_checks import CELL_NODES
    from ibvs_bringup.supervision import NodeProcess, stop_all
    from ibvs_common import contract, dds
    from ibvs_common.conversions import stamp_ns
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import TimeReference

    recording = bag_path if isinstance(bag_path, Recording) else read_recording(bag_path)
    bag_path = recording.bag if isinstance(bag_path, Recording) else bag_path
    out_dir = Path(out_dir)
    log_dir = out_dir / 'logs'
    log_dir.mkdir(parents=True, exist_ok=True)
    camera_rate = float(camera_rate_hz or recording.rate_hz)
    params_file = _node_params(recording, out_dir / 'params.yaml', camera_rate)
    joint_rate = float(recording.params.get('command_rate_hz', 250.0))
    physics_rate = float(recording.params.get('physics_rate_hz', 1000.0))
    with domains.held() as (domain, _):
        dds.configure()
        context = rclpy.context.Context()
        rclpy.init(context=context)
        procs = []
        stop = threading.Event()
        try:
            node = rclpy.create_node('ibvs_nodes_bench', context=context,
                                     parameter_overrides=[])
            commands = []
            node.create_subscription(
                TimeReference, contract.FRAME_LATENCY,
                lambda m: commands.append((stamp_ns(m.header.stamp), stamp_ns(m.time_ref))),
                contract.RELIABLE)
            replayer = Replayer(node, recording, joint_rate, camera_rate, physics_rate)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            for name in CELL_NODES:
                spec = GRAPH.node(name)
                remaps = [arg for topic, remapped in spec.zed_remaps.items()
                          for arg in ('-r', f'{topic}:={remapped}')]
                procs.append(NodeProcess(spec.package, name, params_file, log_dir, remaps))
            progress(f'  nodes alone: ROS_DOMAIN_ID {domain}, {", ".join(CELL_NODES)} started, '
                     f'replaying {bag_path} (part {recording.segment!r}: '
                     f'{len(recording.frames)} frames from frame {recording.first_frame}, '
                     f'{recording.size[0]} x {recording.size[1]}, at {camera_rate:g} Hz)')
            deadline = time.monotonic() + START_TIMEOUT_S
            wanted = {'joint_states': len(CELL_NODES), 'image': 1, 'camera_info': 2}
            while any(replayer.readers()[k] < n for k, n in wanted.items()):
                executor.spin_once(timeout_sec=0.05)
                dead = [p.name for p in procs if p.poll() is not None]
                if dead or time.monotonic() > deadline:
                    raise RuntimeError(f'the nodes did not start: {dead or replayer.readers()}'
                                       f' (logs in {log_dir})')
            thread = threading.Thread(target=replayer.run, args=(duration_s, stop))
            thread.start()
            cpu, since, began = None, None, time.monotonic()
            while thread.is_alive():
                executor.spin_once(timeout_sec=0.01)
                if since is None and commands:  # the graph is up (WARMUP_S)
                    started_s = time.monotonic() - began
                    since = time.time_ns() + int(WARMUP_S * 1e9)
                if cpu is None and since is not None and time.time_ns() >= since:
                    cpu = ({p.name: process_cpu_s(p.proc.pid) for p in procs},
                           time.process_time(), time.monotonic())
            end = time.monotonic()
            after = ({p.name: process_cpu_s(p.proc.pid) for p in procs}, time.process_time())
            settle = time.monotonic() + 0.5  # the last frames' commands
            while time.monotonic() < settle:
                executor.spin_once(timeout_sec=0.01)
        finally:
            stop.set()
            codes = stop_all(procs) if procs else {}
            context.try_shutdown()
    if cpu is None:
        raise ValueError(f'replay of {duration_s} s: ' + (
            f'no joint command used a frame (logs in {log_dir})' if since is None else
            f'it ended within {WARMUP_S} s of the first command ({started_s:.1f} s in)'))
    window_s = end - cpu[2]
    result = latency_stats(replayer.sent, commands, since)
    frames = max(result['frames_sent'], 1)
    result['cpu'] = {name: {'cpu_s': after[0][name] - cpu[0][name],
                            'cores': (after[0][name] - cpu[0][name]) / window_s,
                            'ms_per_frame': (after[0][name] - cpu[0][name]) / frames * 1e3}
                     for name in CELL_NODES}
    result['cpu']['replayer (this process)'] = {
        'cpu_s': after[1] - cpu[1], 'cores': (after[1] - cpu[1]) / window_s,
        'ms_per_frame': (after[1] - cpu[1]) / frames * 1e3}
    result.update(width=recording.size[0], height=recording.size[1], replay_s=duration_s,
                  measured_s=window_s, warmup_s=WARMUP_S, first_command_s=started_s,
                  bag=str(bag_path), camera_rate_hz=camera_rate, segment=recording.segment,
                  segment_frames=len(recording.frames), first_frame=recording.first_frame,
                  exit_codes=codes, load_average=f'{os.getloadavg()[0]:.2f}')
    return result


def frame_split(recording: Recording, camera_rate_hz: float | None = None,
                frames: int = 120) -> dict[str, float]:
    """
    Return where the feature node's CPU goes a frame (ms), fed ``recording`` in this process.

    A feature node of the recording's parameters (on the wall clock, as :func:`replay`
    gives them) is built in this process and its callbacks are called with the messages
    the replay would publish (the joint states at the command rate, each frame with a
    joint state of its stamp, ``frames`` frames at ``camera_rate_hz`` after as many again
    to start), each message deserialised from its bytes first as rclpy does for a
    subscription. Timed on this thread (CPU time): the deserialisation, the detection by
    its stages (:attr:`ibvs_vision.detector.StereoDetector.timings`, their wall time, and
    the rest of it) and the node's own handling of the messages (everything else its
    callbacks do: reading, pairing, the model's estimate, the stamp offset, publishing).
    What it leaves out: DDS's own threads and the executor. This process's malloc keeps
    the memory it frees, as a node's does (:func:`ibvs_common.process.keep_freed_memory`).
    """
    import rclpy
    from rclpy.parameter import Parameter
    from rclpy.serialization import deserialize_message, serialize_message
    from ibvs_bringup import domains, scenario
    from ibvs_common import contract, process
    from ibvs_common.conversions import ns_stamp
    from ibvs_model.urdf import JOINT_NAMES
    from ibvs_vision.feature_node import FeatureNode, PARAMS
    from sensor_msgs.msg import CameraInfo, Image, JointState

    process.keep_freed_memory()
    rate = float(camera_rate_hz or recording.rate_hz)
    params = {k: v for k, v in recording.params.items() if k not in scenario.RUNNER_ONLY}
    params.update(use_sim_time=False, camera_rate_hz=rate, stamp_offset_initial_s=0.0)
    names = {p.name for p in PARAMS} | {'use_sim_time'}
    frame_ns, joint_ns = round(1e9 / rate), round(1e9 / float(params.get(
        'command_rate_hz', 250.0)))
    recorded_ns = round(1e9 / recording.rate_hz)
    cycle_ns = len(recording.frames) * recorded_ns
    total = 2 * frames
    start = (time.time_ns() - int((total / rate + 2.0) * 1e9)) // 1_000_000 * 1_000_000
    times = {'deserialise': 0.0, 'callbacks': 0.0, 'detection (CPU)': 0.0}

    def joint_bytes(t_ns):
        into = ((t_ns - start) % cycle_ns) * 1e-9 + recording.joint_offset_s
        i = max(int(np.searchsorted(recording.joint_t, into, side='right')) - 1, 0)
        msg = JointState(name=list(JOINT_NAMES),
                         position=[float(v) for v in recording.joint_q[i]],
                         velocity=[float(v) for v in recording.joint_qd[i]])
        msg.header.stamp = ns_stamp(t_ns)
        return serialize_message(msg)

    def take(data, kind):
        c = time.thread_time()
        msg = deserialize_message(data, kind)
        times['deserialise'] += time.thread_time() - c
        return msg

    def call(callback, *args):
        c = time.thread_time()
        callback(*args)
        times['callbacks'] += time.thread_time() - c

    with domains.held():
        context = rclpy.context.Context()
        rclpy.init(context=context)
        try:
            node = FeatureNode(context=context, parameter_overrides=[
                Parameter(k, value=v) for k, v in params.items() if k in names])
            for topic, msg in recording.latched.items():
                if topic == contract.STEREO_POSE:
                    node.camera_input.on_pose(msg)
                elif topic in (contract.TEACH_LEFT_IMAGE, contract.TEACH_RIGHT_IMAGE):
                    side = 'left' if topic == contract.TEACH_LEFT_IMAGE else 'right'
                    node._on_teach(side, msg)
            for side, info in zip(('left', 'right'), recording.frames[0][2:4]):
                node.camera_input.on_info(side, info)  # the camera model, the detector
            detect = node._detector.detect

            def timed_detect(*args, **kwargs):
                c = time.thread_time()
                try:
                    return detect(*args, **kwargs)
                finally:
                    times['detection (CPU)'] += time.thread_time() - c
            node._detector.detect = timed_detect
            joint_t = start
            for n in range(total):
                if n == frames:  # started: from here on, measured
                    times = dict.fromkeys(times, 0.0)
                    node._detector.timings = {}
                t_ns = start + n * frame_ns // 1_000_000 * 1_000_000
                while joint_t < t_ns:
                    call(node._on_joints, take(joint_bytes(joint_t), JointState))
                    joint_t += joint_ns
                call(node._on_joints, take(joint_bytes(t_ns), JointState))
                parts = recording.frames[(n * frame_ns // recorded_ns) % len(recording.frames)]
                stamp = ns_stamp(t_ns)
                for msg in parts:
                    msg.header.stamp = stamp
                data = [serialize_message(m) for m in parts]
                left, right = take(data[0], Image), take(data[1], Image)
                infos = take(data[2], CameraInfo), take(data[3], CameraInfo)
                call(node._on_image, 'left', left)
                call(node._on_image, 'right', right)
                call(node.camera_input.on_info, 'left', infos[0])
                call(node.camera_input.on_info, 'right', infos[1])
            stages = node._detector.timings
            measured = node._diag.values.get('frames_measured', 0)
            node.destroy_node()
        finally:
            context.try_shutdown()
    out = {'deserialisation (rclpy: 2 images, 2 camera_info, the joint states)':
           times['deserialise'] / frames * 1e3}
    staged = 0.0
    for stage, seconds in sorted(stages.items()):
        out[f'detection: {stage}'] = seconds / frames * 1e3
        staged += seconds
    out['detection: the rest'] = max(times['detection (CPU)'] - staged, 0.0) / frames * 1e3
    out['message handling (the callbacks less the detection)'] = \
        (times['callbacks'] - times['detection (CPU)']) / frames * 1e3
    out['total'] = (times['deserialise'] + times['callbacks']) / frames * 1e3
    out['frames'] = frames
    out['frames measured (of all)'] = measured
    return out


def frame_split_apart(bag: str | Path, which: str, camera_rate_hz: float | None,
                      detectable: Sequence[bool] | None, frames: int = 120
                      ) -> dict[str, float]:
    """
    Return :func:`frame_split` of part ``which`` of ``bag``, measured in a process of its own.

    A feature node in the replaying process would share its executor's and its threads'
    time and memory with the stand-in camera, and the replay after it would not be the one
    measured; a process of its own (``python -m ibvs_experiments.nodes_bench split``) is
    as the node's is. ``detectable``: :func:`detectable_frames` of the bag (None for
    'all').
    """
    import json
    import subprocess
    import sys

    marks = ''.join('1' if ok else '0' for ok in detectable) if detectable is not None else ''
    done = subprocess.run(
        [sys.executable, '-m', 'ibvs_experiments.nodes_bench', 'split', str(bag), which,
         str(camera_rate_hz or 0.0), str(frames), marks or '-'],
        capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: Sequence[str] | None = None) -> int:
    """``split BAG PART RATE FRAMES DETECTABLE``: print :func:`frame_split` as JSON."""
    import json
    import sys

    args = list(sys.argv[1:] if argv is None else argv)
    if len(args) != 6 or args[0] != 'split':
        print('usage: python -m ibvs_experiments.nodes_bench split BAG PART RATE FRAMES '
              "DETECTABLE (one 0 or 1 a frame, '-' for none)", file=sys.stderr)
        return 2
    _, bag, which, rate, frames, marks = args
    recording = read_recording(bag)
    detectable = None if marks == '-' else [c == '1' for c in marks]
    part = segment(recording, which, detectable)
    print(json.dumps(frame_split(part, float(rate) or None, int(frames))))
    return 0


def print_split(split: dict[str, float], title: str) -> None:
    """Print :func:`frame_split`'s numbers."""
    print(title)
    for name, value in split.items():
        if name.startswith('frames'):
            continue
        print(f'  {name:62s} {value:7.2f} ms a frame')
    print(f'  ({split["frames"]} frames; {split["frames measured (of all)"]} measured of all '
          'it was fed)')


def record(resolution: str, duration_s: float, out_dir: str | Path,
           progress: Callable[[str], None] = print) -> Path:
    """Record a real-cell run at ``resolution`` with its images; return its bag's path."""
    from . import runner
    result = runner.run_scenario('real_cell', out_dir, overrides={'resolution': resolution},
                                 duration_s=duration_s, record_images=True, figures=False,
                                 progress=progress)
    return Path(result.bag_path)


def measure(resolution: str, out_dir: str | Path, replay_s: float, record_s: float,
            progress: Callable[[str], None] = print,
            rates_hz: Sequence[float | None] = (None,),
            segments: Sequence[str] = ('all',), split: bool = False) -> list[dict[str, Any]]:
    """
    Record (or reuse) a real-cell bag at ``resolution``, replay it, print the numbers.

    Each of ``segments`` (:data:`SEGMENTS`) is replayed at each of ``rates_hz`` (None: the
    bag's rate), ``replay_s`` each; a segment the bag has too little of is reported and
    skipped. With ``split``, where the feature node's CPU goes a frame (:func:`frame_split`)
    is measured first, in this process. Returns one result a replay (:func:`replay`, with
    the resolution, and ``split``).
    """
    out_dir = Path(out_dir) / resolution
    bag = out_dir / 'bag'
    if (bag / 'metadata.yaml').exists():
        progress(f'nodes alone at {resolution}: the bag {bag} again')
    else:
        progress(f'nodes alone at {resolution}: recording {record_s:g} s of ibvs run '
                 f'real_cell with images')
        bag = record(resolution, record_s, out_dir, progress=lambda line: None)
    recording = read_recording(bag)
    detectable = None
    if set(segments) - {'all'}:
        detectable = _DETECTABLE.get(str(bag))
        if detectable is None:
            detectable = _DETECTABLE[str(bag)] = detectable_frames(recording)
    if detectable is not None:
        servo = segment_bounds(detectable, 'servo')
        progress(f'  {int(detectable.sum())} of {len(detectable)} frames detectable; the '
                 f'servo part: frames {servo[0]}-{servo[1] - 1}, the lost part: the '
                 f'{servo[0]} before it')
    results = []
    for which in segments:
        try:
            part = segment(recording, which, detectable)
        except ValueError as exc:
            progress(f'nodes alone at {resolution}, part {which!r}: not measured: {exc}')
            continue
        for rate in rates_hz:
            name = f'{which}_{rate or recording.rate_hz:g}hz'
            parts = None
            if split:
                parts = frame_split_apart(bag, which, rate, detectable)
                print_split(parts, f'the feature node a frame, in this process, at '
                            f'{resolution}, part {which!r} at {rate or recording.rate_hz:g} '
                            'Hz (CPU of this thread):')
            result = replay(part, replay_s, out_dir / 'replay' / name, progress,
                            camera_rate_hz=rate)
            result['resolution'] = resolution
            result['split'] = parts
            print_result(result)
            results.append(result)
    return results


def print_result(result: dict[str, Any]) -> None:
    """Print one replay's latency and CPU lines."""
    rate = result.get('camera_rate_hz', 30.0)
    period_ms = 1e3 / rate
    head = (f'nodes alone at {result["resolution"]} ({result["width"]} x {result["height"]}), '
            f'part {result.get("segment", "all")!r} ({result.get("segment_frames", "?")} '
            f'frames), {rate:g} Hz for {result["measured_s"]:.1f} s, from '
            f'{result["warmup_s"]:g} s after the first command '
            f'({result["first_command_s"]:.1f} s into the replay), '
            f'load average {result["load_average"]}:')
    print(head)
    if result['frames_used']:
        print(f'  frame to command latency: mean {result["latency_mean_ms"]:.1f} ms, '
              f'p95 {result["latency_p95_ms"]:.1f} ms, max {result["latency_max_ms"]:.1f} ms '
              f'(one frame period: {period_ms:.1f} ms); {result["frames_used"]} of '
              f'{result["frames_sent"]} frames used')
    else:
        print(f'  no frame reached a command ({result["frames_sent"]} sent)')
    for name, cpu in result['cpu'].items():
        print(f'  CPU {name:34s} {cpu["cores"]:6.3f} cores   {cpu["ms_per_frame"]:7.2f} ms '
              'per frame')


if __name__ == '__main__':
    raise SystemExit(main())
