"""
A run's bag read back: its time series (:class:`RunData`) and its metrics.

:func:`load_run` reads a rosbag2 (MCAP) recording with ``rosbags``; :func:`analyse_bag`
gives its metrics, defined in :mod:`.metrics` (from arrays), with the joint series of
:func:`load_joints` and the bound of :func:`optimal_metrics`.

A cell's bag (``ibvs cell``; the keys are absent from a run's): without the simulator's
/ibvs/tool_path the tool poses are the nominal kinematics of /joint_states (the encoders:
the model's pose, what a real cell knows), ``tool_pose_source: joint_states``; a
rehearsal's bag that carries its teach record (``ibvs cell --teach``) with the true tool
pose where the simulator held the tool has that pose as the target, ``target_source:
teach`` (the parameters' target is the encoders' kinematics there, which the simulated
encoder offsets move away from the truth).
"""

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any, TYPE_CHECKING

from ibvs_common import contract, profiling
from ibvs_common.conversions import (camera_from_msgs, InputError, pose_matrix, read_joint_path,
                                     read_joints)
from ibvs_common.shared_params import target_from_parameters
from ibvs_common.timing import NS_PER_S, seconds_to_ns
import numpy as np
from numpy.typing import NDArray
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores
import yaml

from .metrics import (compute_metrics, final_image_error, free_running_metrics,
                      interrupted_outcome, joint_metrics, RENDER_KEYS, render_metrics,
                      SERVO_RTF_KEYS, STAMP_OFFSET_KEYS, stamp_offset_metrics)

if TYPE_CHECKING:
    from ibvs_model.robot import RobotParams

#: Custom-data key of the bag's metadata that holds the run's parameters (YAML).
PARAMS_KEY = 'ibvs.parameters'
RUN_KEY = 'ibvs.run'
#: Custom-data key of a cell session's teach record (``ibvs cell --teach``: YAML of
#: ibvs_experiments.teach's record, its true tool pose under :data:`TRUE_TOOL_POSE_KEY`).
TEACH_KEY = 'ibvs.teach'
TRUE_TOOL_POSE_KEY = 'true_tool_pose'
#: Where the tool poses come from: the simulator's truth (/ibvs/tool_path), or the
#: encoders through the nominal kinematics (/joint_states: a real cell has no truth).
TOOL_SOURCES = ('simulator', 'joint_states')
#: Where the target comes from: the parameters, or a rehearsal's teach record (the true
#: tool pose where the simulator held it, ``ibvs teach``).
TARGET_SOURCES = ('parameters', 'teach')


class NotAnalysable(ValueError):
    """A bag that holds too little of a run to analyse (``ibvs analyse``: exit code 2)."""


@dataclass
class RunData:
    """Time series of one run, as arrays (seconds of sim time, metres, pixels)."""

    params: dict
    run_info: dict
    t: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    target: np.ndarray
    feature_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    features: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    mode_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    modes: list = field(default_factory=list)
    #: Free-running: (command ns, frame ns) of each /ibvs/frame_latency, and the simulator's
    #: real_time_factor_held reports.
    latency: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    rtf_held: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: Free-running: the stamps (ns) of the left camera_info messages (frames published),
    #: and the simulator's last real_time_factor_servo_* values (/diagnostics).
    frame_stamps: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    servo_rtf: dict = field(default_factory=dict)
    #: The feature node's last stamp offset values (:data:`.metrics.STAMP_OFFSET_KEYS`), as
    #: strings.
    stamp_offset: dict = field(default_factory=dict)
    camera: object = None
    #: The simulator's render_device and render_hardware (/diagnostics), where it said them.
    render: dict = field(default_factory=dict)
    #: The last frame's image error (px, :func:`.metrics.final_image_error`) and the run's
    #: last /ibvs/servo_status (a ServoStatus name), None where the bag has none.
    final_image_error_px: float | None = None
    servo_status: str | None = None
    #: Set by :func:`analyse_bag`: the joint series (:func:`load_joints`, to the run's
    #: duration) and the limits of the run's robot (q_min, q_max, qd_max, torque), which
    #: the metrics and ``joints.png`` both use.
    joints: tuple | None = None
    joint_limits: tuple | None = None
    #: The taught target features p_bar (px, 6) the feature node measured on the teach pair
    #: and the controller servoed to (``target_features_source: taught``), from its
    #: ``taught_target_px`` on /diagnostics; None when not taught (or an older bag).
    taught_target: np.ndarray | None = None
    #: Where :attr:`position` and :attr:`rotation` come from, and :attr:`target`
    #: (:data:`TOOL_SOURCES`, :data:`TARGET_SOURCES`).
    tool_source: str = TOOL_SOURCES[0]
    target_source: str = TARGET_SOURCES[0]


