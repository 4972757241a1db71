"""
The safety envelope every servo law can run inside (no ROS).

A law turns a frame into q_feedback; :class:`EnvelopedLaw` takes that output and, per
frame, shapes the step it makes (delta = the law's q_feedback less the one last sent):

1. Joint-limit avoidance, the classic laws (``ibvs``, ``pbvs``): the secondary task of
   Marey & Chaumette (IROS 2010) as ViSP computes it,
   ``vpServo::secondaryTaskJointLimitAvoidance`` (lagadic/visp efb30f0,
   ``modules/vs/src/vpServo.cpp`` L1149-1232; defaults rho = 0.1, rho1 = 0.3,
   lambda_tune = 0.7 in ``modules/vs/include/visp3/vs/vpServo.h`` L988-989), projected by
   ViSP's large projection operator (``vpServo::computeProjectionOperators``, L1048-1079:
   P = sig(|e|) P_|e| + (1 - sig) (I - W^+ W), Marey & Chaumette 2010 eq. 24) built from
   the law's Jacobian C1 and error. Before lagadic/visp#1946 (fixed by 8cb03e3 and
   ad2ff38; the former code, e.g. 025247a, tested ``if (b < 1.)``) the task for joint i
   acted only when b = |qdot1_i| / |(P g_i)_i| < 1, so a joint driven hard towards its
   limit switched its own avoidance off. Here, as ViSP after the fix: past q_l1 (zone C1)
   b is not bounded, |qdot2_i| = (1 + lambda_tune) |qdot1_i| >= |qdot1_i| (the paper's
   Section III-B.3 guarantee); between q_l0 and q_l1 (zone C2) b is clamped to 1; a
   vanishing (P g_i)_i gives b = 1.
   The paper's law: its feedforward's joint-space path is a straight line from q(0) to
   q_target (eq. 43-45), inside the box of the joint limits when both ends are (the box
   is convex); the envelope keeps q(0) + q_feedback and q_target + q_feedback inside the
   limits less ``final_margin_rad``, so every reference q_ff + q_fb on the way is too.
2. Singularities: MoveIt Servo's scaling by the condition number kappa of the Jacobian
   (moveit2 jazzy 4d84106, ``moveit_ros/moveit_servo/src/utils/common.cpp`` L282-379,
   ``velocityScalingFactorForSingularity``; ``config/servo_parameters.yaml`` L274-294:
   ``lower_singularity_threshold`` 17, ``hard_stop_singularity_threshold`` 30,
   ``leaving_singularity_threshold_multiplier`` 2): scale 1 below 17, linear to 0 at 30
   when the step raises kappa, to 0 at 17 + 2 (30 - 17) when it lowers it; kappa of the
   robot's geometric Jacobian, as Servo (``robot_state->getJacobian``). Two changes, both
   ours: the direction is kappa after the step against kappa now (Servo probes a step
   along the last singular vector), and a step that lowers kappa is never halted but
   scaled by at least ``leaving_min_scale``: the paper's scenarios 2 and 3 start on the
   wrist singularity (q5 = 0, kappa infinite), where Servo would halt for ever.
3. Collisions: the clearances of :func:`ibvs_model.capsules.clearances` at the encoder
   angles, scaled as MoveIt Servo's collision monitor (jazzy 4d84106,
   ``src/collision_monitor.cpp`` L98-166): exp(k (d - threshold)), k = -ln(0.001) /
   threshold, below ``self_collision_proximity_threshold`` 0.01 m and
   ``scene_collision_proximity_threshold`` 0.02 m (``servo_parameters.yaml`` L244-259);
   halt at contact (d <= 0).
4. The final guarantee: whatever the law and the steps above did, the joint reference
   stays inside [q_min + final_margin_rad, q_max - final_margin_rad].

Every intervention is counted under its :class:`Intervention` code. When none acts the
law's q_feedback goes out unchanged, the same array values (bit-identical runs).
"""

from collections import Counter
from dataclasses import dataclass, replace
from enum import IntEnum
import math
from typing import Any

from ibvs_model import condition_number, ModelError
from ibvs_model.capsules import Cell, clearances
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .controllers import (feature_error, FeedbackUpdate, JOINT_LIMIT_MARGIN_RAD,
                          target_branch)
from .servo_status import ServoStatus

