"""
Servo laws beside the paper's: classic IBVS, PBVS and a switching scheme (no ROS).

Each law turns one camera frame (features p_hat, encoder angles q_T and speeds) into a
q_feedback (6,) that the joint controller adds to q_feedforward: q_ref = q_feedforward +
q_feedback (joint_controller_node, unchanged). Which feedforward goes with which law:

===========  ===========================================  ===================================
law          q_feedforward (``feedforward_method``)        q_feedback
===========  ===========================================  ===================================
paper        T_forward IK(target), eq. 43-45               k(z) C1^+ (p_bar - p_hat), eq. 38-41
switching    T_forward IK(target), eq. 43-45, slower (*)   0 until the switch, then as paper
ibvs         q(0), held ('hold')                            integral of -lambda C1^+ e
pbvs         q(0), held ('hold')                            integral of J^-1 (-lambda e_pose)
===========  ===========================================  ===================================

(*) ``feedforward_ratio`` :data:`SWITCHING_FEEDFORWARD_RATIO` instead of the paper's 0.1
(:func:`feedforward_overrides`).

For ibvs and pbvs the feedforward holds the initial joints, so q_feedback carries the whole
move from q(0): q_ref = q(0) + sum of the velocity commands times the camera period. The
velocity command of a frame acts on the joint reference through the inner loop (eq. 29),
whose lag (3 tau = 30 ms) is short against 1 / lambda.

The laws take ``measured`` (the detector found both markers in both images) with each frame:
ibvs and pbvs hold still when it is False (ViSP's examples stop the robot when a feature is
lost), so from scenarios 2 and 3 (markers out of view at the start) they do not move; the
switching law waits for it before its feedback starts.
"""

from dataclasses import dataclass

from ibvs_model import geometric_jacobian, InvalidInputError
import numpy as np

from .controllers import AdaptiveFeedback, check_inputs, FeedbackUpdate, FEEDFORWARD_METHODS
from .decoupling import decouple, SVD_RCOND

SERVO_LAWS = ('paper', 'ibvs', 'pbvs', 'switching')
#: Laws whose q_feedforward holds q(0) (feedforward_method 'hold').
WITHOUT_FEEDFORWARD = ('ibvs', 'pbvs')
#: Defaults of the gain (:class:`AdaptiveGain`, 1/s and 1/(s px)) and of the switch.
#: Model-only loop, scenario 1 (|e| = 1840 px at the start): a constant lambda of 4, 6 or
#: 12 / s takes the two markers within 8, 0.8 and 5 px of each other in the image on the
#: way (20 px apart at the start and at the target), where the detector loses them
#: (graph, lambda 12: lost at 0.07 s, the arm stops 1.16 m from the target); this
#: adaptive gain (3 / s far away, 12 / s near) keeps them 18 px apart and is within 1 mm
#: after 1.29 s. PBVS keeps them apart at lambda 12 (1 mm after 0.61 s).
LAMBDA_0 = 12.0
LAMBDA_INF = 3.0
LAMBDA_SLOPE = 0.09
#: The switching law's wait (s) and T_forward double pole, in tau_in (``feedforward_ratio``;
#: the paper: 0.1). Before the switch the feedforward alone moves the arm, and the paper's
#: 1 ms joint response asks up to 1.2e3 rad/s and ~1e6 rad/s^2, which the simulated arm
#: does not follow (graph, ideal actuators, 47 / 18 / 27 mm overshoot in scenarios 1 / 2 / 3,
#: all of it before the switch, against 0.1 / 1.8 / 2.3 mm model-only): PyBullet clamps
#: joint speeds at 100 rad/s (Bullet's default maxJointVelocity), so the arm lags the
#: reference by up to 159 deg and overshoots when it catches up. (With the clamp lifted,
#: an experiment: 44 / 1.8 / 125 mm, since the computed torque evaluates M and h at the
#: encoder angles, d_q off the true ones in scenarios 1 and 3.) A double pole at
#: 2 tau_in = 20 ms (at most ~60 rad/s, 400 times less acceleration) is followed; the
#: feedforward is then within 1 mm after about 0.2 s, and a switch before that would let
#: the feedback integrate the feedforward's own transient. (At 1 tau_in, without the
#: clamp, scenario 3 overshot 9.3 mm; at 3 tau_in the switch waits for the joints to slow
#: down until 0.23 s and the tool is within 1 mm after 0.55-0.57 s.)
SWITCH_SETTLE_S = 0.2
SWITCHING_FEEDFORWARD_RATIO = 2.0
#: Sub-steps of the PBVS integration over one camera period (:class:`PBVS`).
SUBSTEPS = 10