def _stamp(header):
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def _before(end_ns, stamps, values):
    """Return (stamps, values) of the samples stamped (s) before ``end_ns``."""
    keep = [i for i, x in enumerate(stamps) if seconds_to_ns(x) < end_ns]
    return [stamps[i] for i in keep], [values[i] for i in keep]


#: The camera_info topics of either camera_topics setting, by side.
INFO_SIDES = {contract.LEFT_INFO: 'left', contract.RIGHT_INFO: 'right',
              contract.ZED_LEFT_INFO: 'left', contract.ZED_RIGHT_INFO: 'right'}

#: The tool poses of bags recorded before /ibvs/tool_path: one PoseStamped a step.
OLD_TOOL_POSE = '/ibvs/tool_pose'


def _read(bag_path: Path) -> SimpleNamespace:
    """
    Return what :func:`load_run` takes from a run's bag, as the messages come.

    The tool poses' stamps and 4x4 poses (``t``, ``poses``), ``states`` ((stamp s, q) of
    /joint_states: the tool poses of a bag without the truth), the features' and the feature
    status's stamps, points and modes (``ft``, ``feats``, ``mt``, ``modes``), the first
    camera_info of each side and the first /stereo/pose (``infos``, ``cam_pose``), the
    free-running records and /diagnostics values, and ``statuses`` ((bag time ns, code) of
    each /ibvs/servo_status).
    """
    got = SimpleNamespace(t=[], poses=[], states=[], ft=[], feats=[], mt=[], modes=[],
                          infos={}, cam_pose=None, latency=[], rtf_held=[], render={},
                          taught=[], frame_stamps=[], servo_rtf={}, stamp_offset={},
                          statuses=[])
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([bag_path], default_typestore=typestore) as reader:
        wanted = {contract.TOOL_PATH, OLD_TOOL_POSE, contract.FEATURES, contract.FEATURE_STATUS,
                  contract.LEFT_INFO, contract.RIGHT_INFO, contract.STEREO_POSE,
                  contract.ZED_LEFT_INFO, contract.ZED_RIGHT_INFO, contract.FRAME_LATENCY,
                  contract.DIAGNOSTICS, contract.SERVO_STATUS}
        if not any(c.topic in (contract.TOOL_PATH, OLD_TOOL_POSE) for c in reader.connections):
            wanted.add(contract.JOINT_STATES)
        conns = [c for c in reader.connections if c.topic in wanted]
        for conn, bag_ns, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == contract.SERVO_STATUS:
                got.statuses.append((bag_ns, int(msg.data)))  # no header: the bag's time
            elif conn.topic == contract.JOINT_STATES:
                try:  # by name, other joints ignored, as the nodes read them
                    got.states.append((_stamp(msg.header), read_joints(msg)))
                except InputError:
                    pass
            elif conn.topic in (contract.TOOL_PATH, OLD_TOOL_POSE):
                for pose in (msg.poses if conn.topic == contract.TOOL_PATH else [msg]):
                    got.t.append(_stamp(pose.header))
                    got.poses.append(pose_matrix(pose.pose))
            elif conn.topic == contract.FEATURES:
                got.ft.append(_stamp(msg.header))
                got.feats.append([[p.x, p.y, p.z] for p in msg.polygon.points])
            elif conn.topic == contract.FEATURE_STATUS:
                values = {kv.key: kv.value for s in msg.status for kv in s.values}
                got.mt.append(_stamp(msg.header))
                got.modes.append(values.get('mode', 'unknown'))
            elif conn.topic in INFO_SIDES:
                got.infos.setdefault(INFO_SIDES[conn.topic], msg)
                if INFO_SIDES[conn.topic] == 'left':
                    got.frame_stamps.append(msg.header.stamp.sec * 10 ** 9
                                            + msg.header.stamp.nanosec)
            elif conn.topic == contract.FRAME_LATENCY:
                got.latency.append((msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec,
                                    msg.time_ref.sec * 10 ** 9 + msg.time_ref.nanosec))
            elif conn.topic == contract.DIAGNOSTICS:
                got.rtf_held.extend(float(kv.value) for status in msg.status
                                    for kv in status.values
                                    if kv.key == 'real_time_factor_held')
                got.render.update((kv.key, kv.value) for status in msg.status
                                  for kv in status.values if kv.key in RENDER_KEYS)
                got.taught = [kv.value for status in msg.status for kv in status.values
                              if kv.key == TAUGHT_KEY] or got.taught
                got.servo_rtf.update((kv.key, kv.value) for status in msg.status
                                     for kv in status.values if kv.key in SERVO_RTF_KEYS)
                got.stamp_offset.update((kv.key, kv.value) for status in msg.status
                                        for kv in status.values if kv.key in STAMP_OFFSET_KEYS)
            elif conn.topic == contract.STEREO_POSE and got.cam_pose is None:
                got.cam_pose = msg
    return got


