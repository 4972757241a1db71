"""
Metrics of one run, computed from its rosbag2 (MCAP) recording.

The pure part (:func:`compute_metrics`) takes arrays; :func:`load_run` reads them from a
bag with ``rosbags``, so ``analyse <bag>`` reproduces every number and figure of a run.

Definitions (tool = flange frame {E}, target = the scenario's target pose):

- position error e(t) = |p(t) - p_target|; tool-axis error = angle between z6(t) and the
  target's z6 (the roll about the tool axis is not controlled: docs/design.md §5);
- ``settling_time_2pct_s``: first time after which e(t) stays within 2 % of e(0);
- ``time_to_1mm_s``: first time after which e(t) stays within 1 mm;
- ``max_overshoot_m``: how far the tool goes past the target along the approach direction
  d = (p_target - p(0)) / |p_target - p(0)|: max over t of (p(t) - p_target) . d, or 0.
  A joint-space move swings the tool sideways (scenario 1 turns joint 1 by 160 deg, taking
  y out to about 1.2 m); that swing is ``max_lateral_excursion_m`` (largest distance from
  the start-target line), and ``overshoot_xyz_m`` gives each coordinate's excursion past
  its target in the direction of its own motion (any excursion for a coordinate that does
  not move net), as the paper's Figures 10-12 show them;
- ``lowest_tool_z_m``: the lowest the tool came, z of {O} (0 is the robot's base plane;
  below ``-mount_height_m`` of the simulator it is under the floor, hidden from the camera);
- ``*_last_0_5s_*``: the mean and the maximum of the position and tool-axis errors over
  the last ``LAST_WINDOW_S`` = 0.5 s of the run (one final sample says little under image
  noise), and the position error's ripple there (its maximum less its minimum: ringing,
  or the image noise through the feedback); the whole run when it is shorter;
- ``time_estimated_s``: sim time during which the features were not measured: the feature
  node's modes 'estimated' (from the model, eq. 46) and 'blending' (the switch from one
  source to the other, section 2.3); ``final_feature_mode``: the mode of the last feature
  status ('measured', 'blending', 'estimated'; None without any);
- ``success``: the run ends within :data:`.convergence.SUCCESS` (1 mm and 0.5 deg), the
  project's one success criterion, never for a run that SIGINT stopped
  (:func:`interrupted_outcome`); ``miss_reason``: why not (interrupted, timed out, stalled,
  features lost, held in a local minimum of the image error, with the final errors:
  :func:`.convergence.miss_reason`), None on success; ``time_to_success_s``: first time
  after which both errors stay within it;
- ``final_image_error_px``: |p_hat - p_bar| of the run's last frame of /ibvs/features, p_bar
  the controller's target features (the taught ones the feature node measured, else the
  target pose's through the run's camera: :func:`final_image_error`);
  ``final_servo_status``: the last /ibvs/servo_status of the run (a name of
  ibvs_common.servo_codes.ServoStatus, e.g. 'LOCAL_MINIMUM'); each absent from a bag
  without them;
- ``peak_joint_speed_ratio``, ``peak_joint_torque_ratio`` (:func:`joint_metrics`; from the
  bag's joint states and torques, :func:`analyse_bag`): the largest |qdot_i| / qd_max_i
  (the IRB 4600's rated joint speeds) and |tau_i| / tau_max_i (the torque limits estimated
  by :func:`ibvs_model.mass_model.joint_efforts`) over joints and time: 1 is the real
  arm's limit, 32.7 a joint 32.7 times faster than the IRB 4600 can turn;
- ``wall_duration_s``, ``real_time_factor``: the machine's wall time from step 0 and sim
  time per wall second (timings of the machine, not of the loop).

Free-running runs (``command_interface: position``; the keys are absent from lockstep runs, whose
metrics stay as they were):

- ``frame_latency_{mean,p95,max}_s``, ``frames_used``: sim time from a frame's exposure
  (its stamp) to the first position command that used its q_feedback, from the joint
  controller's /ibvs/frame_latency (sensor_msgs/TimeReference: header.stamp = command,
  time_ref = frame): camera-to-command latency as the loop saw it, in the time the
  controller runs on;
- ``frames_published``: the stereo frames the simulator published, counted as the left
  camera_info messages in the bag stamped before the run's end (a frame is one image and
  one camera_info per lens; a lost frame or one in a camera outage has none), beside
  ``frames_used``, the frames whose q_feedback a command used;
- ``real_time_factor_held_{mean,min}``: the simulator's own measurement, every 2 s of wall
  time, of the sim seconds it advanced per wall second (``real_time_factor_held`` on
  /diagnostics), against ``real_time_factor`` (the overall sim/wall ratio of the run,
  start-up excluded);
- ``real_time_factor_servo_{mean,min_1s}``: the factor held while servoing, from the
  simulator's first position reference on (start-up, the renderer's first frames and the
  wait for the first command left out): it cuts that span into consecutive windows of 1 s
  of wall time and reports the minimum of their factors (sim s advanced / wall s) and the
  mean (sim time over wall time of all the complete windows); their last values on
  /diagnostics. Wall-time windows because the factor is a rate of the wall clock and the
  stepping is paced by it: a stall of the machine is a wall-time event, which a window of
  1 s of sim time (20 s of wall time at 0.05) would average away. None when the run had
  no complete window;
- ``time_optimal_s`` (the position interface's runs): the bound, the arm's time-optimal
  move from its first joint angles to the feedforward's goal under the joint controller's
  limits plus the drive's dead time (:func:`optimal_metrics`), and
  ``time_to_1mm_over_optimal_s``, the time to 1 mm less it.

A cell's bag (``ibvs cell``; the keys are absent from a run's): without the simulator's
/ibvs/tool_path the tool poses are the nominal kinematics of /joint_states (the encoders:
the model's pose, what a real cell knows), ``tool_pose_source: joint_states``; a
rehearsal's bag that carries its teach record (``ibvs cell --teach``) with the true tool
pose where the simulator held the tool has that pose as the target, ``target_source:
teach`` (the parameters' target is the encoders' kinematics there, which the simulated
encoder offsets move away from the truth).

What drew the images (runs that rendered them; the simulator's /diagnostics):
``render_device``, the OpenGL GL_RENDERER string (e.g. 'llvmpipe (LLVM 15.0.6, 256 bits)'),
and ``render_hardware``, true on a GPU, false on a software rasteriser (ibvs_sim.gl_renderer).
"""

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TYPE_CHECKING