#: ViSP's defaults (vpServo.h): activation at rho of the range from a limit, the critical
#: zone rho * rho1 of the range further, lambda_tune.
RHO = 0.1
RHO1 = 0.3
LAMBDA_TUNE = 0.7
#: ViSP's sigmoid bounds of the large projection operator, |e| in normalised image units
#: (0.1 and 0.7, vpServo::computeProjectionOperators) times the ZED 2's focal length at
#: HD720 (about 685 px, ibvs_model.camera): our error is in pixels.
E0_PX = 68.5
E1_PX = 479.5
#: MoveIt Servo's singularity thresholds and multiplier (module docstring).
LOWER_SINGULARITY_THRESHOLD = 17.0
HARD_STOP_SINGULARITY_THRESHOLD = 30.0
LEAVING_SINGULARITY_THRESHOLD_MULTIPLIER = 2.0
#: Ours: least scale of a step that lowers kappa (module docstring).
LEAVING_MIN_SCALE = 0.1
#: MoveIt Servo's collision proximity thresholds (m).
SELF_COLLISION_PROXIMITY_THRESHOLD = 0.01
SCENE_COLLISION_PROXIMITY_THRESHOLD = 0.02


class Intervention(IntEnum):
    """
    What the envelope did on a frame: MoveIt Servo's codes where they mean the same.

    1-6 are :class:`.servo_status.ServoStatus`'s (MoveIt Servo's StatusCode); 20 and up are
    the envelope's own (the joint controller's are 10-13).
    """

    DECELERATE_FOR_APPROACHING_SINGULARITY = ServoStatus.DECELERATE_FOR_APPROACHING_SINGULARITY
    HALT_FOR_SINGULARITY = ServoStatus.HALT_FOR_SINGULARITY
    DECELERATE_FOR_LEAVING_SINGULARITY = ServoStatus.DECELERATE_FOR_LEAVING_SINGULARITY
    DECELERATE_FOR_COLLISION = ServoStatus.DECELERATE_FOR_COLLISION
    HALT_FOR_COLLISION = ServoStatus.HALT_FOR_COLLISION
    #: The final guarantee cut the reference at the joint range less its margin.
    JOINT_BOUND = ServoStatus.JOINT_BOUND
    #: The joint-limit avoidance task added a velocity.
    JOINT_LIMIT_AVOIDANCE = 20


def singularity_scale(kappa: float, towards: bool,
                      lower: float = LOWER_SINGULARITY_THRESHOLD,
                      hard_stop: float = HARD_STOP_SINGULARITY_THRESHOLD,
                      leaving_multiplier: float = LEAVING_SINGULARITY_THRESHOLD_MULTIPLIER,
                      leaving_min_scale: float = LEAVING_MIN_SCALE
                      ) -> tuple[float, Intervention | None]:
    """
    Return the velocity scale for the condition number ``kappa`` and its code (None: 1).

    MoveIt Servo's rule (module docstring): 1 - (kappa - lower) / (upper - lower) with
    upper = ``hard_stop`` moving towards the singularity, lower + ``leaving_multiplier``
    (hard_stop - lower) leaving it; towards and kappa >= hard_stop: 0 (halt). Leaving,
    the scale is at least ``leaving_min_scale`` (ours).

    Parameters
    ----------
    kappa : float
        Condition number (>= 1, inf allowed).
    towards : bool
        Whether the step raises kappa.
    lower, hard_stop, leaving_multiplier, leaving_min_scale : float
        The thresholds.

    Returns
    -------
    tuple of (float, Intervention or None)

    """
    if not kappa > lower:
        return 1.0, None
    if towards:
        if kappa >= hard_stop:
            return 0.0, Intervention.HALT_FOR_SINGULARITY
        return (1.0 - (kappa - lower) / (hard_stop - lower),
                Intervention.DECELERATE_FOR_APPROACHING_SINGULARITY)
    upper = lower + (hard_stop - lower) * leaving_multiplier
    scale = 1.0 - (kappa - lower) / (upper - lower) if math.isfinite(kappa) else 0.0
    return max(leaving_min_scale, scale), Intervention.DECELERATE_FOR_LEAVING_SINGULARITY


def collision_scale(distance: float, threshold: float) -> float:
    """
    Return MoveIt Servo's collision scale: 1 beyond ``threshold``, 0 at contact.

    exp(k (d - threshold)), k = -ln(0.001) / threshold: 1 at the threshold, 0.001 at
    d = 0 (collision_monitor.cpp L128-131); d <= 0 (a collision) halts.
    """
    if distance >= threshold:
        return 1.0
    if distance <= 0.0:
        return 0.0
    return math.exp(-math.log(0.001) / threshold * (distance - threshold))


