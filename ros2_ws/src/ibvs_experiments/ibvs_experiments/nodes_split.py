"""
Where the feature node's CPU goes a frame, for the nodes-alone bench (:mod:`.nodes_bench`).

:func:`frame_split` builds a feature node in this process and feeds its callbacks the
messages the replay would publish, each deserialised from its bytes first as rclpy does,
timing on this thread rclpy's deserialisation, the detector's stages and the node's own
handling of the messages. :func:`frame_split_apart` measures it in a process of its own
(``python -m ibvs_experiments.nodes_bench split``), as the node's is; :func:`print_split`
prints its numbers.
"""

from collections.abc import Sequence
from pathlib import Path
import time
from typing import Any

from ibvs_analysis.recording import Recording
import numpy as np


def _split_params(recording: Recording, rate: float) -> dict[str, Any]:
    """Return the feature node's parameters: the recorded run's, as :func:`.replay` gives."""
    from ibvs_bringup import scenario
    params = {k: v for k, v in recording.params.items() if k not in scenario.RUNNER_ONLY}
    params.update(use_sim_time=False, camera_rate_hz=rate, stamp_offset_initial_s=0.0)
    return params


def _feature_node(context: Any, recording: Recording, params: dict[str, Any]) -> Any:
    """Return a feature node of ``params`` in ``context``, given the latched messages."""
    from rclpy.parameter import Parameter
    from ibvs_common import contract
    from ibvs_vision.feature_node import FeatureNode, PARAMS

    names = {p.name for p in PARAMS} | {'use_sim_time'}
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
    return node