from ibvs_common import contract, profiling
from ibvs_common.conversions import (camera_from_msgs, InputError, pose_matrix, read_joint_path,
                                     read_joints)
from ibvs_common.shared_params import target_from_parameters
from ibvs_common.timing import NS_PER_S, ns_to_seconds, seconds_to_ns
import numpy as np
from numpy.typing import ArrayLike, NDArray
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores
import yaml

from .convergence import miss_reason, REACHED, SUCCESS

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
#: The simulator's /diagnostics values that say what drew the images (module docstring).
RENDER_KEYS = ('render_device', 'render_hardware')
#: The simulator's /diagnostics values of the factor held while servoing (module docstring).
SERVO_RTF_KEYS = ('real_time_factor_servo_mean', 'real_time_factor_servo_min_1s')
#: The feature node's /diagnostics values of the camera's stamp offset (ibvs_vision.stamp_offset).
STAMP_OFFSET_KEYS = ('stamp_offset_ms', 'stamp_offset_sd_ms', 'stamp_offset_applied_ms')
#: The closing window of the run over which the error's mean and maximum are reported, s.
LAST_WINDOW_S = 0.5


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
    #: The feature node's last stamp offset values (:data:`STAMP_OFFSET_KEYS`), as strings.
    stamp_offset: dict = field(default_factory=dict)
    camera: object = None
    #: The simulator's render_device and render_hardware (/diagnostics), where it said them.
    render: dict = field(default_factory=dict)
    #: The last frame's image error (px, :func:`final_image_error`) and the run's last
    #: /ibvs/servo_status (a ServoStatus name), None where the bag has none.
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


def _settle_time(t, inside):
    """Return the first time from which ``inside`` holds to the end (None if it never does)."""
    if not inside[-1]:
        return None
    outside = np.nonzero(~inside)[0]
    return float(t[0]) if outside.size == 0 else float(t[outside[-1] + 1])