def load_run(bag_path: str | Path) -> 'RunData':
    """Read a run's bag: tool poses, features, feature modes, camera and parameters."""
    bag_path = Path(bag_path)
    meta = yaml.safe_load((bag_path / 'metadata.yaml').read_text())
    custom = meta.get('rosbag2_bagfile_information', {}).get('custom_data') or {}
    params = yaml.safe_load(custom.get(PARAMS_KEY, '{}')) or {}
    run_info = yaml.safe_load(custom.get(RUN_KEY, '{}')) or {}
    got = _read(bag_path)
    t, poses, ft, feats, mt, modes = got.t, got.poses, got.ft, got.feats, got.mt, got.modes
    states, infos, cam_pose, taught = got.states, got.infos, got.cam_pose, got.taught
    latency, rtf_held, render = got.latency, got.rtf_held, got.render
    frame_stamps, servo_rtf, stamp_offset = got.frame_stamps, got.servo_rtf, got.stamp_offset
    statuses = got.statuses
    # A run of duration D covers the steps stamped in [0, D): what the simulator did while
    # the runner was stopping it is left out, so that the metrics do not depend on when it
    # stopped (older bags have no duration_s and are taken whole).
    tool_source = TOOL_SOURCES[0]
    if not t and states:  # a real cell's bag: the model's pose, FK of the encoders
        from ibvs_model import forward_kinematics_batch
        t = [stamp for stamp, _ in states]
        poses = list(forward_kinematics_batch(np.array([q for _, q in states])))
        tool_source = TOOL_SOURCES[1]
    limit = run_info.get('duration_s')
    if limit is not None:
        end_ns = seconds_to_ns(limit)
        t, poses = _before(end_ns, t, poses)
        ft, feats = _before(end_ns, ft, feats)
        mt, modes = _before(end_ns, mt, modes)
        latency = [pair for pair in latency if pair[0] < end_ns]
        statuses = [status for status in statuses if status[0] < end_ns]
        frame_stamps = [stamp for stamp in frame_stamps if stamp < end_ns]
    if len(t) < 2:
        raise NotAnalysable(f'{bag_path}: fewer than two tool poses on {contract.TOOL_PATH} '
                            f'(or {contract.JOINT_STATES}): the run ended (or was killed) '
                            'before time advanced')
    order = np.argsort(t, kind='stable')
    poses = np.array(poses)[order]
    camera = None
    if cam_pose is not None and len(infos) == 2:
        # rosbags messages have the fields of the rclpy ones: the same conversion serves.
        camera = camera_from_msgs(infos['left'], infos['right'], cam_pose)
    target = target_from_parameters(params)
    teach = yaml.safe_load(custom.get(TEACH_KEY, '{}')) or {}
    target_source = TARGET_SOURCES[0]
    if tool_source == TOOL_SOURCES[0] and teach.get(TRUE_TOOL_POSE_KEY) is not None:
        # A rehearsal's taught target: where the simulator held the tool, in the truth's
        # own terms (the parameters' target is the encoders' FK, which d_q moves).
        target = np.array(teach[TRUE_TOOL_POSE_KEY], dtype=float).reshape(4, 4)
        target_source = TARGET_SOURCES[1]
    feats = np.array([np.ravel(f) for f in feats if len(f) == 2]) if feats else np.zeros((0, 6))
    return RunData(params=params, run_info=run_info, t=np.asarray(t)[order],
                   position=poses[:, :3, 3], rotation=poses[:, :3, :3], target=target,
                   feature_t=np.asarray(ft), features=feats, mode_t=np.asarray(mt),
                   modes=modes, camera=camera,
                   latency=np.array(latency, dtype=np.int64).reshape(-1, 2),
                   rtf_held=np.array(rtf_held), render=render_metrics(render),
                   taught_target=_taught(taught),
                   frame_stamps=np.array(frame_stamps, dtype=np.int64), servo_rtf=servo_rtf,
                   stamp_offset=stamp_offset,
                   tool_source=tool_source, target_source=target_source,
                   final_image_error_px=final_image_error(
                       feats, _taught(taught), camera, target_from_parameters(params)),
                   servo_status=_status_name(statuses[-1][1]) if statuses else None)


