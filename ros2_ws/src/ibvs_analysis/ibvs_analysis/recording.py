"""
A recorded run's frames and joint path, read from its bag for a replay, and its parts.

:func:`read_recording` reads a bag recorded with its images into a :class:`Recording` (the
serialised frames, the joint path, the latched messages, the run's parameters; step 1 of
:mod:`ibvs_experiments.nodes_bench`, the nodes-alone bench). :func:`detectable_frames`
classifies each frame by the detector itself, and :func:`segment_bounds` and
:func:`segment` take a part of the run from it (step 2a): 'servo' the longest run of
detectable frames, 'lost' the frames before it, 'all' the whole bag.
"""

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

#: The parts of a recording that can be replayed (the module docstring).
SEGMENTS = ('servo', 'lost', 'all')
#: The fewest frames a segment replays: less is not a part of the run worth a measurement.
MIN_SEGMENT_FRAMES = 15


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
    """Read a real-cell bag recorded with its images (the nodes-alone bench's step 1)."""
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
    Return the frames [start, end) of part ``which`` of a run (the module docstring).

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