def axis_angle_deg(rotation: ArrayLike, target_rotation: ArrayLike) -> NDArray[np.float64]:
    """Return the angle (deg) between each tool axis z6 and the target's, for (N, 3, 3)."""
    from ibvs_model import tool_axis_angle
    return np.degrees(tool_axis_angle(rotation, target_rotation))


def estimated_time(mode_t: 'Sequence[float] | NDArray[np.float64]', modes: Sequence[str],
                   t_end: float) -> float:
    """Return the sim time spent with features not purely measured (mode held to next frame)."""
    if len(mode_t) == 0:
        return 0.0
    ends = np.append(mode_t[1:], max(t_end, mode_t[-1]))
    return float(sum(e - s for s, e, m in zip(mode_t, ends, modes) if m != 'measured'))


def compute_metrics(t: ArrayLike, position: ArrayLike, rotation: ArrayLike,
                    target: ArrayLike, mode_t: 'Sequence[float] | NDArray[np.float64]' = (),
                    modes: Sequence[str] = (), wall_duration_s: float | None = None,
                    scenario: str | int | None = None,
                    final_image_error_px: float | None = None) -> dict[str, Any]:
    """
    Return the run's metrics dict (see the module docstring) from arrays.

    ``final_image_error_px`` (the feedback's last image error, where known) is a metric and
    tells a local minimum from another stall (:func:`.convergence.miss_reason`).
    """
    t = np.asarray(t, dtype=float)
    position = np.asarray(position, dtype=float)
    rotation = np.asarray(rotation, dtype=float)
    target = np.asarray(target, dtype=float)
    if t.size < 2:
        raise ValueError('a run needs at least two tool poses to be analysed')
    error = np.linalg.norm(position - target[:3, 3], axis=1)
    axis_err = axis_angle_deg(rotation, target[:3, :3])
    step = target[:3, 3] - position[0]
    approach = step / max(np.linalg.norm(step), 1e-12)
    past = (position - target[:3, 3]) @ approach
    offset = position - position[0]
    lateral = np.linalg.norm(offset - np.outer(offset @ approach, approach), axis=1)
    # A coordinate that has no net step overshoots by any excursion from its target.
    beyond = np.where(np.abs(step) > 1e-9, (position - target[:3, 3]) * np.sign(step),
                      np.abs(position - target[:3, 3]))
    overshoot_axes = np.maximum(beyond.max(axis=0), 0.0)
    sim_duration = float(t[-1] - t[0])
    last = t >= t[-1] - LAST_WINDOW_S
    metrics = {
        'scenario': scenario,
        'final_position_error_m': float(error[-1]),
        'final_tool_axis_error_deg': float(axis_err[-1]),
        'mean_position_error_last_0_5s_m': float(error[last].mean()),
        'max_position_error_last_0_5s_m': float(error[last].max()),
        'mean_tool_axis_error_last_0_5s_deg': float(axis_err[last].mean()),
        'max_tool_axis_error_last_0_5s_deg': float(axis_err[last].max()),
        'position_error_ripple_last_0_5s_m': float(np.ptp(error[last])),
        'initial_position_error_m': float(error[0]),
        'settling_time_2pct_s': _relative(_settle_time(t, error <= 0.02 * error[0]), t),
        'time_to_1mm_s': _relative(_settle_time(t, REACHED.within(error)), t),
        'time_to_success_s': _relative(_settle_time(t, SUCCESS.within(error, axis_err)), t),
        'max_overshoot_m': float(max(past.max(), 0.0)),
        'max_lateral_excursion_m': float(lateral.max()),
        'overshoot_xyz_m': [float(v) for v in overshoot_axes],
        'max_position_error_m': float(error.max()),
        'lowest_tool_z_m': float(position[:, 2].min()),
        'time_estimated_s': estimated_time(np.asarray(mode_t, float), list(modes), t[-1]),
        'final_feature_mode': _last_mode(mode_t, modes),
        'sim_duration_s': sim_duration,
        'wall_duration_s': wall_duration_s,
        'real_time_factor': (sim_duration / wall_duration_s
                             if wall_duration_s else None),
        'samples': int(t.size),
    }
    if final_image_error_px is not None:
        metrics['final_image_error_px'] = float(final_image_error_px)
    metrics['success'] = SUCCESS.final(metrics)
    metrics['miss_reason'] = miss_reason(metrics)
    return metrics