def large_projection_operator(jac: ArrayLike, error: ArrayLike, svd_rcond: float = 1e-6,
                              e0: float = E0_PX, e1: float = E1_PX) -> NDArray[np.float64]:
    """
    Return ViSP's large projection operator P (Marey & Chaumette 2010, eq. 24).

    P = sig P_|e| + (1 - sig) (I - W^+ W), P_|e| = I - J^T e e^T J / (e^T J J^T e), sig
    ViSP's sigmoid of |e| between ``e0`` and ``e1`` (vpServo::computeProjectionOperators);
    W^+ W the projector on the row space of J (its singular vectors above ``svd_rcond``).

    Parameters
    ----------
    jac : array_like, shape (m, n)
        The task Jacobian.
    error : array_like, shape (m,)
        The task error.
    svd_rcond : float
        Relative rank threshold.
    e0, e1 : float
        The sigmoid's bounds (units of ``error``).

    Returns
    -------
    ndarray, shape (n, n)

    """
    jac = np.asarray(jac, dtype=float)
    error = np.asarray(error, dtype=float)
    n = jac.shape[1]
    _, s, vt = np.linalg.svd(jac)
    rank = int(np.count_nonzero(s > svd_rcond * s[0])) if s[0] > 0.0 else 0
    i_wpw = np.eye(n) - vt[:rank].T @ vt[:rank]
    norm_e = float(np.linalg.norm(error))
    if norm_e > e1:
        sig = 1.0
    elif norm_e >= e0:
        sig = 1.0 / (1.0 + math.exp(-12.0 * (norm_e - e0) / (e1 - e0) + 6.0))
    else:
        sig = 0.0
    jte = jac.T @ error
    pp = float(jte @ jte)
    if sig == 0.0 or pp <= 0.0:
        return i_wpw
    return sig * (np.eye(n) - np.outer(jte, jte) / pp) + (1.0 - sig) * i_wpw


def joint_limit_avoidance(q: ArrayLike, qdot1: ArrayLike, projector: ArrayLike,
                          q_min: ArrayLike, q_max: ArrayLike, rho: float = RHO,
                          rho1: float = RHO1, lambda_tune: float = LAMBDA_TUNE
                          ) -> NDArray[np.float64]:
    """
    Return the joint-limit avoidance velocity qdot2 of Marey & Chaumette 2010 (ViSP's).

    As ``vpServo::secondaryTaskJointLimitAvoidance`` after lagadic/visp#1946's fix (module
    docstring): per joint i past q_l0 (rho of the range inside a limit), g_i = +-e_i,
    b = |qdot1_i| / |(P g_i)_i| (1 where that vanishes), qdot2 += -w (1 + lambda_tune) b
    P g_i with w = 1 and b unbounded past q_l1 (rho * rho1 of the range further), ViSP's
    sigmoid w and b clamped to 1 between: the task never switches itself off.

    Parameters
    ----------
    q : array_like, shape (n,)
        Joint angles (rad).
    qdot1 : array_like, shape (n,)
        The primary task's joint velocity (rad/s).
    projector : array_like, shape (n, n)
        P (:func:`large_projection_operator`).
    q_min, q_max : array_like, shape (n,)
        Joint limits (rad).
    rho, rho1, lambda_tune : float
        ViSP's parameters (defaults ViSP's).

    Returns
    -------
    ndarray, shape (n,)
        qdot2 (rad/s).

    """
    q, qdot1 = np.asarray(q, dtype=float), np.asarray(qdot1, dtype=float)
    projector = np.asarray(projector, dtype=float)
    q_min, q_max = np.asarray(q_min, dtype=float), np.asarray(q_max, dtype=float)
    span = q_max - q_min
    l0_min, l0_max = q_min + rho * span, q_max - rho * span
    l1_min, l1_max = l0_min - rho * rho1 * span, l0_max + rho * rho1 * span
    out = np.zeros_like(q)
    for i in range(q.size):
        if l0_min[i] < q[i] < l0_max[i]:
            continue
        g = np.zeros_like(q)
        g[i] = -1.0 if q[i] <= l0_min[i] else 1.0
        pg = projector @ g
        b = abs(qdot1[i]) / abs(pg[i]) if abs(pg[i]) >= 10.0 * np.finfo(float).eps else 1.0
        if q[i] < l1_min[i] or q[i] > l1_max[i]:
            weight = 1.0
        else:
            b = min(b, 1.0)
            if q[i] >= l0_max[i]:
                weight = 1.0 / (1.0 + math.exp(-12.0 * (q[i] - l0_max[i])
                                               / (l1_max[i] - l0_max[i]) + 6.0))
            else:
                weight = 1.0 / (1.0 + math.exp(-12.0 * (q[i] - l0_min[i])
                                               / (l1_min[i] - l0_min[i]) + 6.0))
        out -= weight * (1.0 + lambda_tune) * b * pg
    return out


