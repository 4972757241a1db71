"""
Parameters of the control nodes, their start-time checks, and their typed configurations.

The feedforward's, the feedback's and the joint controller's configurations are here, each
holding the shared groups it reads (:class:`ibvs_common.shared_params.Timing`,
:class:`~ibvs_common.shared_params.Target`) as one field. The model-only loop's
configuration (:class:`.closed_loop.LoopConfig`) is not a node's and stays with it.

Shared parameters come from :mod:`ibvs_common.shared_params`; the ones below belong to this
package. The checks turn a configuration the controllers cannot work with into a
:class:`ibvs_common.params.ParameterError` that names the parameter, so that the node stops
at start (exit code 2, ibvs_common.node_main.run) instead of misbehaving later.
"""

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TYPE_CHECKING

from ibvs_common import shared_params as shared
from ibvs_common.params import group_field, Param, param_field, ParamConfig, ParameterError
from ibvs_common.shared_params import OMEGA_N, target_from_parameters, TAU_IN, ZETA
from ibvs_model import IRB4600, ModelError
import numpy as np
from numpy.typing import NDArray

from . import controllers, prediction, servo_laws, youla

if TYPE_CHECKING:
    from ibvs_model.robot import RobotParams

FEEDFORWARD_METHOD = Param(
    'feedforward_method', controllers.FEEDFORWARD_METHODS[0],
    "T_forward (eq. 44-45) at the physics rate: 'sampled' (inverse of the sampled inner "
    "loop, no overshoot) or 'tustin' / 'zoh' (eq. 44 discretised by scipy); 'hold': no "
    "feedforward, q(0) held (servo_law 'ibvs' and 'pbvs' need it)", '-',
    choices=controllers.FEEDFORWARD_METHODS)
FEEDFORWARD_RATIO = Param(
    'feedforward_ratio', controllers.FEEDFORWARD_RATIO,
    "T_forward's double pole at feedforward_ratio * tau_in (eq. 44-45; the paper: 0.1, a "
    '1 ms joint response that asks up to 1.2e3 rad/s); larger is a slower, gentler '
    "reference on the same joint-space line ('ibvs run' sets 2 for servo_law 'switching')",
    '-', low=0.01, high=100.0)
SERVO_LAW = Param(
    'servo_law', servo_laws.SERVO_LAWS[0],
    "feedback law: 'paper' (adaptive Youla, eq. 38-41), 'switching' (the paper's law, "
    "switched on once the markers are measured and the feedforward has settled), 'ibvs' "
    "(classic IBVS, -lambda C1^+ e) or 'pbvs' (position-based, flange and tool axis); "
    "'ibvs' and 'pbvs' need feedforward_method 'hold'", '-', choices=servo_laws.SERVO_LAWS)
FEATURE_FALLBACK = Param(
    'feature_fallback', servo_laws.FEATURE_FALLBACKS[0],
    "servo_law 'ibvs' / 'pbvs', a frame whose markers were not measured: 'estimate' "
    "integrates the feature node's blended or model-estimated features as 'paper' does; "
    "'hold' adds nothing (the robot stops)", '-', choices=servo_laws.FEATURE_FALLBACKS)
WINDUP_HORIZON_S = Param(
    'windup_horizon_s', servo_laws.WINDUP_HORIZON_S,
    "servo_law 'ibvs' / 'pbvs', anti-windup: the joint reference stays within the joint "
    'speed limits times this of the encoder angles', 's', low=0.0, high=10.0, low_open=True)
JOINT_LIMIT_MARGIN_RAD = Param(
    'joint_limit_margin_rad', servo_laws.JOINT_LIMIT_MARGIN_RAD,
    "servo_law 'ibvs' / 'pbvs': the joint reference stays this far inside the joint limits",
    'rad', low=0.0, high=0.5)
SAFETY_ENVELOPE = Param(
    'safety_envelope', False,
    'run the servo law inside the safety envelope (ibvs_control.envelope): joint-limit '
    "avoidance ('ibvs' / 'pbvs': ViSP's secondary task), MoveIt Servo's singularity and "
    'collision slow-down and halt, and the joint range kept; false: the law alone', '-')
ENVELOPE_SINGULARITY_SCALING = Param(
    'envelope_singularity_scaling', True,
    "safety_envelope: slow down and halt by the condition number of the robot's Jacobian "
    "(MoveIt Servo's thresholds 17 and 30); false: the envelope's other stages only", '-')