def _last_mode(mode_t, modes):
    """Return the mode of the latest feature status (by stamp), None without any."""
    if not len(modes):
        return None
    return str(modes[int(np.argmax(np.asarray(mode_t, dtype=float)))])


def joint_metrics(series: Sequence[ArrayLike], qd_max: ArrayLike, tau_max: ArrayLike
                  ) -> dict[str, Any]:
    """
    Return ``peak_joint_speed_ratio`` and ``peak_joint_torque_ratio`` (module docstring).

    ``series``: :func:`load_joints`' (t, q, qd, tau_t, tau); ``qd_max``, ``tau_max``: the six
    joints' rated speeds (rad/s) and torque limits (N m). None where the series is empty.
    """
    _, _, qd, _, tau = series

    def peak(values, limits):
        values = np.abs(np.asarray(values, dtype=float)).reshape(-1, 6)
        return float((values / np.asarray(limits, dtype=float)).max()) if values.size else None
    return {'peak_joint_speed_ratio': peak(qd, qd_max),
            'peak_joint_torque_ratio': peak(tau, tau_max)}


def free_running_metrics(latency: ArrayLike, rtf_held: ArrayLike,
                         frames_published: int | None = None,
                         servo_rtf: dict | None = None) -> dict[str, Any]:
    """
    Return the free-running metrics (module docstring); {} without latency records.

    ``latency``: (command ns, frame ns) pairs; ``rtf_held``: the simulator's
    real_time_factor_held reports; ``frames_published``: the frames in the bag (None:
    not known); ``servo_rtf``: the simulator's last ``real_time_factor_servo_mean`` and
    ``real_time_factor_servo_min_1s`` (absent: None).
    """
    latency = np.asarray(latency, dtype=np.int64).reshape(-1, 2)
    if latency.size == 0:
        return {}
    delay = ns_to_seconds(latency[:, 0] - latency[:, 1])
    held = np.asarray(rtf_held, dtype=float)
    return {
        'frames_used': int(delay.size),
        'frame_latency_mean_s': float(delay.mean()),
        'frame_latency_p95_s': float(np.percentile(delay, 95)),
        'frame_latency_max_s': float(delay.max()),
        'real_time_factor_held_mean': float(held.mean()) if held.size else None,
        'real_time_factor_held_min': float(held.min()) if held.size else None,
        'frames_published': frames_published,
        **{key: (float(servo_rtf[key]) if key in (servo_rtf or {}) else None)
           for key in SERVO_RTF_KEYS},
    }


def render_metrics(values: dict[str, str]) -> dict[str, Any]:
    """Return the render metrics of the simulator's /diagnostics strings (module docstring)."""
    out = {}
    if 'render_device' in values:
        out['render_device'] = values['render_device']
    if 'render_hardware' in values:
        out['render_hardware'] = values['render_hardware'] == 'True'
    return out


def stamp_offset_metrics(values: Mapping[str, str]) -> dict[str, Any]:
    """
    Return the camera's stamp offset the feature node estimated last (ms), where it did.

    ``stamp_offset_ms`` and ``stamp_offset_sd_ms`` (the estimate and its noise's share,
    ibvs_vision.stamp_offset) and ``stamp_offset_applied_ms``; nothing for a run without an
    estimate (lockstep, where the stamps are the exposures, or a run too short).
    """
    try:
        return {key: float(values[key]) for key in STAMP_OFFSET_KEYS}
    except (KeyError, ValueError):  # 'none': no estimate
        return {}


def _relative(value, t):
    return None if value is None else float(value - t[0])


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


