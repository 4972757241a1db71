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
ibvs_experiments.nodes_bench split``). The recording and its parts are
:mod:`ibvs_analysis.recording`'s, the split :mod:`.nodes_split`'s.
"""

from collections.abc import Callable, Sequence
from dataclasses import dataclass
import os
from pathlib import Path
import threading
import time
from typing import Any

# The recording and its parts (step 1, 2a), and the split: this module's names too.
from ibvs_analysis.recording import (detectable_frames, MIN_SEGMENT_FRAMES,  # noqa: F401
                                     read_recording, Recording, segment, segment_bounds,
                                     SEGMENTS)
import numpy as np

from .nodes_split import frame_split, frame_split_apart, print_split

#: Measurement starts this long (wall s) after the first joint command that used a frame:
#: the graph's start (the feedforward's trajectory, 60 s of it at 1 kHz, which the joint
#: controller waits for; the detector's first full search) is not a frame's latency.
WARMUP_S = 1.0
#: How long the nodes may take to subscribe (wall s) before the replay gives up.
START_TIMEOUT_S = 60.0
#: detectable_frames of each bag measured in this process, by its path.
_DETECTABLE = {}


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


def _bench_node(context: Any) -> tuple[Any, list[tuple[int, int]]]:
    """Return this process's node and the (command stamp, exposure) of each frame latency."""
    from ibvs_common import contract
    from ibvs_common.conversions import stamp_ns
    import rclpy
    from sensor_msgs.msg import TimeReference

    node = rclpy.create_node('ibvs_nodes_bench', context=context, parameter_overrides=[])
    commands = []
    node.create_subscription(
        TimeReference, contract.FRAME_LATENCY,
        lambda m: commands.append((stamp_ns(m.header.stamp), stamp_ns(m.time_ref))),
        contract.RELIABLE)
    return node, commands


def _start_nodes(procs: list, params_file: Path, log_dir: Path) -> None:
    """Start each of the cell's nodes, a process of its own, into ``procs``."""
    from ibvs_bringup.cell_checks import CELL_NODES
    from ibvs_bringup.graph import GRAPH
    from ibvs_bringup.supervision import NodeProcess

    for name in CELL_NODES:
        spec = GRAPH.node(name)
        remaps = [arg for topic, remapped in spec.zed_remaps.items()
                  for arg in ('-r', f'{topic}:={remapped}')]
        procs.append(NodeProcess(spec.package, name, params_file, log_dir, remaps))


def _wait_for_nodes(executor: Any, replayer: Replayer, procs: Sequence[Any],
                    log_dir: Path) -> None:
    """Spin until the nodes subscribe to the replay; RuntimeError if one ends or it is late."""
    from ibvs_bringup.cell_checks import CELL_NODES

    deadline = time.monotonic() + START_TIMEOUT_S
    wanted = {'joint_states': len(CELL_NODES), 'image': 1, 'camera_info': 2}
    while any(replayer.readers()[k] < n for k, n in wanted.items()):
        executor.spin_once(timeout_sec=0.05)
        dead = [p.name for p in procs if p.poll() is not None]
        if dead or time.monotonic() > deadline:
            raise RuntimeError(f'the nodes did not start: {dead or replayer.readers()}'
                               f' (logs in {log_dir})')


def _cpu_now(procs: Sequence[Any]) -> tuple[dict[str, float], float]:
    """Return each node's CPU time (s, by name) and this process's."""
    return {p.name: process_cpu_s(p.proc.pid) for p in procs}, time.process_time()


@dataclass
class _Window:
    """What :func:`_spin_replay` measured: the window from WARMUP_S after the first command."""

    #: :func:`_cpu_now` at the window's start, and its wall time (monotonic s); None when
    #: the window never started.
    cpu: tuple | None
    #: The window's start (wall clock, ns), None when no command came.
    since_ns: int | None
    #: When the first command came (s into the replay), None when none came.
    started_s: float | None
    #: The replay's end (monotonic s), and :func:`_cpu_now` at it.
    end: float
    after: tuple