JOINT_STATE_TIMEOUT_S = Param(
    'joint_state_timeout_s', 0.1,
    "command_interface 'position': /joint_states older than this (the node's clock less "
    'their stamp) make the controller hold the arm and report it on /ibvs/servo_status '
    "(MoveIt Servo's incoming_command_timeout is 0.1 s)", 's', low=0.0, high=10.0,
    low_open=True)
FRAME_TIMEOUT_S = Param(
    'frame_timeout_s', 0.3,
    "command_interface 'position': a camera frame (camera_info) or a q_feedback older than "
    'this makes the controller hold the arm and report which on /ibvs/servo_status; above '
    "the camera's latency (ZED 2: 67-100 ms) and feedback_latency_s", 's', low=0.0,
    high=10.0, low_open=True)
LAMBDA_0 = Param('lambda_0', servo_laws.LAMBDA_0,
                 "servo_law 'ibvs' / 'pbvs': gain lambda at zero error (ViSP's lambda(0); "
                 "'pbvs' uses it as its constant gain); settable at run time", '1/s', low=0.0,
                 high=1000.0, low_open=True, read_only=False)
LAMBDA_INF = Param('lambda_inf', servo_laws.LAMBDA_INF,
                   "servo_law 'ibvs': gain lambda at a very large image error (ViSP's "
                   'lambda(inf)); used only when lambda_slope > 0, then <= lambda_0; settable '
                   'at run time', '1/s', low=0.0, high=1000.0, low_open=True, read_only=False)
LAMBDA_SLOPE = Param('lambda_slope', servo_laws.LAMBDA_SLOPE,
                     "servo_law 'ibvs': ViSP's lambda'(0), how fast the gain falls from "
                     'lambda_0 towards lambda_inf as |p_hat - p_bar| grows; 0: constant '
                     'gain lambda_0; settable at run time', '1/(s px)', low=0.0, high=1000.0,
                     read_only=False)
SWITCH_SETTLE_S = Param('switch_settle_s', servo_laws.SWITCH_SETTLE_S,
                        "servo_law 'switching': the feedback switches on no earlier than "
                        'this after the first frame (the feedforward transient), and only on '
                        'a measured frame with every joint slower than hold_speed_fraction of '
                        'its limit', 's', low=0.0, high=100.0)
FEEDBACK_DESIGN = Param(
    'feedback_design', controllers.FEEDBACK_DESIGNS[0],
    "outer controller k at the camera period: 'sampled' (eq. 37-41 on the ZOH plant: eq. 36 "
    "at the frames) or 'tustin' (k(s) discretised)", '-', choices=controllers.FEEDBACK_DESIGNS)
SVD_RCOND = Param('svd_rcond', controllers.SVD_RCOND,
                  'singular values of C1 below svd_rcond * sigma_1 are not inverted', '-',
                  low=0.0, high=0.1, low_open=True)
SVD_DAMPING = Param('svd_damping', controllers.SVD_DAMPING,
                    'Tikhonov damping of the inverted singular values of C1 (0: exact)',
                    'px/rad', low=0.0, high=100.0)
MAX_CORRECTION_RAD = Param('max_correction_rad', controllers.MAX_CORRECTION_RAD,
                           'trust region of the linearisation: largest correction one '
                           'decoupled channel of C1^+ (p_bar - p_hat) integrates per frame',
                           'rad', low=0.0, high=10.0, low_open=True)
LINEARISE_AT = Param('linearise_at', controllers.LINEARISE_AT,
                     "where C1 (eq. 31) is evaluated: 'encoders' (the encoder angles q_T) or "
                     "'features' (q~ = F^-1(p_hat), the paper's eq. 42; less robust to a wrong "
                     'robot model)', '-', choices=controllers.LINEARISATION_POINTS)
LATENCY_COMPENSATION = Param(
    'latency_compensation', prediction.LATENCY_COMPENSATIONS[0],
    "how the feedback designs for the camera's latency: 'encoders' (the Youla design on "
    'the delayed plant, the Smith predictor: each frame predicted to the time its '
    'q_feedback acts, s(t_e) + F(q(t_a)) - F(q(t_e)), with the encoders of both times; '
    "without latency the paper's law exactly) or 'none' (the paper's law as published, "
    "the frame's own encoder angles)", '-', choices=prediction.LATENCY_COMPENSATIONS)