class _FrameFeeder:
    """Feed a feature node the replay's messages as bytes, timing them (:func:`frame_split`)."""

    def __init__(self, recording: Recording, rate: float, joint_rate_hz: float,
                 frames: int) -> None:
        """Start ``2 * frames`` frames at ``rate`` back on the wall clock's 1 ms grid."""
        from rclpy.serialization import deserialize_message, serialize_message
        from ibvs_common.conversions import ns_stamp
        from ibvs_model.urdf import JOINT_NAMES
        from sensor_msgs.msg import CameraInfo, Image, JointState

        self.recording = recording
        self.frame_ns, self.joint_ns = round(1e9 / rate), round(1e9 / joint_rate_hz)
        self.recorded_ns = round(1e9 / recording.rate_hz)
        self.cycle_ns = len(recording.frames) * self.recorded_ns
        total = 2 * frames
        self.start = (time.time_ns() - int((total / rate + 2.0) * 1e9)) // 1_000_000 \
            * 1_000_000
        #: The next joint state's stamp (ns).
        self.joint_t = self.start
        #: CPU time (s) of this thread: deserialising, in the callbacks, detecting.
        self.times = {'deserialise': 0.0, 'callbacks': 0.0, 'detection (CPU)': 0.0}
        self._names = list(JOINT_NAMES)
        self._deserialize, self._serialize = deserialize_message, serialize_message
        self._ns_stamp = ns_stamp
        self._camera_info, self._image, self._joint_state = CameraInfo, Image, JointState

    def joint_bytes(self, t_ns: int) -> bytes:
        """Return the recorded joint state of ``t_ns`` into the cycle, serialised."""
        rec = self.recording
        into = ((t_ns - self.start) % self.cycle_ns) * 1e-9 + rec.joint_offset_s
        i = max(int(np.searchsorted(rec.joint_t, into, side='right')) - 1, 0)
        msg = self._joint_state(name=list(self._names),
                                position=[float(v) for v in rec.joint_q[i]],
                                velocity=[float(v) for v in rec.joint_qd[i]])
        msg.header.stamp = self._ns_stamp(t_ns)
        return self._serialize(msg)

    def take(self, data: bytes, kind: type) -> Any:
        """Return ``data`` deserialised as a ``kind``, timed."""
        c = time.thread_time()
        msg = self._deserialize(data, kind)
        self.times['deserialise'] += time.thread_time() - c
        return msg

    def call(self, callback: Any, *args: Any) -> None:
        """Call ``callback``, timed."""
        c = time.thread_time()
        callback(*args)
        self.times['callbacks'] += time.thread_time() - c

    def time_detection(self, node: Any) -> None:
        """Time each of the node's detections (its detector's ``detect``)."""
        detect = node._detector.detect

        def timed_detect(*args, **kwargs):
            c = time.thread_time()
            try:
                return detect(*args, **kwargs)
            finally:
                self.times['detection (CPU)'] += time.thread_time() - c
        node._detector.detect = timed_detect

    def restart(self, node: Any) -> None:
        """Measure from here on: the times and the detector's stage timings back to zero."""
        self.times = dict.fromkeys(self.times, 0.0)
        node._detector.timings = {}

    def feed(self, node: Any, n: int) -> None:
        """Feed frame ``n``: the joint states up to its stamp, one of its stamp, the frame."""
        t_ns = self.start + n * self.frame_ns // 1_000_000 * 1_000_000
        while self.joint_t < t_ns:
            self.call(node._on_joints, self.take(self.joint_bytes(self.joint_t),
                                                 self._joint_state))
            self.joint_t += self.joint_ns
        self.call(node._on_joints, self.take(self.joint_bytes(t_ns), self._joint_state))
        frames = self.recording.frames
        parts = frames[(n * self.frame_ns // self.recorded_ns) % len(frames)]
        stamp = self._ns_stamp(t_ns)
        for msg in parts:
            msg.header.stamp = stamp
        data = [self._serialize(m) for m in parts]
        left, right = self.take(data[0], self._image), self.take(data[1], self._image)
        infos = self.take(data[2], self._camera_info), self.take(data[3], self._camera_info)
        self.call(node._on_image, 'left', left)
        self.call(node._on_image, 'right', right)
        self.call(node.camera_input.on_info, 'left', infos[0])
        self.call(node.camera_input.on_info, 'right', infos[1])


def _split_numbers(times: dict[str, float], stages: dict[str, float], frames: int,
                   measured: int) -> dict[str, float]:
    """Return :func:`frame_split`'s numbers (ms a frame) from the CPU times measured (s)."""
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


def frame_split(recording: Recording, camera_rate_hz: float | None = None,
                frames: int = 120) -> dict[str, float]:
    """
    Return where the feature node's CPU goes a frame (ms), fed ``recording`` in this process.

    A feature node of the recording's parameters (on the wall clock, as :func:`.replay`
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
    from ibvs_bringup import domains
    from ibvs_common import process

    process.keep_freed_memory()
    rate = float(camera_rate_hz or recording.rate_hz)
    params = _split_params(recording, rate)
    feeder = _FrameFeeder(recording, rate, float(params.get('command_rate_hz', 250.0)),
                          frames)
    with domains.held():
        context = rclpy.context.Context()
        rclpy.init(context=context)
        try:
            node = _feature_node(context, recording, params)
            feeder.time_detection(node)
            for n in range(2 * frames):
                if n == frames:  # started: from here on, measured
                    feeder.restart(node)
                feeder.feed(node, n)
            stages = node._detector.timings
            measured = node._diag.values.get('frames_measured', 0)
            node.destroy_node()
        finally:
            context.try_shutdown()
    return _split_numbers(feeder.times, stages, frames, measured)


def frame_split_apart(bag: str | Path, which: str, camera_rate_hz: float | None,
                      detectable: Sequence[bool] | None, frames: int = 120
                      ) -> dict[str, float]:
    """
    Return :func:`frame_split` of part ``which`` of ``bag``, measured in a process of its own.

    A feature node in the replaying process would share its executor's and its threads'
    time and memory with the stand-in camera, and the replay after it would not be the one
    measured; a process of its own (``python -m ibvs_experiments.nodes_bench split``) is
    as the node's is. ``detectable``: :func:`.detectable_frames` of the bag (None for
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


def print_split(split: dict[str, float], title: str) -> None:
    """Print :func:`frame_split`'s numbers."""
    print(title)
    for name, value in split.items():
        if name.startswith('frames'):
            continue
        print(f'  {name:62s} {value:7.2f} ms a frame')
    print(f'  ({split["frames"]} frames; {split["frames measured (of all)"]} measured of all '
          'it was fed)')