def _spin_replay(executor: Any, replayer: Replayer, procs: Sequence[Any],
                 commands: list, duration_s: float, stop: threading.Event) -> _Window:
    """Run the replay for ``duration_s`` on a thread of its own, spinning; measure its CPU."""
    thread = threading.Thread(target=replayer.run, args=(duration_s, stop))
    thread.start()
    cpu, since, began, started_s = None, None, time.monotonic(), None
    while thread.is_alive():
        executor.spin_once(timeout_sec=0.01)
        if since is None and commands:  # the graph is up (WARMUP_S)
            started_s = time.monotonic() - began
            since = time.time_ns() + int(WARMUP_S * 1e9)
        if cpu is None and since is not None and time.time_ns() >= since:
            cpu = _cpu_now(procs) + (time.monotonic(),)
    end = time.monotonic()
    after = _cpu_now(procs)
    settle = time.monotonic() + 0.5  # the last frames' commands
    while time.monotonic() < settle:
        executor.spin_once(timeout_sec=0.01)
    return _Window(cpu, since, started_s, end, after)


def _replay_numbers(window: _Window, sent: dict[int, int], commands: list,
                    duration_s: float, log_dir: Path) -> dict[str, Any]:
    """Return the latency and each process's CPU of a replay's window (:func:`replay`)."""
    from ibvs_bringup.cell_checks import CELL_NODES

    cpu, after, since = window.cpu, window.after, window.since_ns
    if cpu is None:
        started_s = window.started_s
        raise ValueError(f'replay of {duration_s} s: ' + (
            f'no joint command used a frame (logs in {log_dir})' if since is None else
            f'it ended within {WARMUP_S} s of the first command ({started_s:.1f} s in)'))
    window_s = window.end - cpu[2]
    result = latency_stats(sent, commands, since)
    frames = max(result['frames_sent'], 1)
    result['cpu'] = {name: {'cpu_s': after[0][name] - cpu[0][name],
                            'cores': (after[0][name] - cpu[0][name]) / window_s,
                            'ms_per_frame': (after[0][name] - cpu[0][name]) / frames * 1e3}
                     for name in CELL_NODES}
    result['cpu']['replayer (this process)'] = {
        'cpu_s': after[1] - cpu[1], 'cores': (after[1] - cpu[1]) / window_s,
        'ms_per_frame': (after[1] - cpu[1]) / frames * 1e3}
    return result


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
    from ibvs_bringup.cell_checks import CELL_NODES
    from ibvs_bringup.supervision import stop_all
    from ibvs_common import dds
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

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
            node, commands = _bench_node(context)
            replayer = Replayer(node, recording, joint_rate, camera_rate, physics_rate)
            executor = SingleThreadedExecutor(context=context)
            executor.add_node(node)
            _start_nodes(procs, params_file, log_dir)
            progress(f'  nodes alone: ROS_DOMAIN_ID {domain}, {", ".join(CELL_NODES)} started, '
                     f'replaying {bag_path} (part {recording.segment!r}: '
                     f'{len(recording.frames)} frames from frame {recording.first_frame}, '
                     f'{recording.size[0]} x {recording.size[1]}, at {camera_rate:g} Hz)')
            _wait_for_nodes(executor, replayer, procs, log_dir)
            window = _spin_replay(executor, replayer, procs, commands, duration_s, stop)
        finally:
            stop.set()
            codes = stop_all(procs) if procs else {}
            context.try_shutdown()
    result = _replay_numbers(window, replayer.sent, commands, duration_s, log_dir)
    result.update(width=recording.size[0], height=recording.size[1], replay_s=duration_s,
                  measured_s=window.end - window.cpu[2], warmup_s=WARMUP_S,
                  first_command_s=window.started_s, bag=str(bag_path),
                  camera_rate_hz=camera_rate, segment=recording.segment,
                  segment_frames=len(recording.frames), first_frame=recording.first_frame,
                  exit_codes=codes, load_average=f'{os.getloadavg()[0]:.2f}')
    return result


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