MODEL_ERROR_TRANSPORT = Param(
    'model_error_transport', prediction.MODEL_ERROR_TRANSPORTS[0],
    "latency_compensation 'internal_model': how a frame's disagreement with the model is "
    "carried to the rest pose, 'image' (unchanged, s(t_e) + F(q_rest) - F(q_e)) or "
    "'joints' (as the encoder offset that explains it, taken from frames with the arm "
    'slower than hold_speed_fraction of its rated speeds and held through the slew)', '-',
    choices=prediction.MODEL_ERROR_TRANSPORTS)
HOLD_SPEED_FRACTION = Param('hold_speed_fraction', controllers.HOLD_SPEED_FRACTION,
                            'the feedback holds (does not integrate) while an encoder joint '
                            'moves faster than this fraction of the speed it is allowed (its '
                            "rated speed; with command_interface 'position' at most "
                            'max_joint_speed_deg_s)', '-',
                            low=0.0, high=10.0, low_open=True)
TORQUE_LIMITS = Param('torque_limits', [0.0] * 6,
                      "'limited' actuators: torque limit per joint; 0 takes the URDF's "
                      'joint effort', 'N m', low=0.0, high=1e6, length=6)
SPEED_MARGIN = Param('speed_margin', controllers.SPEED_MARGIN, "'limited' actuators: the "
                     "governor's speed as a fraction of the IRB 4600 speed limits", '-',
                     low=0.0, high=1.0, low_open=True)
ACCELERATION_MARGIN = Param('acceleration_margin', controllers.ACCELERATION_MARGIN,
                            "'limited' actuators: share of the torque left after h(q, qdot) "
                            'that the governor may use', '-', low=0.0, high=1.0, low_open=True)
DRIVE_ACCELERATION_MARGIN = Param(
    'drive_acceleration_margin', 0.8,
    "command_interface 'position': the share of the drive's acceleration limits the joint "
    "controller's reference is planned with; the rest is the drive's position loop's, to "
    'correct the arm with while it brakes (a plan at the very limits leaves it none: the arm '
    'runs past its stop)', '-', low=0.0, high=1.0, low_open=True)
DRY_RUN = Param(
    'dry_run', False,
    "command_interface 'position': compute the references as always but publish them on "
    '/ibvs/dry_run/commands (joint_trajectory: /ibvs/dry_run/joint_trajectory), never on '
    "the arm's command topic, which is not even opened: the features, the errors and the "
    'references of a cell, the arm still (ibvs cell --dry-run)', '-')
TRAJECTORY_WINDOW_POINTS = Param(
    'trajectory_window_points', 26,
    "position_command_type 'joint_trajectory': points in each JointTrajectory, one every "
    'command period from now (stamped now): the reference now and its shaped course ahead, '
    'so that a controller updating at another rate interpolates instead of holding or '
    "skipping. 26 at 250 Hz: 0.1 s ahead, MoveIt Servo's max_expected_latency; 1: one "
    'point, now', '-', low=1, high=1000)

#: The parameters that go to the servo law's :meth:`.servo_laws.ServoLaw.create` under their
#: names (each law takes those it declares), besides its gain (:func:`check_servo_law`).
LAW_PARAMS = (TAU_IN, OMEGA_N, ZETA, FEEDBACK_DESIGN, SVD_RCOND, SVD_DAMPING, MAX_CORRECTION_RAD,
              HOLD_SPEED_FRACTION, LINEARISE_AT, SWITCH_SETTLE_S, FEATURE_FALLBACK,
              WINDUP_HORIZON_S, JOINT_LIMIT_MARGIN_RAD, SAFETY_ENVELOPE,
              ENVELOPE_SINGULARITY_SCALING)


def allowed_joint_speeds(values: Mapping[str, Any], params: 'RobotParams' = IRB4600
                         ) -> NDArray[np.float64]:
    """
    Return the joint speeds (6,) rad/s the arm is allowed with ``values`` (by name).

    The rated qd_max; with ``command_interface`` 'position', at most
    ``max_joint_speed_deg_s`` as well (the cap the joint controller's shaper and the EGM
    session share). The feedback's hold rule takes its fraction of these.
    """
    rated = np.asarray(params.qd_max, dtype=float)
    if values.get('command_interface') != 'position':
        return rated
    return np.minimum(rated, np.radians(values['max_joint_speed_deg_s']))


