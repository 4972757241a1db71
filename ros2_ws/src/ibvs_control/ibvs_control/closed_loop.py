"""
Model-only closed loop of the paper's Figure 3 (no ROS, no PyBullet).

Plant: per joint the double integrator of eq. (27) (the feedback-linearised arm, sampled
exactly with a zero-order hold) closed by the sampled G_c of :class:`.JointLoop`, which
gives the inner loop of eq. (29); true angles = encoder angles + d_q (the paper's input
disturbance); image features p_hat = F(true angles) (eq. 30) at the camera rate. The
feedforward and the adaptive feedback run as in the nodes, with the same timing rule
(ibvs_common.timing.feedback_frame_ns, the contract's own, free of rclpy): integer
nanosecond stamps, physics step
k at k * dt, camera frame n due at n * camera_period, taken at the first physics step at or
after it and stamped with that step's time, and its q_feedback acting from
``feedback_latency_s`` after the frame. Which q_feedback acts at a step is decided by the
joint controller's own lockstep, :class:`.feedback_lockstep.FeedbackLockstep`.

This is the reference the node graph (PyBullet, rendering, Hough) is compared against.
"""

from collections import deque
from dataclasses import asdict, dataclass, field
from typing import Any, TYPE_CHECKING

from ibvs_common import shared_params
from ibvs_common.params import param_field, ParamConfig
from ibvs_common.timing import (check_camera_rate, feedback_action_ns, period_ns,
                                seconds_to_ns)
from ibvs_model import CameraRobotModel, default_model, inverse_kinematics, ModelError, paper
import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import node_params
from .controllers import Feedforward, JointLoop, makes_own_move, synchronised_move
from .feedback_lockstep import FeedbackLockstep
from .prediction import Predictor
from .servo_laws import AdaptiveGain, feedforward_overrides, law_class

if TYPE_CHECKING:
    from ibvs_model.camera import StereoCamera
    from ibvs_model.robot import RobotParams


@dataclass(frozen=True)
class LoopConfig(ParamConfig):
    """
    The node parameters the model-only loop runs with, each declared once as a Param.

    Each field means what the parameter of the same name means to the nodes (README); each
    value is checked against its Param at construction, and the combinations the nodes
    check at start are checked here too (ParameterError naming the parameter):
    omega_n < 1 / tau_in (:func:`.node_params.check_gains`), a feedforward_method that goes
    with the servo law and lambda_inf <= lambda_0 (:func:`.node_params.check_servo_law`).
    ``torque_limits``: with 'limited' actuators and the bare double integrator (M = I,
    h = 0), the acceleration limits (rad/s^2); 0 does not take the URDF's here.
    """

    scenario: int = param_field(shared_params.SCENARIO)
    start_joints: tuple[float, ...] = param_field(shared_params.START_JOINTS)
    physics_rate_hz: float = param_field(shared_params.PHYSICS_RATE_HZ)
    camera_rate_hz: float = param_field(shared_params.CAMERA_RATE_HZ)
    feedback_latency_s: float = param_field(shared_params.FEEDBACK_LATENCY_S)
    tau_in: float = param_field(shared_params.TAU_IN)
    omega_n: float = param_field(shared_params.OMEGA_N)
    zeta: float = param_field(shared_params.ZETA)
    actuators: str = param_field(shared_params.ACTUATORS)
    torque_limits: tuple[float, ...] = param_field(node_params.TORQUE_LIMITS)
    speed_margin: float = param_field(node_params.SPEED_MARGIN)
    acceleration_margin: float = param_field(node_params.ACCELERATION_MARGIN)
    target_features_source: str = param_field(shared_params.TARGET_FEATURES_SOURCE)
    servo_law: str = param_field(node_params.SERVO_LAW)
    feedforward_method: str = param_field(node_params.FEEDFORWARD_METHOD)
    feedforward_ratio: float = param_field(node_params.FEEDFORWARD_RATIO)
    lambda_0: float = param_field(node_params.LAMBDA_0)
    lambda_inf: float = param_field(node_params.LAMBDA_INF)
    lambda_slope: float = param_field(node_params.LAMBDA_SLOPE)
    feedback_design: str = param_field(node_params.FEEDBACK_DESIGN)
    svd_rcond: float = param_field(node_params.SVD_RCOND)
    svd_damping: float = param_field(node_params.SVD_DAMPING)
    max_correction_rad: float = param_field(node_params.MAX_CORRECTION_RAD)
    hold_speed_fraction: float = param_field(node_params.HOLD_SPEED_FRACTION)
    linearise_at: str = param_field(node_params.LINEARISE_AT)
    latency_compensation: str = param_field(node_params.LATENCY_COMPENSATION)
    model_error_transport: str = param_field(node_params.MODEL_ERROR_TRANSPORT)
    switch_settle_s: float = param_field(node_params.SWITCH_SETTLE_S)
    feature_fallback: str = param_field(node_params.FEATURE_FALLBACK)
    windup_horizon_s: float = param_field(node_params.WINDUP_HORIZON_S)
    joint_limit_margin_rad: float = param_field(node_params.JOINT_LIMIT_MARGIN_RAD)
    safety_envelope: bool = param_field(node_params.SAFETY_ENVELOPE)
    envelope_singularity_scaling: bool = param_field(node_params.ENVELOPE_SINGULARITY_SCALING)

    def __post_init__(self):
        """Check each value against its Param, then the combinations (class docstring)."""
        super().__post_init__()
        values = asdict(self)
        node_params.check_gains(values)
        node_params.check_servo_law(values)

    @property
    def gain(self) -> AdaptiveGain:
        """Return the :class:`.servo_laws.AdaptiveGain` of lambda_0, lambda_inf, lambda_slope."""
        return AdaptiveGain(self.lambda_0, self.lambda_inf, self.lambda_slope)

    @classmethod
    def for_law(cls, servo_law: str, **values: Any) -> 'LoopConfig':
        """
        Return the config of ``servo_law`` with the feedforward that goes with it.

        As ``ibvs run`` sets it (:func:`.servo_laws.feedforward_overrides`: 'hold' for
        'ibvs' and 'pbvs', ratio 2 for 'switching'); ``values`` override the rest.
        """
        return cls(servo_law=servo_law, **{**feedforward_overrides(servo_law), **values})