def feedforward_overrides(law):
    """
    Return the feedforward parameters that go with ``law``.

    ``ibvs run`` and the report set them unless given: feedforward_method 'hold' for ibvs
    and pbvs, feedforward_ratio :data:`SWITCHING_FEEDFORWARD_RATIO` for switching, none for
    paper.
    """
    if law not in SERVO_LAWS:
        raise ValueError(f'servo_law must be one of {SERVO_LAWS}, got {law!r}')
    if law in WITHOUT_FEEDFORWARD:
        return {'feedforward_method': 'hold'}
    return {'feedforward_ratio': SWITCHING_FEEDFORWARD_RATIO} if law == 'switching' else {}


def feedforward_method_for(law, feedforward_method=FEEDFORWARD_METHODS[0]):
    """Return the feedforward_method that goes with ``law``: 'hold' for ibvs and pbvs."""
    if law not in SERVO_LAWS:
        raise ValueError(f'servo_law must be one of {SERVO_LAWS}, got {law!r}')
    return 'hold' if law in WITHOUT_FEEDFORWARD else feedforward_method


@dataclass(frozen=True)
class AdaptiveGain:
    """
    ViSP's adaptive gain (vpAdaptiveGain): lambda(x) = a exp(-b x) + c, x = |e|.

    With lambda_0 = lambda(0), lambda_inf = lambda(inf) and the slope lambda'_0 =
    ``lambda_slope`` at 0:
    a = lambda_0 - lambda_inf, b = lambda'_0 / a, c = lambda_inf, i.e.
    lambda(x) = (lambda_0 - lambda_inf) exp(-lambda'_0 x / (lambda_0 - lambda_inf)) + lambda_inf.
    ``lambda_slope`` 0 (lambda_inf is then unused) or lambda_0 = lambda_inf gives the
    constant gain lambda_0 of the classic law
    (Chaumette & Hutchinson, IEEE RAM 2006, eq. 4; Corke, Robotics, Vision and Control, 15.2).
    A large error gets the small gain lambda_inf, a small one the large lambda_0.
    """

    lambda_0: float = LAMBDA_0
    lambda_inf: float = LAMBDA_INF
    lambda_slope: float = LAMBDA_SLOPE

    def __post_init__(self):
        """Check lambda_0 > 0, lambda_slope >= 0 and, if > 0, 0 < lambda_inf <= lambda_0."""
        if not self.lambda_0 > 0.0 or not self.lambda_slope >= 0.0:
            raise ValueError(f'adaptive gain needs lambda_0 = {self.lambda_0} > 0 and '
                             f'lambda_slope = {self.lambda_slope} >= 0')
        if self.lambda_slope > 0.0 and not 0.0 < self.lambda_inf <= self.lambda_0:
            raise ValueError(f'adaptive gain needs 0 < lambda_inf = {self.lambda_inf} <= '
                             f'lambda_0 = {self.lambda_0} when lambda_slope = '
                             f'{self.lambda_slope} > 0')

    def __call__(self, error_norm):
        """Return lambda(|e|) (1/s)."""
        a = self.lambda_0 - self.lambda_inf
        if a <= 0.0 or self.lambda_slope == 0.0:
            return float(self.lambda_0)
        return float(a * np.exp(-self.lambda_slope * float(error_norm) / a) + self.lambda_inf)


def _target_features(model, pose, p_target=None):
    """Return p_bar: ``p_target`` (taught, checked) or the model's F at ``pose`` (eq. 30)."""
    if p_target is not None:
        p_target = np.asarray(p_target, dtype=float).reshape(-1)
        if p_target.shape != (6,) or not np.all(np.isfinite(p_target)):
            raise ValueError('p_target must be 6 finite values (u_l, u_r, v per marker)')
        return p_target
    markers = model.params.fiducials_E @ pose[:3, :3].T + pose[:3, 3]
    return model.camera.project(markers).reshape(6)