def _status_name(code):
    """Return the ServoStatus name of ``code``, or the code in words if it is none."""
    from ibvs_common.servo_codes import ServoStatus
    try:
        return ServoStatus(code).name
    except ValueError:
        return f'code {code}'


#: The feature node's /diagnostics key of the taught target features (feature_node.py).
TAUGHT_KEY = 'taught_target_px'


def _taught(values):
    """Return the last ``taught_target_px`` value ('[u, ...]', 6 numbers) as an array."""
    if not values:
        return None
    try:
        numbers = [float(x) for x in values[-1].strip('[]').split(',')]
    except ValueError:
        return None
    return np.array(numbers) if len(numbers) == 6 else None


def load_joints(bag_path: str | Path, end_s: float | None = None
                ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64],
                           NDArray[np.float64], NDArray[np.float64]]:
    """
    Return (t, q, qd, tau_t, tau) of a run's bag: its joint states and joint torques.

    The joint states are the simulator's batches on /ibvs/joint_path where the bag has them
    (a run's: the recorder takes those), else /joint_states (a real cell's bag, or a
    recorder asked for them), never both, so each step counts once. The torques are the
    /joint_effort_commands where the bag has them, else those the batches report applied
    (a state's effort is the torque of the step before it, which is the command stamped at
    that step's start unless the simulator rejected it: the same float64s, at the same
    times). Angles and speeds by joint name (contract.JOINT_NAMES), (N, 6); times in s of
    sim time; only the samples stamped before ``end_s`` when given.
    """
    states, efforts, batched = [], [], []
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([Path(bag_path)], default_typestore=typestore) as reader:
        has_batches = any(c.topic == contract.JOINT_PATH for c in reader.connections)
        wanted = {contract.JOINT_PATH if has_batches else contract.JOINT_STATES,
                  contract.EFFORT_COMMANDS}
        conns = [c for c in reader.connections if c.topic in wanted]
        # rosbags reads every topic for an empty list: a bag without joints has none here
        for conn, _, raw in reader.messages(connections=conns) if conns else ():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == contract.JOINT_PATH:
                try:
                    stamps, q, qd, tau = read_joint_path(msg)
                except InputError:
                    continue
                batched.extend(zip((ns // NS_PER_S + ns % NS_PER_S * 1e-9  # as _stamp does
                                    for ns in stamps.tolist()), q, qd, tau))
                continue
            t = _stamp(msg.header)
            if (end_s is not None and t >= end_s) or list(msg.name) != list(
                    contract.JOINT_NAMES):
                continue
            if conn.topic == contract.JOINT_STATES:
                states.append((t, msg.position, msg.velocity))
            else:
                efforts.append((t, msg.effort))
    states += [(t, q, qd) for t, q, qd, _ in batched if end_s is None or t < end_s]
    if not efforts:
        efforts = [(t, tau) for (t, *_), (*_, tau) in zip(batched, batched[1:])
                   if len(tau) and (end_s is None or t < end_s)]

    def column(items, k):
        if not items:
            return np.zeros((0, 6)) if k else np.zeros(0)
        values = np.array([r[k] for r in items], dtype=float)
        return values if k else values.reshape(-1)
    return (column(states, 0), column(states, 1), column(states, 2), column(efforts, 0),
            column(efforts, 1))