@dataclass
class LoopResult:
    """Time histories of one model-only run (arrays, SI units, rad and px)."""

    t: np.ndarray
    q: np.ndarray
    q_true: np.ndarray
    q_feedforward: np.ndarray
    q_feedback: np.ndarray
    frame_t: np.ndarray
    features: np.ndarray
    measured: np.ndarray
    p_target: np.ndarray
    q_target: np.ndarray
    model: CameraRobotModel
    rejected_frames: int = 0
    #: Frames lost (``frame_drop_probability``): the law not updated, q_feedback held.
    dropped_frames: int = 0
    #: The safety envelope's interventions, frames per code (``envelope.Intervention``'s
    #: value): empty without the envelope.
    interventions: dict = field(default_factory=dict)

    @property
    def image_error(self) -> NDArray[np.float64]:
        """Return |p_bar - p_hat| (px) at each frame (Euclidean norm over the 6 values)."""
        return np.linalg.norm(self.features - self.p_target, axis=1)

    def final_image_error(self) -> float:
        """Return the image error (px) of F(true angles) at the end of the run."""
        return float(np.linalg.norm(self.model.features(self.q_true[-1]) - self.p_target))


def _answer(fb, frame, q, qd, predictor, lockstep, counts):
    """
    Answer one pending frame at its action time, with the encoders ``q``, ``qd`` of then.

    As the feedback node answers it: a lost frame with the held q_feedback (the joint
    controller holds it on the simulator's notice), a frame F^-1 cannot use likewise
    (counted as rejected); else the law's update on what the ``predictor``
    (:class:`.prediction.Predictor`) makes of the frame and the encoders of then.
    """
    t_ns, _, p_hat, q_e, qd_e, measured, lost = frame
    if lost:
        q_feedback = fb.q_feedback
        counts['dropped'] += 1
    else:
        try:
            p_hat, q_e, qd_e = predictor.inputs(fb.q_feedback, p_hat, q_e, qd_e, q, qd,
                                                measured=measured)
            q_feedback = fb.update(p_hat, q_e, qd_e, measured=measured,
                                   t=t_ns * 1e-9).q_feedback
        except ModelError:
            q_feedback = fb.q_feedback
            counts['rejected'] += 1
    # as the simulator stamps it: the frame's exposure step
    _accepted(lockstep.offer_feedback(t_ns, q_feedback))


def _accepted(rejection):
    """Raise if the lockstep refused an input: the loop feeds it every one in order."""
    if rejection is not None:
        raise RuntimeError(f'lockstep refused an input: {rejection.reason} ({rejection.detail})')