class VelocityLaw:
    """
    What the velocity laws (:class:`ClassicIBVS`, :class:`PBVS`) share.

    Each frame asks a joint velocity; q_feedback sums the joint corrections (that velocity
    over the camera period ``dt``) of the measured frames. A frame not measured adds
    nothing: q_feedback is held (the robot stops). ``svd_rcond`` truncates the SVD of the
    Jacobian the law inverts (:func:`.decoupling.decouple`).
    """

    def __init__(self, model, pose, dt, gain, svd_rcond, p_target):
        """Keep the model, the target pose and p_bar (``p_target`` or F at the pose)."""
        self.model = model
        self.pose = np.asarray(pose, dtype=float)
        self.p_target = _target_features(model, self.pose, p_target)
        self.dt = float(dt)
        self.gain = AdaptiveGain() if gain is None else gain
        self.svd_rcond = svd_rcond
        self._q_feedback = np.zeros(6)
        self.last = None

    @property
    def q_feedback(self):
        """Return the integrated correction (zeros before the first frame)."""
        return self._q_feedback.copy()

    def _integrate(self, q_encoder, dec, error_norm, correction, measured):
        """Add ``correction`` if ``measured``; return the frame's FeedbackUpdate."""
        if measured:
            self._q_feedback = self._q_feedback + correction
        self.last = FeedbackUpdate(self.q_feedback, q_encoder, dec.s, dec.rank, dec.condition,
                                   error_norm, correction, False, not measured)
        return self.last

    def reset(self):
        """Forget the integrated correction."""
        self._q_feedback = np.zeros(6)
        self.last = None


class ClassicIBVS(VelocityLaw):
    """
    Classic IBVS, integrated at the camera rate: q_feedback += T qdot, one frame at a time.

    qdot = -lambda(|e|) C1^+ e, e = p_hat - p_bar (ViSP vpServo::computeControlLaw with the
    eye-to-hand task L_s J_robot; Chaumette & Hutchinson 2006, eq. 4; Corke, Robotics,
    Vision and Control, eq. 15.11). Here L_s J_robot is our stereo C1 = dF/dq (eq. 31) at
    the encoder angles: both cameras' image Jacobians of both markers times the robot's
    point Jacobians; its truncated/damped pseudo-inverse (:func:`.decoupling.decouple` with
    ``svd_rcond`` and ``svd_damping``, rank 5) leaves q6 alone. For small errors e decays
    as exp(-lambda t). No trust region: the law is the textbook one. Not measured:
    q_feedback is held (the robot stops).
    """

    def __init__(self, model, pose, dt, gain=None, svd_rcond=SVD_RCOND, svd_damping=0.0,
                 p_target=None):
        """
        Project the target markers (p_bar = F(q_target), eq. 30); ``dt`` the camera period.

        ``p_target``: a taught p_bar (6,) instead (the features measured at the target).
        """
        super().__init__(model, pose, dt, gain, svd_rcond, p_target)
        self.svd_damping = svd_damping

    def update(self, p_hat, q_encoder, qdot_encoder=None, measured=True, t=None):
        """Return the :class:`.controllers.FeedbackUpdate` of one frame."""
        p_hat, q_encoder = check_inputs(p_hat, q_encoder)
        error = p_hat - self.p_target
        dec = decouple(self.model.jacobian(q_encoder), self.svd_rcond, self.svd_damping)
        norm = float(np.linalg.norm(error))
        correction = -self.gain(norm) * self.dt * (dec.pinv @ error)
        return self._integrate(q_encoder, dec, norm, correction, measured)


def tool_from_markers(camera, p_hat):
    """
    Return the flange position (3,) and the unit tool axis (3,) in {O} from the features.

    Both markers are triangulated (inverse of eq. 19-22); P1 is the flange origin and
    P2 - P1 points along z6 (section 3.1), as in F^-1 (eq. 42).
    """
    points = camera.triangulate(np.asarray(p_hat, dtype=float).reshape(2, 3))
    axis = points[1] - points[0]
    norm = np.linalg.norm(axis)
    if norm < 1e-6:
        raise InvalidInputError('p_image: both fiducials triangulate to the same point')
    return points[0], axis / norm


def axis_error(axis, axis_target):
    """
    Return theta u (3,): the rotation (angle-axis, rad) that takes ``axis`` to ``axis_target``.

    u = a x a* / |a x a*|, theta = atan2(|a x a*|, a . a*): the shortest rotation, about an
    axis normal to both, so it never asks a roll about the tool axis (unobservable).
    """
    cross = np.cross(axis, axis_target)
    sin = np.linalg.norm(cross)
    if sin < 1e-12:
        return np.zeros(3)
    return cross / sin * np.arctan2(sin, float(np.dot(axis, axis_target)))