def still_speeds(values: Mapping[str, Any], params: 'RobotParams' = IRB4600
                 ) -> NDArray[np.float64]:
    """
    Return the joint speeds (6,) rad/s above which a frame's stamp error shows, ``values``.

    ``hold_speed_fraction`` times the rated qd_max, whatever the cap: what a frame's stamp
    error puts in its disagreement with the model is the joint speed times the error, so
    this is a speed of the arm's, not of the move's (the hold rule's, relative to the
    speeds allowed, is :func:`allowed_joint_speeds`). Faster, the internal model keeps
    its joint offset (:class:`.prediction.Predictor`).
    """
    return values['hold_speed_fraction'] * np.asarray(params.qd_max, dtype=float)


#: The parameters a running feedback node takes from ``ros2 param set`` (checked as at start,
#: the gain rebuilt): the velocity laws' gain. Every other parameter is structural and
#: read-only (its descriptor says so; rclpy refuses a set).
LIVE_PARAMS = (LAMBDA_0, LAMBDA_INF, LAMBDA_SLOPE)


def law_settings(values: Mapping[str, Any]) -> dict[str, Any]:
    """
    Return the values of :data:`LAW_PARAMS` in ``values`` (a mapping by name), by name.

    With ``speed_limits``, the speeds the arm is allowed (:func:`allowed_joint_speeds`), and
    ``own_move``, whether the joint controller makes its own move to the goal
    (:func:`.controllers.makes_own_move`: the position interface, or 'limited' actuators).
    """
    settings = {spec.name: values[spec.name] for spec in LAW_PARAMS}
    settings['speed_limits'] = allowed_joint_speeds(values)
    settings['own_move'] = controllers.makes_own_move(values.get('command_interface', 'effort'),
                                                      values.get('actuators', 'ideal'))
    return settings


def check_gains(values: Mapping[str, Any]) -> None:
    """Raise ParameterError naming 'omega_n' unless 1 / omega_n > tau_in (paper, eq. 36)."""
    try:
        youla.check_bandwidth_rule(values['tau_in'], values['omega_n'])
    except ValueError as exc:
        raise ParameterError(
            f"parameter 'omega_n' = {values['omega_n']!r} is invalid with tau_in = "
            f"{values['tau_in']!r}: {exc}; allowed: omega_n < 1 / tau_in") from None


def check_servo_law(values: Mapping[str, Any]) -> servo_laws.AdaptiveGain:
    """
    Raise ParameterError unless the servo law, its gains and the feedforward agree.

    The law's class says which feedforward_method goes with it
    (:meth:`.servo_laws.ServoLaw.feedforward_problem`); with lambda_slope > 0, lambda_inf
    must not exceed lambda_0 (:class:`.servo_laws.AdaptiveGain`). Return the gain.
    """
    law, method = servo_laws.law_class(values['servo_law']), values['feedforward_method']
    problem = law.feedforward_problem(method)
    if problem is not None:
        raise ParameterError(
            f"parameter 'feedforward_method' = {method!r} is invalid with servo_law = "
            f'{law.name!r}: {problem}')
    try:
        return servo_laws.AdaptiveGain(**{spec.name: values[spec.name]
                                          for spec in (LAMBDA_0, LAMBDA_INF, LAMBDA_SLOPE)})
    except ValueError as exc:
        raise ParameterError(
            f"parameter 'lambda_inf' = {values['lambda_inf']!r} is invalid: {exc}; allowed: "
            'lambda_inf <= lambda_0, or lambda_slope 0') from None


def target_from(values: Mapping[str, Any], params: 'RobotParams' = IRB4600
                ) -> NDArray[np.float64]:
    """
    Return the target pose of 'target_position' / 'target_rotation', checked reachable.

    Built by :func:`ibvs_common.shared_params.target_from_parameters`; raises
    ParameterError naming 'target_rotation' (not a rotation) or 'target_position' (no IK
    branch within the joint limits, eq. 43).
    """
    pose = target_from_parameters(values)
    try:
        controllers.check_reachable(pose, params)
    except ModelError as exc:
        raise ParameterError(f"parameter 'target_position' = {values['target_position']!r} "
                             f'is invalid: unreachable target: {exc}; allowed: a pose with '
                             'an IK branch within the joint limits') from None
    return pose


@dataclass(frozen=True)
class FeedforwardConfig(ParamConfig):
    """The parameters of feedforward_node (each field: the parameter of its name)."""

    #: Rules between parameters, run at start and by ``ibvs run`` before any node starts.
    RULES = (target_from,)

    tau_in: float = param_field(TAU_IN)
    timing: shared.Timing = group_field(shared.Timing)
    target: shared.Target = group_field(shared.Target)
    feedforward_method: str = param_field(FEEDFORWARD_METHOD)
    feedforward_ratio: float = param_field(FEEDFORWARD_RATIO)
    command_interface: str = param_field(shared.COMMAND_INTERFACE)
    actuators: str = param_field(shared.ACTUATORS)


