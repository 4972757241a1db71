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

from dataclasses import dataclass

from ibvs_common.timing import period_ns
from ibvs_model import CameraRobotModel, default_model, inverse_kinematics, ModelError, paper
import numpy as np

from .controllers import (ACTUATORS, FEEDBACK_DESIGNS, Feedforward, FEEDFORWARD_METHODS,
                          FEEDFORWARD_RATIO, HOLD_SPEED_FRACTION, JointLoop, LINEARISE_AT,
                          MAX_CORRECTION_RAD, SVD_DAMPING, SVD_RCOND)
from .feedback_lockstep import FeedbackLockstep
from .servo_laws import (FEATURE_FALLBACKS, JOINT_LIMIT_MARGIN_RAD, law_class, SERVO_LAWS,
                         SWITCH_SETTLE_S, WINDUP_HORIZON_S)


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

    @property
    def image_error(self):
        """Return |p_bar - p_hat| (px) at each frame (Euclidean norm over the 6 values)."""
        return np.linalg.norm(self.features - self.p_target, axis=1)

    def final_image_error(self):
        """Return the image error (px) of F(true angles) at the end of the run."""
        return float(np.linalg.norm(self.model.features(self.q_true[-1]) - self.p_target))


def _accepted(rejection):
    """Raise if the lockstep refused an input: the loop feeds it every one in order."""
    if rejection is not None:
        raise RuntimeError(f'lockstep refused an input: {rejection.reason} ({rejection.detail})')