class PBVS(VelocityLaw):
    """
    Position-based visual servoing of the flange point and the tool axis, in {O}.

    From the triangulated markers (:func:`tool_from_markers`): the position error
    e_t = t - t* and the axis error theta u (:func:`axis_error`, toward the target axis).
    The classic PBVS law (Chaumette & Hutchinson 2006, eq. 24-25 with the frame {O} as
    reference; Corke, Robotics, Vision and Control, eq. 15.3) asks the flange velocity
    v = -lambda e_t and the angular velocity omega = lambda theta u, mapped to joints by
    the robot's geometric Jacobian at the encoder angles, qdot = J(q)^+ [v; omega]
    (SVD truncated at ``svd_rcond``, undamped: ``svd_damping`` is in px/rad, J's units are
    m/rad and 1), and integrated at the camera rate: the twist of a frame is held over the
    camera period and integrated in ``substeps`` steps with J updated along the way. The
    flange then moves on the straight line from where it is to t* (dt/dt = -lambda e_t),
    whatever the image does.
    The gain is constant (``gain.lambda_0``): |e| mixes metres and radians.
    Not measured: q_feedback is held.
    """

    def __init__(self, model, pose, dt, gain=None, svd_rcond=SVD_RCOND, substeps=SUBSTEPS,
                 p_target=None):
        """
        Keep the target flange position and axis; ``dt`` the camera period.

        ``p_target``: taught features (6,) at the target; the target position and axis are
        then triangulated from them (:func:`tool_from_markers`), as a taught PBVS does.
        """
        super().__init__(model, pose, dt, gain, svd_rcond, p_target)
        self.substeps = int(substeps)
        self.q_start = None
        if p_target is None:
            self.t_target = self.pose[:3, 3].copy()
            self.axis_target = self.pose[:3, 2].copy()
        else:
            self.t_target, self.axis_target = tool_from_markers(model.camera, self.p_target)

    def pose_error(self, p_hat):
        """Return e = [t - t*, -theta u] (6,) of the measured features (m, rad)."""
        position, axis = tool_from_markers(self.model.camera, p_hat)
        return np.concatenate([position - self.t_target,
                               -axis_error(axis, self.axis_target)])

    def update(self, p_hat, q_encoder, qdot_encoder=None, measured=True, t=None):
        """Return the :class:`.controllers.FeedbackUpdate` of one frame."""
        p_hat, q_encoder = check_inputs(p_hat, q_encoder)
        error = self.pose_error(p_hat)
        twist = -self.gain.lambda_0 * np.concatenate([error[:3], error[3:]])
        # The frame's twist, held over the camera period, integrated in sub-steps with J
        # re-evaluated on the way (model FK only): one Euler step of T would bend the path
        # by O((lambda T |e|)^2) (22 mm off the line from scenario 1 with lambda = 1 / s).
        if self.q_start is None:
            self.q_start = q_encoder.copy()
        q_ref = self.q_start + self._q_feedback
        correction = np.zeros(6)
        for _ in range(self.substeps):
            dec = decouple(geometric_jacobian(q_ref + correction, self.model.params),
                           self.svd_rcond)
            correction = correction + self.dt / self.substeps * (dec.pinv @ twist)
        return self._integrate(q_encoder, dec, float(np.linalg.norm(error)), correction,
                               measured)