@dataclass(frozen=True)
class EnvelopeConfig:
    """The envelope's settings (module docstring for each; defaults the cited ones)."""

    joint_limit_avoidance: bool = True
    singularity_scaling: bool = True
    rho: float = RHO
    rho1: float = RHO1
    lambda_tune: float = LAMBDA_TUNE
    lower_singularity_threshold: float = LOWER_SINGULARITY_THRESHOLD
    hard_stop_singularity_threshold: float = HARD_STOP_SINGULARITY_THRESHOLD
    leaving_min_scale: float = LEAVING_MIN_SCALE
    self_collision_proximity_threshold: float = SELF_COLLISION_PROXIMITY_THRESHOLD
    scene_collision_proximity_threshold: float = SCENE_COLLISION_PROXIMITY_THRESHOLD
    final_margin_rad: float = JOINT_LIMIT_MARGIN_RAD
    cell: Cell = Cell()

    def __post_init__(self):
        """Check the ranges (ViSP's for rho, rho1, lambda_tune)."""
        if not (0.0 < self.rho <= 0.5 and 0.0 < self.rho1 <= 1.0
                and 0.0 <= self.lambda_tune <= 1.0):
            raise ValueError('envelope: rho in ]0, 0.5], rho1 in ]0, 1], lambda_tune in '
                             f'[0, 1]; got {self.rho}, {self.rho1}, {self.lambda_tune}')
        if not 1.0 <= self.lower_singularity_threshold < self.hard_stop_singularity_threshold:
            raise ValueError('envelope: need 1 <= lower_singularity_threshold < '
                             'hard_stop_singularity_threshold')
        if not (0.0 <= self.leaving_min_scale <= 1.0 and self.final_margin_rad >= 0.0
                and self.self_collision_proximity_threshold > 0.0
                and self.scene_collision_proximity_threshold > 0.0):
            raise ValueError('envelope: leaving_min_scale in [0, 1], final_margin_rad >= 0, '
                             'collision thresholds > 0')