def node_timings(bag_path: str | Path) -> dict[str, dict[str, Any]]:
    """
    Return each node's last section timings from the bag's /diagnostics.

    {node status name: {'sim_time_s': float, 'sections': {name: (total s, count)}}}, from
    the ``wall[...]_s`` and ``count[...]`` values of :mod:`ibvs_common.profiling`.
    """
    out = {}
    typestore = get_typestore(Stores.ROS2_JAZZY)
    with AnyReader([Path(bag_path)], default_typestore=typestore) as reader:
        conns = [c for c in reader.connections if c.topic == contract.DIAGNOSTICS]
        for conn, _, raw in reader.messages(connections=conns):
            for status in reader.deserialize(raw, conn.msgtype).status:
                values = {kv.key: kv.value for kv in status.values}
                if profiling.SIM_TIME_KEY not in values:
                    continue
                sections = {}
                for key, value in values.items():
                    if key.startswith('wall[') and key.endswith(']_s'):
                        name = key[len('wall['):-len(']_s')]
                        count = int(values.get(profiling.COUNT_KEY.format(name), '0'))
                        sections[name] = (float(value), count)
                out[status.name.split(':')[0]] = {
                    'sim_time_s': float(values[profiling.SIM_TIME_KEY]), 'sections': sections}
    return out


def feature_errors(run: 'RunData', params: 'RobotParams | None' = None
                   ) -> NDArray[np.float64]:
    """
    Return the measured features minus the true projection of the markers, (N, 6) px.

    One row (u_l, u_r, v of marker 1, then of marker 2) per frame whose mode on
    /ibvs/feature_status is 'measured' (estimated and blended frames are not
    measurements). The truth: the fiducials P1, P2 (eq. 8-9) at the recorded true flange
    pose of the frame's stamp, projected (eq. 14-22) by the run's camera (the published
    one: the true camera unless the run sets calibration errors). ``params``: the robot
    whose tool carries the fiducials (default the paper's IRB 4600). Not part of the
    metrics: an accuracy check of the renderer and detector, printed by ``make bench``.
    """
    from ibvs_model import IRB4600
    params = IRB4600 if params is None else params
    if run.camera is None:
        raise ValueError('the run recorded no camera (camera_info and /stereo/pose)')
    if len(run.feature_t) != len(run.features):
        raise ValueError('features without two points in the recording')
    mode_of = {seconds_to_ns(t): mode for t, mode in zip(run.mode_t, run.modes)}
    step_of = {seconds_to_ns(t): i for i, t in enumerate(run.t)}
    rows = []
    for t, features in zip(run.feature_t, run.features):
        stamp = seconds_to_ns(t)
        if mode_of.get(stamp) != 'measured' or stamp not in step_of:
            continue
        i = step_of[stamp]
        points = params.fiducials_E @ run.rotation[i].T + run.position[i]
        rows.append(features - run.camera.project(points).reshape(6))
    return np.array(rows).reshape(-1, 6)