class Switching:
    """
    Feedforward alone, then the paper's feedback: a switch that happens once, bumplessly.

    Until the switch q_feedback = 0, so q_ref = q_feedforward (eq. 43-45) exactly. The
    switch comes at the first frame that (1) is measured (both markers found by the
    detector, not estimated by eq. 46), (2) is at least ``switch_settle_s`` after the first
    frame (the feedforward's transient: with ideal actuators and the switching law's
    ``feedforward_ratio`` 2 the arm is within 1 mm of q_target's pose after ~0.2 s) and
    (3) sees every encoder joint slower than ``hold_speed_fraction`` times its speed limit (with
    limited actuators the slew takes ~1 s). From that frame on the
    :class:`.controllers.AdaptiveFeedback` of the paper runs, its integrator starting at
    rest: q_feedback starts at k_d's direct feedthrough D times the first correction (D =
    omega_n^2 tau^2 / 3 ~ 3e-3 for the paper's numbers), so the joint reference does not
    jump. Skipped before the switch: the frames that the paper's feedback integrates
    while the feedforward still moves the arm (the first one sees the whole start-to-target
    error). The feedforward before the switch is the paper's T_forward with its double pole
    at ``feedforward_ratio`` tau_in (:data:`SWITCHING_FEEDFORWARD_RATIO`, set by
    :func:`feedforward_overrides`), slow enough for the simulated arm to follow.
    """

    def __init__(self, feedback, switch_settle_s=SWITCH_SETTLE_S):
        """Wrap an :class:`.controllers.AdaptiveFeedback`; ``switch_settle_s`` in seconds."""
        if not isinstance(feedback, AdaptiveFeedback):
            raise TypeError('feedback must be an AdaptiveFeedback')
        if switch_settle_s < 0.0:
            raise ValueError(f'switch_settle_s = {switch_settle_s} s must be >= 0')
        self.feedback = feedback
        self.p_target = feedback.p_target
        self.switch_settle_s = float(switch_settle_s)
        self.t0 = None
        self.switched_at = None
        self.last = None

    @property
    def q_feedback(self):
        """Return the feedback's output (zeros before the switch)."""
        return self.feedback.q_feedback

    def ready(self, t, qdot_encoder, measured):
        """Return True when the frame at ``t`` (s) may switch the feedback on."""
        if not measured or t - self.t0 < self.switch_settle_s:
            return False
        limit = self.feedback.hold_speed_fraction * np.asarray(self.feedback.model.params.qd_max)
        return qdot_encoder is None or bool(np.all(np.abs(qdot_encoder) <= limit))

    def update(self, p_hat, q_encoder, qdot_encoder=None, measured=True, t=None):
        """
        Return the :class:`.controllers.FeedbackUpdate` of one frame.

        ``t``: the frame's time (s), needed; ``measured``: the detector found both
        markers in both images this frame.
        """
        if t is None:
            raise ValueError('the switching law needs the frame time t')
        if self.t0 is None:
            self.t0 = float(t)
        if self.switched_at is None and self.ready(float(t), qdot_encoder, measured):
            self.switched_at = float(t)
        if self.switched_at is not None:
            self.last = self.feedback.update(p_hat, q_encoder, qdot_encoder)
            return self.last
        p_hat, q_encoder = check_inputs(p_hat, q_encoder)
        error = self.feedback.p_target - p_hat
        self.last = FeedbackUpdate(self.q_feedback, q_encoder, np.zeros(6), 0, float('inf'),
                                   float(np.linalg.norm(error)), np.zeros(6), False, True)
        return self.last

    def reset(self):
        """Back to feedforward alone."""
        self.feedback.reset()
        self.t0 = None
        self.switched_at = None
        self.last = None


#: The options of :func:`make_law` that each law without feedforward takes.
LAW_OPTIONS = {'ibvs': ('svd_rcond', 'svd_damping', 'p_target'),
               'pbvs': ('svd_rcond', 'p_target')}


def make_law(law, model, pose, tau_in, omega_n, zeta, dt, gain=None,
             switch_settle_s=SWITCH_SETTLE_S, **feedback_options):
    """
    Return the servo law ``law`` (one of :data:`SERVO_LAWS`) at camera period ``dt``.

    ``feedback_options`` go to :class:`.controllers.AdaptiveFeedback` (paper, switching);
    ibvs and pbvs take those of :data:`LAW_OPTIONS` only (``p_target``: a taught p_bar,
    see each class), the others keep their defaults.
    """
    if law not in SERVO_LAWS:
        raise ValueError(f'servo_law must be one of {SERVO_LAWS}, got {law!r}')
    if law in WITHOUT_FEEDFORWARD:
        options = {name: feedback_options[name] for name in LAW_OPTIONS[law]
                   if name in feedback_options}
        return (PBVS if law == 'pbvs' else ClassicIBVS)(model, pose, dt, gain, **options)
    feedback = AdaptiveFeedback(model, pose, tau_in, omega_n, zeta, dt, **feedback_options)
    return feedback if law == 'paper' else Switching(feedback, switch_settle_s)
