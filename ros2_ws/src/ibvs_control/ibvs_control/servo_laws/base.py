"""
The interface of a servo law, and what the velocity laws share (no ROS).

A servo law turns one camera frame (features p_hat, encoder angles q_T and speeds) into a
q_feedback (6,) that the joint controller adds to q_feedforward: q_ref = q_feedforward +
q_feedback. :class:`ServoLaw` declares, on the class, what a law needs from the rest of
the graph (its feedforward, its options, whether it reads /ibvs/feature_status); the
callers (the feedback node, the node parameters, ``ibvs run``, the law report, the
model-only loop) ask the class and never compare names. One sign convention for the
error of every law: e = s - s* (:func:`ibvs_control.controllers.feature_error`; ViSP
vpServo, Chaumette & Hutchinson, IEEE RAM 2006, eq. 1).
"""

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import envelope
from ..controllers import FeedbackUpdate, JOINT_LIMIT_MARGIN_RAD
from ..decoupling import SVD_RCOND

if TYPE_CHECKING:
    from ibvs_model.combined import CameraRobotModel
    from ibvs_model.robot import RobotParams

#: Defaults of the velocity laws' gain (:class:`AdaptiveGain`, 1/s and 1/(s px)).
#: Model-only loop, scenario 1 (|e| = 1840 px at the start): a constant lambda of 4, 6 or
#: 12 / s takes the two markers within 8, 0.8 and 5 px of each other in the image on the
#: way (20 px apart at the start and at the target), where the detector loses them
#: (graph, lambda 12: lost at 0.07 s, the arm stops 1.16 m from the target); this
#: adaptive gain (3 / s far away, 12 / s near) keeps them 18 px apart and is within 1 mm
#: after 1.29 s. PBVS keeps them apart at lambda 12 (1 mm after 0.61 s).
LAMBDA_0 = 12.0
LAMBDA_INF = 3.0
LAMBDA_SLOPE = 0.09
#: What the velocity laws do with a frame whose markers the detector did not find (the
#: feature node then sends the blended or model-estimated features, eq. 46): 'estimate'
#: (default) integrates it as the paper's law does; 'hold' does not (the robot stops, as
#: ViSP's examples do on a lost feature).
FEATURE_FALLBACKS = ('estimate', 'hold')
#: Anti-windup of the velocity laws (:func:`guard_reference`): the joint reference stays
#: within qd_max * WINDUP_HORIZON_S of the encoder angles of the frame (s).
WINDUP_HORIZON_S = 0.2


