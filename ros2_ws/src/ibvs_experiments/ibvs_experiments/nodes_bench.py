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
   images are published once, latched.
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
in a process of its own costs too.
"""

from collections.abc import Callable, Sequence
from dataclasses import dataclass
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


def read_recording(bag_path: str | Path) -> Recording:
    """Read a real-cell bag recorded with its images (module docstring, step 1)."""
    from geometry_msgs.msg import PoseStamped
    from ibvs_common import contract
    from ibvs_common.conversions import stamp_ns
    from rclpy.serialization import deserialize_message
    from rosbags.highlevel import AnyReader
    from sensor_msgs.msg import CameraInfo, Image
    import yaml

    from . import analysis

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
    frames = [tuple(parts[t] for t in camera) for _, parts in sorted(by_stamp.items())
              if len(parts) == len(camera)]
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
    return Recording(frames, joint_t - joint_t[0], joint_q, joint_qd, latched, params, size)


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
    (command stamp, frame stamp) of each /ibvs/frame_latency. A frame counts once, with its
    first command.
    """
    first = {}
    for command_ns, frame_ns in commands:
        if frame_ns in sent and sent[frame_ns] >= since_ns:
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
        cycle_ns = len(rec.frames) * self.frame_period_ns
        joint_ns, frame_ns = self.joint_period_ns, self.frame_period_ns
        start = (time.time_ns() // joint_ns + 1) * joint_ns
        end = start + int(duration_s * 1e9)
        joint_k, frame_n = 0, -(-start // frame_ns)
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
            if next_joint <= next_frame:
                self._joint(next_joint, start, cycle_ns)
                last = next_joint
                joint_k += 1
                continue
            if last != next_frame:  # the arm's sample at the exposure (module docstring)
                self._joint(next_frame, start, cycle_ns)
                last = next_frame
            parts = rec.frames[(frame_n - start // frame_ns) % len(rec.frames)]
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
        into = ((t_ns - start) % cycle_ns) * 1e-9
        i = max(int(np.searchsorted(rec.joint_t, into, side='right')) - 1, 0)
        msg = self._joint_state(name=self.names, position=[float(v) for v in rec.joint_q[i]],
                                velocity=[float(v) for v in rec.joint_qd[i]])
        msg.header.stamp = self._time(t_ns)
        self.joint_pub.publish(msg)


def _node_params(recording: Recording, path: Path) -> Path:
    """Write the nodes' parameters: the recorded run's, on the wall clock."""
    from ibvs_bringup import scenario
    params = {k: v for k, v in recording.params.items() if k not in scenario.RUNNER_ONLY}
    params['use_sim_time'] = False
    return scenario.write_parameters(params, path)


def replay(bag_path: str | Path, duration_s: float, out_dir: str | Path,
           progress: Callable[[str], None] = print) -> dict[str, Any]:
    """
    Replay a real-cell bag into the nodes alone for ``duration_s`` of wall time; measure.

    Returns the measurements of the module docstring: latency (ms), frames sent and used,
    each node's CPU and this process's, the images' size, the wall time replayed.
    """
    from ibvs_bringup import domains
    from ibvs_bringup.graph import GRAPH

    from .cell import CELL_NODES
    from ibvs_bringup.supervision import NodeProcess, stop_all
    from ibvs_common import contract, dds
    from ibvs_common.conversions import stamp_ns
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import TimeReference

    recording = read_recording(bag_path)
    out_dir = Path(out_dir)
    log_dir = out_dir / 'logs'
    log_dir.mkdir(parents=True, exist_ok=True)
    params_file = _node_params(recording, out_dir / 'params.yaml')
    joint_rate = float(recording.params.get('command_rate_hz', 250.0))
    camera_rate = float(recording.params.get('camera_rate_hz', 30.0))
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
                     f'replaying {bag_path} ({len(recording.frames)} frames, '
                     f'{recording.size[0]} x {recording.size[1]})')
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
                  bag=str(bag_path),
                  exit_codes=codes, load_average=f'{os.getloadavg()[0]:.2f}')
    return result


def record(resolution: str, duration_s: float, out_dir: str | Path,
           progress: Callable[[str], None] = print) -> Path:
    """Record a real-cell run at ``resolution`` with its images; return its bag's path."""
    from . import runner
    result = runner.run_scenario('real_cell', out_dir, overrides={'resolution': resolution},
                                 duration_s=duration_s, record_images=True, figures=False,
                                 progress=progress)
    return Path(result.bag_path)


def measure(resolution: str, out_dir: str | Path, replay_s: float, record_s: float,
            progress: Callable[[str], None] = print) -> dict[str, Any]:
    """Record (or reuse) a real-cell bag at ``resolution``, replay it, print the numbers."""
    out_dir = Path(out_dir) / resolution
    bag = out_dir / 'bag'
    if (bag / 'metadata.yaml').exists():
        progress(f'nodes alone at {resolution}: the bag {bag} again')
    else:
        progress(f'nodes alone at {resolution}: recording {record_s:g} s of ibvs run '
                 f'real_cell with images')
        bag = record(resolution, record_s, out_dir, progress=lambda line: None)
    result = replay(bag, replay_s, out_dir / 'replay', progress)
    result['resolution'] = resolution
    print_result(result)
    return result


def print_result(result: dict[str, Any]) -> None:
    """Print one replay's latency and CPU lines."""
    period_ms = 1e3 / 30.0
    head = (f'nodes alone at {result["resolution"]} ({result["width"]} x {result["height"]}), '
            f'30 Hz for {result["measured_s"]:.1f} s, from {result["warmup_s"]:g} s after the '
            f'first command ({result["first_command_s"]:.1f} s into the replay), '
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