def load_run(bag_path: str | Path) -> 'RunData':
    """Read a run's bag: tool poses, features, feature modes, camera and parameters."""
    bag_path = Path(bag_path)
    meta = yaml.safe_load((bag_path / 'metadata.yaml').read_text())
    custom = meta.get('rosbag2_bagfile_information', {}).get('custom_data') or {}
    params = yaml.safe_load(custom.get(PARAMS_KEY, '{}')) or {}
    run_info = yaml.safe_load(custom.get(RUN_KEY, '{}')) or {}
    t, poses, ft, feats, mt, modes = [], [], [], [], [], []
    states = []  # (stamp s, q) of /joint_states: the tool poses of a bag without the truth
    infos, cam_pose = {}, None
    latency, rtf_held, render, taught = [], [], {}, []
    frame_stamps, servo_rtf, stamp_offset = [], {}, {}
    statuses = []  # (bag time ns, code) of each /ibvs/servo_status
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
                statuses.append((bag_ns, int(msg.data)))  # no header: the bag's time
            elif conn.topic == contract.JOINT_STATES:
                try:  # by name, other joints ignored, as the nodes read them
                    states.append((_stamp(msg.header), read_joints(msg)))
                except InputError:
                    pass
            elif conn.topic in (contract.TOOL_PATH, OLD_TOOL_POSE):
                for pose in (msg.poses if conn.topic == contract.TOOL_PATH else [msg]):
                    t.append(_stamp(pose.header))
                    poses.append(pose_matrix(pose.pose))
            elif conn.topic == contract.FEATURES:
                ft.append(_stamp(msg.header))
                feats.append([[p.x, p.y, p.z] for p in msg.polygon.points])
            elif conn.topic == contract.FEATURE_STATUS:
                values = {kv.key: kv.value for s in msg.status for kv in s.values}
                mt.append(_stamp(msg.header))
                modes.append(values.get('mode', 'unknown'))
            elif conn.topic in INFO_SIDES:
                infos.setdefault(INFO_SIDES[conn.topic], msg)
                if INFO_SIDES[conn.topic] == 'left':
                    frame_stamps.append(msg.header.stamp.sec * 10 ** 9
                                        + msg.header.stamp.nanosec)
            elif conn.topic == contract.FRAME_LATENCY:
                latency.append((msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec,
                                msg.time_ref.sec * 10 ** 9 + msg.time_ref.nanosec))
            elif conn.topic == contract.DIAGNOSTICS:
                rtf_held.extend(float(kv.value) for status in msg.status
                                for kv in status.values if kv.key == 'real_time_factor_held')
                render.update((kv.key, kv.value) for status in msg.status
                              for kv in status.values if kv.key in RENDER_KEYS)
                taught = [kv.value for status in msg.status for kv in status.values
                          if kv.key == TAUGHT_KEY] or taught
                servo_rtf.update((kv.key, kv.value) for status in msg.status
                                 for kv in status.values if kv.key in SERVO_RTF_KEYS)
                stamp_offset.update((kv.key, kv.value) for status in msg.status
                                    for kv in status.values if kv.key in STAMP_OFFSET_KEYS)
            elif conn.topic == contract.STEREO_POSE and cam_pose is None:
                cam_pose = msg
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


def final_image_error(features: NDArray[np.float64], taught: NDArray[np.float64] | None,
                      camera: Any, target: NDArray[np.float64]) -> float | None:
    """
    Return |p_hat - p_bar| (px) of the last of ``features`` (N, 6), or None without one.

    p_bar is what the controller servoes to: the ``taught`` target features where the
    feature node measured them, else the fiducials (:attr:`ibvs_model.RobotParams.fiducials_E`)
    at the ``target`` pose (the parameters') through ``camera`` (None: not known).
    """
    if not len(features):
        return None
    if taught is None:
        if camera is None:
            return None
        from ibvs_model import IRB4600
        points = IRB4600.fiducials_E @ target[:3, :3].T + target[:3, 3]
        taught = camera.project(points).reshape(6)
    return float(np.linalg.norm(features[-1] - taught))


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

    The joint metrics (:func:`joint_metrics`) against the limits of the IRB 4600 with the
    run's ``l2_scale`` and ``l4_scale``, as ``joints.png`` draws them.
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


def interrupted_outcome(metrics: dict[str, Any], run_info: Mapping[str, Any]
                        ) -> dict[str, Any]:
    """
    Return ``metrics`` with a run that SIGINT stopped (``run_info['interrupted']``) missed.

    Such a run did not run its time: whatever its last errors, ``success`` is False and
    ``miss_reason`` says it was interrupted, then gives the errors. Other runs unchanged.
    """
    if not run_info.get('interrupted'):
        return metrics
    position, axis = metrics['final_position_error_m'], metrics['final_tool_axis_error_deg']
    metrics['success'] = False
    metrics['miss_reason'] = (
        f"interrupted (SIGINT) at {metrics['sim_duration_s']:.3g} s of sim time: final "
        f'{position * 1e3:.3g} mm, {axis:.3g} deg')
    return metrics