class ServoLaw:
    """
    The interface of a servo law: declarations on the class, one object per run.

    Class attributes (what the callers ask, never the name):

    name : str
        The ``servo_law`` parameter's value.
    feedforward : dict
        Feedforward parameters the law runs with unless given (``ibvs run``, the law
        report and the model-only loop set them): e.g. ``{'feedforward_method': 'hold'}``.
    without_feedforward : bool
        True: q_feedforward must hold q(0) (feedforward_method 'hold') and the feedback
        carries the whole move; False: the law needs the feedforward ('hold' refused).
    options : tuple of str
        The settings (node parameter names, plus ``gain`` and ``p_target``) that
        :meth:`create` passes to the constructor; others are ignored.
    holding : str
        What /diagnostics says while the law holds q_feedback on a usable frame.

    Instances have ``p_target`` (p_bar, 6 px), ``q_feedback``, ``last`` and
    :meth:`update` / :meth:`reset`.
    """

    name = None
    feedforward = {}
    without_feedforward = False
    options = ()
    holding = 'holding'

    @classmethod
    def create(cls, model: 'CameraRobotModel', pose: ArrayLike, dt: float,
               **settings: Any) -> 'ServoLaw':
        """
        Return the law for ``model``, target ``pose`` and camera period ``dt`` (s).

        With ``safety_envelope`` True in ``settings`` the law comes inside the safety
        envelope (:class:`ibvs_control.envelope.EnvelopedLaw`, same interface; its
        singularity scaling off with ``envelope_singularity_scaling`` False); without it,
        or False, the law itself.
        """
        config = envelope.EnvelopeConfig(
            singularity_scaling=bool(settings.get('envelope_singularity_scaling', True)),
            final_margin_rad=float(settings.get('joint_limit_margin_rad',
                                                JOINT_LIMIT_MARGIN_RAD)))
        return envelope.wrap(cls.build(model, pose, dt, **settings),
                             bool(settings.get('safety_envelope', False)), config)

    @classmethod
    def build(cls, model: 'CameraRobotModel', pose: ArrayLike, dt: float,
              **settings: Any) -> 'ServoLaw':
        """Return the law itself (no envelope) from the settings it declares."""
        return cls(model, pose, dt, **{k: settings[k] for k in cls.options if k in settings})

    @classmethod
    def needs_measured(cls, settings: Mapping[str, Any]) -> bool:
        """Return True when the law needs to know, per frame, whether it was measured."""
        return False

    @classmethod
    def feedforward_method(cls, method: str) -> str:
        """Return the feedforward_method the law runs with when ``method`` is asked."""
        return 'hold' if cls.without_feedforward else method

    @classmethod
    def feedforward_problem(cls, method: str) -> str | None:
        """Return why ``method`` does not go with this law, or None if it does."""
        if cls.without_feedforward and method != 'hold':
            return "that law has no feedforward; allowed: 'hold' (ibvs run sets it for you)"
        if not cls.without_feedforward and method == 'hold':
            return "that law needs the feedforward; allowed: 'sampled', 'tustin' or 'zoh'"
        return None

    def update(self, p_hat: ArrayLike, q_encoder: ArrayLike,
               qdot_encoder: ArrayLike | None = None, measured: bool = True,
               t: float | None = None) -> FeedbackUpdate:
        """Return the :class:`.controllers.FeedbackUpdate` of one frame."""
        raise NotImplementedError

    def reset(self) -> None:
        """Forget the law's state: q_feedback back to 0."""
        raise NotImplementedError


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


def target_features(model: 'CameraRobotModel', pose: NDArray[np.float64],
                    p_target: ArrayLike | None = None) -> NDArray[np.float64]:
    """Return p_bar: ``p_target`` (taught, checked) or the model's F at ``pose`` (eq. 30)."""
    if p_target is not None:
        p_target = np.asarray(p_target, dtype=float).reshape(-1)
        if p_target.shape != (6,) or not np.all(np.isfinite(p_target)):
            raise ValueError('p_target must be 6 finite values (u_l, u_r, v per marker)')
        return p_target
    markers = model.params.fiducials_E @ pose[:3, :3].T + pose[:3, 3]
    return model.camera.project(markers).reshape(6)


def guard_reference(q_ref: ArrayLike, q_encoder: NDArray[np.float64], params: 'RobotParams',
                    windup_horizon_s: float = WINDUP_HORIZON_S,
                    joint_limit_margin_rad: float = JOINT_LIMIT_MARGIN_RAD
                    ) -> tuple[NDArray[np.float64], bool]:
    """
    Return the joint reference kept where the arm can follow it, and whether it was cut.

    1. Anti-windup (integrator clamping, Astrom & Hagglund, Advanced PID Control, 2006,
       3.5): q_ref within q_T +- qd_max * ``windup_horizon_s`` of the encoder angles, i.e.
       never further ahead of the arm than its speed limits cover in that time.
    2. Joint limits: q_ref within [q_min + margin, q_max - margin]
       (``joint_limit_margin_rad``): a clamp, the simpler of the two textbook options. The
       other, ViSP's avoidance term (vpServo::secondaryTaskJointLimitAvoidance, Marey &
       Chaumette, IROS 2010), adds a secondary task through a projection operator of the
       main task; it is not implemented here. A clamped joint can stall the law
       (docs/servo_laws.md).
    """
    q_ref = np.asarray(q_ref, dtype=float)
    lead = np.asarray(params.qd_max, dtype=float) * windup_horizon_s
    guarded = np.clip(q_ref, q_encoder - lead, q_encoder + lead)
    guarded = np.clip(guarded, np.asarray(params.q_min) + joint_limit_margin_rad,
                      np.asarray(params.q_max) - joint_limit_margin_rad)
    return guarded, bool(np.any(guarded != q_ref))