def simulate(config: LoopConfig = LoopConfig(), duration_s: float = 2.0, *,
             model: CameraRobotModel | None = None, plant_params: 'RobotParams | None' = None,
             plant_camera: 'StereoCamera | None' = None, disturbance: ArrayLike | None = None,
             target: ArrayLike | None = None, integration: str = 'exact',
             estimate_out_of_view: bool = True, feature_noise_px: float = 0.0,
             seed: int = 0, frame_drop_probability: float = 0.0,
             target_noise_px: float = 0.0, stamp_error_s: float = 0.0) -> LoopResult:
    """
    Run the model-only loop of a paper scenario and return a :class:`LoopResult`.

    Parameters
    ----------
    config : LoopConfig
        The node parameters (scenario, rates, gains, servo law, ...), checked there.
    duration_s : float
        Sim time to run (s).
    model : CameraRobotModel, optional
        The controllers' F (default :func:`ibvs_model.default_model`).
    plant_params : RobotParams, optional
        The true robot (default the model's; e.g. ``IRB4600.scaled(l2, l4)`` for Figure 13).
    plant_camera : StereoCamera, optional
        The true camera, which makes the features (default the model's; another one is a
        calibration error).
    disturbance : array_like, optional
        d_q (rad), default the scenario's.
    target : array_like, optional
        The target flange pose T_E^O (default :func:`ibvs_model.paper.target_pose`).
    integration : {'exact', 'semi-implicit'}
        'exact': zero-order hold of the acceleration over a step (the continuous arm);
        'semi-implicit': qd += a dt, then q += qd dt, how PyBullet steps the simulated arm
        (use it to compare with the graph).
    estimate_out_of_view : bool
        Out of view, the features are the estimate F(encoder angles) (eq. 46).
    feature_noise_px : float
        Standard deviation of Gaussian noise added to each measured feature (px,
        independent per value and frame; ``numpy.random.default_rng(seed)``), a stand-in
        for the detector's error, not rendered image noise.
    seed : int
        Seed of that noise.
    frame_drop_probability : float
        Probability that a frame is lost, in [0, 1): the law is not updated and its last
        q_feedback is held, as the joint controller holds it on the simulator's notice of a
        lost frame (docs/camera.md). Drawn from ``numpy.random.default_rng([seed, 1])``
        (nothing drawn when 0).
    target_noise_px : float
        With a taught target: standard deviation of Gaussian noise on the taught p_bar (px),
        the detector's error on the one teach pair; drawn once from
        ``numpy.random.default_rng([seed, 2])`` (nothing drawn when 0).
    stamp_error_s : float
        How much later than its exposure a frame is stamped (s, either sign: a camera whose
        stamps are off by a constant, or a latency the prediction gets wrong): the frame's
        encoder angles are those of its stamp, rounded to a step (and at most the step it
        is answered at); when it acts does not change.

    Notes
    -----
    ``target_features_source`` 'model': p_bar = the model's F at the target (eq. 30);
    'taught': p_bar = the true features of the true robot at the target, as the feature
    node measures them on the teach pair. The start is the scenario pose (true angles: IK
    with seed 0, as the simulator does). A frame is 'measured' when both markers are in
    view of the true robot. The feedforward runs with ``config.feedforward_method`` as the
    law takes it (:meth:`.servo_laws.ServoLaw.feedforward_method`); the law (eq. 38-41 for
    'paper') gets the gains and options of ``config``. Raises ValueError for a camera rate
    above the physics rate (a combination no single Param refuses) or another
    ``integration``.

    """
    law = law_class(config.servo_law)
    model = default_model() if model is None else model
    plant = CameraRobotModel(model.camera if plant_camera is None else plant_camera,
                             model.params if plant_params is None else plant_params)
    d_q = paper.scenario_disturbance(config.scenario) if disturbance is None \
        else np.asarray(disturbance, dtype=float)
    pose = paper.target_pose() if target is None else np.asarray(target, dtype=float)
    dt_ns = period_ns(config.physics_rate_hz)
    cam_ns = period_ns(config.camera_rate_hz)
    check_camera_rate(config.camera_rate_hz, config.physics_rate_hz)
    latency_ns = seconds_to_ns(config.feedback_latency_s)
    if not 0.0 <= frame_drop_probability < 1.0:
        raise ValueError(f'frame_drop_probability must be in [0, 1), got '
                         f'{frame_drop_probability}')
    if integration not in ('exact', 'semi-implicit'):
        raise ValueError(f"integration must be 'exact' or 'semi-implicit', got {integration!r}")
    semi_implicit = integration == 'semi-implicit'
    dt = dt_ns * 1e-9

    q_true0 = shared_params.start_joints(config.start_joints)
    if q_true0 is None:
        q_true0 = inverse_kinematics(paper.scenario_start_pose(config.scenario), plant.params)
    q = q_true0 - d_q
    qd = np.zeros(6)
    feedforward_method = law.feedforward_method(config.feedforward_method)
    joint = JointLoop(config.tau_in, dt, config.actuators, plant.params.qd_max,
                      config.torque_limits, speed_margin=config.speed_margin,
                      acceleration_margin=config.acceleration_margin,
                      synchronised=synchronised_move(feedforward_method))
    ff = Feedforward(pose, config.tau_in, dt, model.params,
                     feedforward_ratio=config.feedforward_ratio,
                     feedforward_method=feedforward_method)
    q_target = ff.start(q)
    # Limited actuators: the joint loop makes the time-optimal move to the goal itself.
    goal = ff.goal if makes_own_move('effort', config.actuators) else None
    taught = shared_params.taught(config.values())
    p_taught = None
    if taught:
        p_taught = plant.features(inverse_kinematics(pose, plant.params, seed=q_target))
        if target_noise_px > 0.0:
            p_taught = p_taught + np.random.default_rng([seed, 2]).normal(
                0.0, target_noise_px, 6)
    fb = law.create(model, pose, cam_ns * 1e-9, gain=config.gain, p_target=p_taught,
                    **node_params.law_settings(asdict(config)))

    steps = int(round(duration_s * 1e9 / dt_ns)) + 1
    rec = {k: np.empty((steps, 6)) for k in ('q', 'qd', 'q_ff', 'q_fb')}
    error_steps = int(round(stamp_error_s * 1e9 / dt_ns))
    frames_t, frames_p, frames_measured = [], [], []
    # The joint controller's rule: q_feedback = 0 until the first frame acts.
    lockstep = FeedbackLockstep(cam_ns, latency_ns, dt_ns, initial=np.zeros(6))
    rng = np.random.default_rng(seed)
    drops = np.random.default_rng([seed, 1]) if frame_drop_probability > 0.0 else None
    predictor = Predictor(config.latency_compensation, model, pose,
                          node_params.still_speeds(asdict(config)),
                          config.model_error_transport)
    next_frame = 0
    # Frames taken and not yet answered: (stamp, action time, p_hat, q, qd, measured, lost),
    # answered at their action time (feedback_action_ns), when their q_feedback starts to act.
    pending = deque()
    counts = {'rejected': 0, 'dropped': 0}
    for k in range(steps):
        t_ns = k * dt_ns
        while next_frame * cam_ns <= t_ns:
            q_now = q + d_q
            measured = bool(np.all(plant.in_view(q_now)))
            p_hat = plant.features(q_now) if measured or not estimate_out_of_view \
                else model.features(q)
            if measured and feature_noise_px > 0.0:
                p_hat = p_hat + rng.normal(0.0, feature_noise_px, 6)
            lost = drops is not None and drops.random() < frame_drop_probability
            pending.append((t_ns, feedback_action_ns(t_ns, latency_ns, dt_ns), p_hat, q, qd,
                            measured, lost))
            if not lost:
                frames_t.append(t_ns * 1e-9)
                frames_p.append(p_hat)
                frames_measured.append(measured)
            next_frame += 1
        while pending and pending[0][1] <= t_ns:
            frame = pending.popleft()
            if error_steps:
                i = min(max(frame[0] // dt_ns + error_steps, 0), k)
                frame = frame[:3] + ((rec['q'][i], rec['qd'][i]) if i < k else (q, qd)) \
                    + frame[5:]
            _answer(fb, frame, q, qd, predictor, lockstep, counts)
        _accepted(lockstep.offer_state(t_ns, None))
        _, _, q_fb = lockstep.pop_ready()  # every frame has its q_feedback: never waits
        q_ff = ff.step()
        rec['q'][k], rec['qd'][k], rec['q_ff'][k], rec['q_fb'][k] = q, qd, q_ff, q_fb
        acc = joint.step((q_ff if goal is None else goal) + q_fb, q, qd)
        if semi_implicit:
            qd = qd + acc * dt
            q = q + qd * dt
        else:
            q = q + qd * dt + 0.5 * acc * dt * dt
            qd = qd + acc * dt
    return LoopResult(
        t=np.arange(steps) * dt, q=rec['q'], q_true=rec['q'] + d_q,
        q_feedforward=rec['q_ff'], q_feedback=rec['q_fb'], frame_t=np.array(frames_t),
        features=np.array(frames_p), measured=np.array(frames_measured),
        p_target=fb.p_target, q_target=q_target, model=plant,
        rejected_frames=counts['rejected'], dropped_frames=counts['dropped'],
        interventions={int(code): int(n) for code, n in getattr(fb, 'counts', {}).items()})