def simulate(scenario=1, duration_s=2.0, physics_rate_hz=1000.0, camera_rate_hz=30.0,
             tau_in=paper.TAU_IN, omega_n=paper.OMEGA_N, zeta=paper.ZETA,
             feedback_latency_s=0.0, disturbance=None, actuators=ACTUATORS[0], model=None,
             plant_params=None, torque_limits=None, estimate_out_of_view=True,
             feedforward_method=FEEDFORWARD_METHODS[0], feedback_design=FEEDBACK_DESIGNS[0],
             svd_rcond=SVD_RCOND, svd_damping=SVD_DAMPING,
             max_correction_rad=MAX_CORRECTION_RAD, hold_speed_fraction=HOLD_SPEED_FRACTION,
             target=None, integration='exact', linearise_at=LINEARISE_AT,
             servo_law=SERVO_LAWS[0], gain=None, switch_settle_s=SWITCH_SETTLE_S,
             feedforward_ratio=None,
             feature_fallback=FEATURE_FALLBACKS[0], windup_horizon_s=WINDUP_HORIZON_S,
             joint_limit_margin_rad=JOINT_LIMIT_MARGIN_RAD, plant_camera=None,
             target_features_source='model', feature_noise_px=0.0, seed=0):
    """
    Run the model-only loop of a paper scenario and return a :class:`LoopResult`.

    The arguments named as node parameters (README) mean what those parameters mean.

    ``model``: the controllers' F (default :func:`ibvs_model.default_model`);
    ``plant_params``: the true robot (default the model's; e.g. ``IRB4600.scaled(l2, l4)``
    for Figure 13); ``plant_camera``: the true camera, which makes the features (default
    the model's; another one is a calibration error). ``target_features_source``: 'model'
    (p_bar = the model's F at the target, eq. 30) or 'taught' (p_bar = the true features
    of the true robot at the target, as the feature node measures them on the teach
    pair). ``feature_noise_px``: the standard deviation of Gaussian noise added to each
    measured feature (px, independent per value and frame;
    ``numpy.random.default_rng(seed)``), a stand-in for the detector's error, not rendered
    image noise. ``disturbance``: d_q (rad), default the scenario's. The start is the
    scenario pose (true angles: IK with seed 0, as the simulator does). Out of view, the
    features are the estimate F(encoder angles) (eq. 46) when ``estimate_out_of_view``.
    'limited' actuators with the bare double integrator (M = I, h = 0) take
    ``torque_limits`` as the acceleration limits (rad/s^2). ``integration``: 'exact'
    (zero-order hold of the acceleration over a step: the continuous arm) or 'semi-implicit'
    (qd += a dt, then q += qd dt: how PyBullet steps the simulated arm; use it to compare
    with the graph).
    ``linearise_at``: where the feedback evaluates C1 (:class:`.controllers.AdaptiveFeedback`).
    ``servo_law``: one of :data:`.servo_laws.SERVO_LAWS`; the law's class says its
    feedforward (ibvs and pbvs: held at q(0), 'hold'); ``gain``
    (:class:`.servo_laws.AdaptiveGain`), ``feature_fallback``, ``windup_horizon_s`` and
    ``joint_limit_margin_rad`` are theirs, ``switch_settle_s`` the switching law's. A frame
    is 'measured' when both markers are in view of the true robot. ``feedforward_ratio``:
    T_forward's double pole in tau_in, default the law's (its ``feedforward``: 2 for
    switching, else the paper's 0.1).
    """
    law = law_class(servo_law)
    model = default_model() if model is None else model
    plant = CameraRobotModel(model.camera if plant_camera is None else plant_camera,
                             model.params if plant_params is None else plant_params)
    if target_features_source not in ('model', 'taught'):
        raise ValueError("target_features_source must be 'model' or 'taught', got "
                         f'{target_features_source!r}')
    d_q = paper.scenario_disturbance(scenario) if disturbance is None \
        else np.asarray(disturbance, dtype=float)
    pose = paper.target_pose() if target is None else np.asarray(target, dtype=float)
    dt_ns = period_ns(physics_rate_hz)
    cam_ns = period_ns(camera_rate_hz)
    if cam_ns < dt_ns:
        raise ValueError('the camera rate must not exceed the physics rate')
    latency_ns = int(round(feedback_latency_s * 1e9))
    if integration not in ('exact', 'semi-implicit'):
        raise ValueError(f"integration must be 'exact' or 'semi-implicit', got {integration!r}")
    semi_implicit = integration == 'semi-implicit'
    dt = dt_ns * 1e-9

    q_true0 = inverse_kinematics(paper.scenario_start_pose(scenario), plant.params)
    q = q_true0 - d_q
    qd = np.zeros(6)
    joint = JointLoop(tau_in, dt, actuators, plant.params.qd_max, torque_limits)
    if feedforward_ratio is None:
        feedforward_ratio = law.feedforward.get('feedforward_ratio', FEEDFORWARD_RATIO)
    ff = Feedforward(pose, tau_in, dt, model.params, feedforward_ratio=feedforward_ratio,
                     feedforward_method=law.feedforward_method(feedforward_method))
    q_target = ff.start(q)
    fb = law.create(model, pose, cam_ns * 1e-9, tau_in=tau_in, omega_n=omega_n, zeta=zeta,
                    gain=gain, switch_settle_s=switch_settle_s, svd_rcond=svd_rcond,
                    svd_damping=svd_damping, feedback_design=feedback_design,
                    max_correction_rad=max_correction_rad,
                    hold_speed_fraction=hold_speed_fraction, linearise_at=linearise_at,
                    feature_fallback=feature_fallback, windup_horizon_s=windup_horizon_s,
                    joint_limit_margin_rad=joint_limit_margin_rad,
                    p_target=plant.features(inverse_kinematics(pose, plant.params, seed=q_target))
                    if target_features_source == 'taught' else None)

    steps = int(round(duration_s * 1e9 / dt_ns)) + 1
    rec = {k: np.empty((steps, 6)) for k in ('q', 'q_ff', 'q_fb')}
    frames_t, frames_p, frames_measured = [], [], []
    # The joint controller's rule: q_feedback = 0 until the first frame acts.
    lockstep = FeedbackLockstep(cam_ns, latency_ns, dt_ns, initial=np.zeros(6))
    rng = np.random.default_rng(seed)
    next_frame = 0
    rejected = 0
    for k in range(steps):
        t_ns = k * dt_ns
        while next_frame * cam_ns <= t_ns:
            q_now = q + d_q
            measured = bool(np.all(plant.in_view(q_now)))
            p_hat = plant.features(q_now) if measured or not estimate_out_of_view \
                else model.features(q)
            if measured and feature_noise_px > 0.0:
                p_hat = p_hat + rng.normal(0.0, feature_noise_px, 6)
            try:
                q_feedback = fb.update(p_hat, q, qd, measured=measured,
                                       t=t_ns * 1e-9).q_feedback
            except ModelError:
                # As the node: a frame F^-1 cannot use is rejected, q_feedback held.
                q_feedback = fb.q_feedback
                rejected += 1
            # as the simulator stamps it: the time of this step
            _accepted(lockstep.offer_feedback(t_ns, q_feedback))
            frames_t.append(t_ns * 1e-9)
            frames_p.append(p_hat)
            frames_measured.append(measured)
            next_frame += 1
        _accepted(lockstep.offer_state(t_ns, None))
        _, _, q_fb = lockstep.pop_ready()  # every frame has its q_feedback: never waits
        q_ff = ff.step()
        rec['q'][k], rec['q_ff'][k], rec['q_fb'][k] = q, q_ff, q_fb
        acc = joint.step(q_ff + q_fb, q, qd)
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
        p_target=fb.p_target, q_target=q_target, model=plant, rejected_frames=rejected)