class EnvelopedLaw:
    """
    A servo law inside the safety envelope: the same interface, the output shaped.

    ``law``: a :class:`.servo_laws.ServoLaw`. Its class attributes and instance
    attributes are read through (``p_target``, ``name``, ...). ``counts``: frames per
    :class:`Intervention`; ``codes``: those of the last frame. For a velocity law (its
    feedforward holds q(0)) the shaped q_feedback is written back into its integrator, so
    that it integrates from what was sent; the paper's law keeps its filter's state (its
    output is a filter's, not an integral the envelope can set).
    """

    def __init__(self, law: Any, config: EnvelopeConfig = EnvelopeConfig()) -> None:
        """Wrap ``law``; nothing sent yet."""
        self.law = law
        # the law that holds the model and the target ('switching' wraps the paper's)
        self.core = law if hasattr(law, 'model') else law.feedback
        self.config = config
        self.counts = Counter()
        self.codes = ()
        self._sent = None
        self._ends = None

    def __getattr__(self, name: str) -> Any:
        """Read anything else from the law."""
        if name == 'law':  # not set yet (copy, unpickling): no recursion
            raise AttributeError(name)
        return getattr(self.law, name)

    @property
    def q_feedback(self) -> NDArray[np.float64]:
        """Return the q_feedback last sent (the law's before the first frame)."""
        return self.law.q_feedback if self._sent is None else self._sent.copy()

    def reset(self) -> None:
        """Reset the law and forget what was sent (the counts stay)."""
        self.law.reset()
        self._sent = None
        self._ends = None

    def _path_ends(self, q_encoder):
        """Return the joint-space ends the feedforward goes between (q(0), its target)."""
        if self._ends is None:
            params = self.core.model.params
            if getattr(self.law, 'without_feedforward', False):
                self._ends = np.asarray(q_encoder, dtype=float).copy()[None]
            else:
                q0 = np.asarray(q_encoder, dtype=float).copy()
                # the feedforward's own choice (controllers.Feedforward.start)
                self._ends = np.stack([q0, target_branch(self.core.pose, q0, params)])
        return self._ends

    def update(self, p_hat: ArrayLike, q_encoder: ArrayLike,
               qdot_encoder: ArrayLike | None = None, measured: bool = True,
               t: float | None = None) -> FeedbackUpdate:
        """Return the law's :class:`.controllers.FeedbackUpdate` with the shaped q_feedback."""
        cfg = self.config
        law = self.law
        velocity_law = getattr(law, 'without_feedforward', False)
        ends = self._path_ends(q_encoder)
        if velocity_law and getattr(law, 'q_start', None) is not None:
            ends = np.asarray(law.q_start, dtype=float)[None]
        prev = law.q_feedback if self._sent is None else self._sent
        update = law.update(p_hat, q_encoder, qdot_encoder, measured, t)
        if velocity_law and law.q_start is not None:
            ends = np.asarray(law.q_start, dtype=float)[None]
        wanted = np.asarray(update.q_feedback, dtype=float)
        delta = wanted - prev
        q = np.asarray(q_encoder, dtype=float)
        params = self.core.model.params
        q_min, q_max = np.asarray(params.q_min), np.asarray(params.q_max)
        codes = []
        changed = False
        if np.any(delta != 0.0):
            dt = float(getattr(law, 'dt', 0.0) or 0.0)
            if velocity_law and cfg.joint_limit_avoidance and dt > 0.0:
                error = feature_error(np.asarray(p_hat, dtype=float).reshape(6), law.p_target)
                try:
                    projector = large_projection_operator(law.model.jacobian(q), error)
                except ModelError:  # no image Jacobian here (a marker behind the camera)
                    projector = np.eye(q.size)
                qdot2 = joint_limit_avoidance(q, delta / dt, projector, q_min, q_max,
                                              cfg.rho, cfg.rho1, cfg.lambda_tune)
                if np.any(qdot2 != 0.0):
                    delta = delta + qdot2 * dt
                    codes.append(Intervention.JOINT_LIMIT_AVOIDANCE)
                    changed = True
            kappa = condition_number(q) if cfg.singularity_scaling else 1.0
            scale, code = 1.0, None
            if kappa > cfg.lower_singularity_threshold:
                towards = condition_number(q + delta) > kappa
                scale, code = singularity_scale(
                    kappa, towards, cfg.lower_singularity_threshold,
                    cfg.hard_stop_singularity_threshold, leaving_min_scale=cfg.leaving_min_scale)
            if code is not None:
                codes.append(code)
            self_d, scene_d, _ = clearances(q, cfg.cell, params)
            c_scale = min(collision_scale(self_d, cfg.self_collision_proximity_threshold),
                          collision_scale(scene_d, cfg.scene_collision_proximity_threshold))
            if c_scale < 1.0:
                codes.append(Intervention.HALT_FOR_COLLISION if c_scale == 0.0
                             else Intervention.DECELERATE_FOR_COLLISION)
            scale = min(scale, c_scale)
            if scale < 1.0:
                delta = delta * scale
                changed = True
        out = prev + delta if changed else wanted
        low = q_min + cfg.final_margin_rad - ends.min(axis=0)
        high = q_max - cfg.final_margin_rad - ends.max(axis=0)
        bounded = np.minimum(np.maximum(out, low), high)
        if np.any(bounded != out):
            codes.append(Intervention.JOINT_BOUND)
            out, changed = bounded, True
        if changed and velocity_law:
            law._q_feedback = out.copy()
        self._sent = out.copy()
        self.codes = tuple(codes)
        self.counts.update(codes)
        if not changed:
            return update
        update = replace(update, q_feedback=out.copy(), clipped=True)
        law.last = update
        return update


def wrap(law: Any, enabled: bool, config: EnvelopeConfig | None = None) -> Any:
    """Return ``law`` inside the envelope when ``enabled``, else ``law`` itself."""
    return EnvelopedLaw(law, config or EnvelopeConfig()) if enabled else law
