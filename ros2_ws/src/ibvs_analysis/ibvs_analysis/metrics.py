"""
Metrics of one run, from its arrays: what every number of ``ibvs analyse`` means.

:func:`compute_metrics` takes the tool poses; :func:`.analysis.load_run` reads them from
a bag with ``rosbags`` and :func:`.analysis.analyse_bag` adds the rest, so ``analyse <bag>``
reproduces every number and figure of a run.

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
  bag's joint states and torques, :func:`.analysis.analyse_bag`): the largest |qdot_i| / qd_max_i
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
  limits plus the drive's dead time (:func:`.analysis.optimal_metrics`), and
  ``time_to_1mm_over_optimal_s``, the time to 1 mm less it.

What drew the images (runs that rendered them; the simulator's /diagnostics):
``render_device``, the OpenGL GL_RENDERER string (e.g. 'llvmpipe (LLVM 15.0.6, 256 bits)'),
and ``render_hardware``, true on a GPU, false on a software rasteriser (ibvs_sim.gl_renderer).
"""

from collections.abc import Mapping, Sequence
from typing import Any

from ibvs_common.timing import ns_to_seconds
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .convergence import miss_reason, REACHED, SUCCESS

#: The simulator's /diagnostics values that say what drew the images (module docstring).
RENDER_KEYS = ('render_device', 'render_hardware')
#: The simulator's /diagnostics values of the factor held while servoing (module docstring).
SERVO_RTF_KEYS = ('real_time_factor_servo_mean', 'real_time_factor_servo_min_1s')
#: The feature node's /diagnostics values of the camera's stamp offset (ibvs_vision.stamp_offset).
STAMP_OFFSET_KEYS = ('stamp_offset_ms', 'stamp_offset_sd_ms', 'stamp_offset_applied_ms')
#: The closing window of the run over which the error's mean and maximum are reported, s.
LAST_WINDOW_S = 0.5


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

    ``series``: :func:`.analysis.load_joints`' (t, q, qd, tau_t, tau); ``qd_max``,
    ``tau_max``: the six joints' rated speeds (rad/s) and torque limits (N m). None where the
    series is empty.
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