def analyse_bag(bag_path: str | Path) -> tuple['RunData', dict[str, Any]]:
    """
    Return (RunData, metrics) of a recorded run.

    The joint metrics (:func:`.metrics.joint_metrics`) against the limits of the IRB 4600
    with the run's ``l2_scale`` and ``l4_scale``, as ``joints.png`` draws them.
    """
    from ibvs_model import IRB4600
    from ibvs_model.mass_model import joint_efforts
    run = load_run(bag_path)
    metrics = compute_metrics(run.t, run.position, run.rotation, run.target, run.mode_t,
                              run.modes, run.run_info.get('wall_duration_s'),
                              run.params.get('scenario_name', run.params.get('scenario')),
                              final_image_error_px=run.final_image_error_px)
    if run.servo_status is not None:
        metrics['final_servo_status'] = run.servo_status
    robot = IRB4600.scaled(float(run.params.get('l2_scale', 1.0)),
                           float(run.params.get('l4_scale', 1.0)))
    run.joints = load_joints(bag_path, run.run_info.get('duration_s'))
    run.joint_limits = (robot.q_min, robot.q_max, robot.qd_max, joint_efforts(robot))
    metrics.update(joint_metrics(run.joints, robot.qd_max, run.joint_limits[3]))
    metrics.update(free_running_metrics(run.latency, run.rtf_held, int(run.frame_stamps.size),
                                        run.servo_rtf))
    metrics.update(optimal_metrics(run, metrics))
    metrics.update(run.render)
    metrics.update(stamp_offset_metrics(run.stamp_offset))
    if run.tool_source != TOOL_SOURCES[0]:  # a cell's bag: say what the errors are of
        metrics['tool_pose_source'] = run.tool_source
    if run.target_source != TARGET_SOURCES[0]:
        metrics['target_source'] = run.target_source
    return run, interrupted_outcome(metrics, run.run_info)


def optimal_metrics(run: 'RunData', metrics: Mapping[str, Any]) -> dict[str, Any]:
    """
    Return a position-interface run's bound: ``time_optimal_s`` and its excess.

    The time-optimal move of the arm from the run's first joint angles to the target's IK
    branch near them (the feedforward's goal), under the joint controller's limits with the
    run's parameters, plus the drive's dead time
    (:func:`ibvs_control.position_interface.time_optimal_s`); and
    ``time_to_1mm_over_optimal_s``, the time to 1 mm less that bound (None without one).
    Other runs (the paper's computed torque): empty.
    """
    from ibvs_control.controllers import target_branch
    from ibvs_control.position_interface import time_optimal_s
    if run.params.get('command_interface') != 'position' or run.joints is None \
            or not len(run.joints[1]):
        return {}
    q_start = np.asarray(run.joints[1][0], dtype=float)
    bound = time_optimal_s(q_start, target_branch(run.target, q_start), run.params)
    reached = metrics.get('time_to_1mm_s')
    return {'time_optimal_s': bound,
            'time_to_1mm_over_optimal_s': None if reached is None else reached - bound}


#: The feedback node's /diagnostics key of the envelope's counts (adaptive_feedback_node).
INTERVENTIONS_KEY = 'envelope_interventions'


def envelope_interventions(bag_path: str | Path) -> dict[int, int] | None:
    """
    Return the envelope's counts at the end of a run: {code: frames}, from its bag.

    The last ``envelope_interventions`` value on /diagnostics ('NAME n, NAME n' or 'none');
    None when the bag has none (the envelope off, or no frame answered).
    """
    from ibvs_control.envelope import Intervention
    last = None
    with AnyReader([Path(bag_path)], default_typestore=get_typestore(Stores.ROS2_JAZZY)
                   ) as reader:
        conns = [c for c in reader.connections if c.topic == contract.DIAGNOSTICS]
        for conn, _, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            last = next((kv.value for status in msg.status for kv in status.values
                         if kv.key == INTERVENTIONS_KEY), last)
    if last is None:
        return None
    out = {}
    for item in last.split(','):
        parts = item.split()
        if len(parts) == 2 and parts[0] in Intervention.__members__:
            out[int(Intervention[parts[0]])] = int(parts[1])
    return out