class VelocityLaw(ServoLaw):
    """
    What the velocity laws (classic IBVS, PBVS) share: a joint velocity per frame, integrated.

    Each frame asks a joint velocity; q_feedback sums the joint corrections (that velocity
    over the camera period ``dt``). The feedforward holds q(0) (feedforward_method
    'hold'), so the joint reference is q_ref = q(0) + q_feedback. ``feature_fallback``
    (:data:`FEATURE_FALLBACKS`): 'estimate' integrates every frame the feature node sends,
    measured or estimated, as the paper's law does; 'hold' adds nothing on a frame not
    measured (the robot stops). After each frame q_ref is guarded
    (:func:`guard_reference`: anti-windup against the speed limits, joint limits) and the
    integrator keeps the guarded value. ``svd_rcond`` truncates the SVD of the Jacobian
    the law inverts (:func:`.decoupling.decouple`).
    """

    feedforward = {'feedforward_method': 'hold'}
    without_feedforward = True
    holding = 'holding (markers not measured)'
    options = ('gain', 'svd_rcond', 'p_target', 'feature_fallback', 'windup_horizon_s',
               'joint_limit_margin_rad')

    @classmethod
    def needs_measured(cls, settings: Mapping[str, Any]) -> bool:
        """Return True with feature_fallback 'hold': the law then needs /ibvs/feature_status."""
        return settings.get('feature_fallback', FEATURE_FALLBACKS[0]) == 'hold'

    def __init__(self, model: 'CameraRobotModel', pose: ArrayLike, dt: float,
                 gain: AdaptiveGain | None = None, svd_rcond: float = SVD_RCOND,
                 p_target: ArrayLike | None = None,
                 feature_fallback: str = FEATURE_FALLBACKS[0],
                 windup_horizon_s: float = WINDUP_HORIZON_S,
                 joint_limit_margin_rad: float = JOINT_LIMIT_MARGIN_RAD) -> None:
        """Keep the model, the target pose and p_bar (``p_target`` or F at the pose)."""
        if feature_fallback not in FEATURE_FALLBACKS:
            raise ValueError(f'feature_fallback must be one of {FEATURE_FALLBACKS}, got '
                             f'{feature_fallback!r}')
        if not windup_horizon_s > 0.0 or not joint_limit_margin_rad >= 0.0:
            raise ValueError(f'windup_horizon_s = {windup_horizon_s} must be > 0 and '
                             f'joint_limit_margin_rad = {joint_limit_margin_rad} >= 0')
        self.model = model
        self.pose = np.asarray(pose, dtype=float)
        self.p_target = target_features(model, self.pose, p_target)
        self.dt = float(dt)
        self.gain = AdaptiveGain() if gain is None else gain
        self.svd_rcond = svd_rcond
        self.feature_fallback = feature_fallback
        self.windup_horizon_s = float(windup_horizon_s)
        self.joint_limit_margin_rad = float(joint_limit_margin_rad)
        self._q_feedback = np.zeros(6)
        self.q_start = None
        self.last = None

    @property
    def q_feedback(self) -> NDArray[np.float64]:
        """Return the integrated correction (zeros before the first frame)."""
        return self._q_feedback.copy()

    def q_reference(self, q_encoder: ArrayLike) -> NDArray[np.float64]:
        """Return q(0) + q_feedback, the joint reference; q(0) is the first frame's q_T."""
        if self.q_start is None:
            self.q_start = np.asarray(q_encoder, dtype=float).copy()
        return self.q_start + self._q_feedback

    def _integrate(self, q_encoder, dec, error_norm, correction, measured):
        """Add ``correction`` unless held, guard q_ref; return the frame's FeedbackUpdate."""
        held = not measured and self.feature_fallback == 'hold'
        clipped = False
        if not held:
            q_ref, clipped = guard_reference(
                self.q_reference(q_encoder) + correction, q_encoder, self.model.params,
                self.windup_horizon_s, self.joint_limit_margin_rad)
            self._q_feedback = q_ref - self.q_start
        self.last = FeedbackUpdate(self.q_feedback, q_encoder, dec.s, dec.rank, dec.condition,
                                   error_norm, correction, clipped, held)
        return self.last

    def reset(self) -> None:
        """Forget the integrated correction."""
        self._q_feedback = np.zeros(6)
        self.q_start = None
        self.last = None