@dataclass(frozen=True)
class AdaptiveFeedbackConfig(ParamConfig):
    """
    The parameters of adaptive_feedback_node: the frame, the target, the servo law's.

    The fields after ``max_joint_speed_deg_s`` are :data:`LAW_PARAMS`, handed to the servo
    law (:meth:`law_settings`).
    """

    #: Rules between parameters, run at start and by ``ibvs run`` before any node starts.
    RULES = (check_gains, check_servo_law, target_from, shared.camera_pose_from)

    timing: shared.Timing = group_field(shared.Timing)
    latency_compensation: str = param_field(LATENCY_COMPENSATION)
    model_error_transport: str = param_field(MODEL_ERROR_TRANSPORT)
    target: shared.Target = group_field(shared.Target)
    servo_law: str = param_field(SERVO_LAW)
    feedforward_method: str = param_field(FEEDFORWARD_METHOD)
    lambda_0: float = param_field(LAMBDA_0)
    lambda_inf: float = param_field(LAMBDA_INF)
    lambda_slope: float = param_field(LAMBDA_SLOPE)
    camera_pose: tuple[float, ...] = param_field(shared.CAMERA_POSE)
    command_interface: str = param_field(shared.COMMAND_INTERFACE)
    actuators: str = param_field(shared.ACTUATORS)
    max_joint_speed_deg_s: float = param_field(shared.MAX_JOINT_SPEED_DEG_S)
    tau_in: float = param_field(TAU_IN)
    omega_n: float = param_field(OMEGA_N)
    zeta: float = param_field(ZETA)
    feedback_design: str = param_field(FEEDBACK_DESIGN)
    svd_rcond: float = param_field(SVD_RCOND)
    svd_damping: float = param_field(SVD_DAMPING)
    max_correction_rad: float = param_field(MAX_CORRECTION_RAD)
    hold_speed_fraction: float = param_field(HOLD_SPEED_FRACTION)
    linearise_at: str = param_field(LINEARISE_AT)
    switch_settle_s: float = param_field(SWITCH_SETTLE_S)
    feature_fallback: str = param_field(FEATURE_FALLBACK)
    windup_horizon_s: float = param_field(WINDUP_HORIZON_S)
    joint_limit_margin_rad: float = param_field(JOINT_LIMIT_MARGIN_RAD)
    safety_envelope: bool = param_field(SAFETY_ENVELOPE)
    envelope_singularity_scaling: bool = param_field(ENVELOPE_SINGULARITY_SCALING)

    def law_settings(self) -> dict[str, Any]:
        """Return the values of :data:`LAW_PARAMS` by name (the servo law's settings)."""
        return law_settings(self.values())


@dataclass(frozen=True)
class JointControllerConfig(ParamConfig):
    """The parameters of joint_controller_node (each field: the parameter of its name)."""

    tau_in: float = param_field(shared.TAU_IN)
    timing: shared.Timing = group_field(shared.Timing)
    actuators: str = param_field(shared.ACTUATORS)
    torque_limits: tuple[float, ...] = param_field(TORQUE_LIMITS)
    speed_margin: float = param_field(SPEED_MARGIN)
    feedforward_method: str = param_field(FEEDFORWARD_METHOD)
    acceleration_margin: float = param_field(ACCELERATION_MARGIN)
    drive_acceleration_margin: float = param_field(DRIVE_ACCELERATION_MARGIN)
    interface: shared.Interface = group_field(shared.Interface)
    joint_state_timeout_s: float = param_field(JOINT_STATE_TIMEOUT_S)
    frame_timeout_s: float = param_field(FRAME_TIMEOUT_S)
    max_joint_speed_deg_s: float = param_field(shared.MAX_JOINT_SPEED_DEG_S)
    trajectory_window_points: int = param_field(TRAJECTORY_WINDOW_POINTS)
    dry_run: bool = param_field(DRY_RUN)

    def __post_init__(self):
        """Check each value (the joints: the interface's), then that no effort run is dry."""
        super().__post_init__()
        if self.interface.lockstep and self.dry_run:
            raise ParameterError("parameter 'dry_run' = True is invalid with command_interface "
                                 "'effort': a dry run is of the position interface (the "
                                 "lockstep's simulator waits for every effort command); "
                                 "allowed: false (or command_interface 'position')")
