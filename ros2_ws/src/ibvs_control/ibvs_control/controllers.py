"""
The three controllers of the paper's section 4 as plain objects (no ROS, no PyBullet).

- :class:`JointLoop`: inner joint loop, section 4.1: v = G_c(q_ref - q) (sampled eq. 28),
  u = M(q) v + h(q, qdot) (eq. 26) with M and h given by the caller; 'ideal' or 'limited'
  actuators (IRB 4600 speed and torque limits, with anti-windup).
- :class:`Feedforward`: section 4.3: q from the inverse kinematics of the target pose
  (eq. 43), filtered by T_forward (eq. 44-45).
- :class:`AdaptiveFeedback`: section 4.2: C1 = J (eq. 31) at the encoder angles or at
  q~ = F^-1(p_hat) (eq. 42), G_C = C1^+ k (eq. 38-41) updated at every frame.

The ROS nodes and the model-only closed loop (:mod:`.closed_loop`) both use these.
"""

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ibvs_common import shared_params
from ibvs_model import (forward_kinematics, ik_solutions, InvalidInputError,
                        inverse_kinematics, IRB4600, ModelError, pose_error)
from ibvs_model.ik_branch import in_cone, nearest_branch_ik
import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import youla
from .decoupling import decouple, SVD_RCOND
from .filters import StateSpaceFilter
from .governor import JERK_RISE_S, ReferenceGovernor
from .youla import FEEDFORWARD_RATIO

if TYPE_CHECKING:
    from ibvs_model.combined import CameraRobotModel
    from ibvs_model.robot import RobotParams

#: Each default and set of choices below is also that of the control node parameter of
#: the same name (:mod:`.node_params`): one definition.
#: :class:`JointLoop`: the actuators (the shared parameter's choices, the first being the
#: default) and the 'limited' governor's margins.
ACTUATORS = shared_params.ACTUATORS.choices
SPEED_MARGIN = 0.95
ACCELERATION_MARGIN = 0.5
#: :class:`Feedforward`: how T_forward is discretised, the first being the default.
FEEDFORWARD_METHODS = ('sampled', 'tustin', 'zoh', 'hold')
#: :class:`AdaptiveFeedback`: its tuning (``svd_rcond``: :data:`.decoupling.SVD_RCOND`),
#: how k is discretised (the first is the default) and where C1 is evaluated (the encoder
#: angles or F^-1(p_hat)).
SVD_DAMPING = 0.1
MAX_CORRECTION_RAD = 0.05
HOLD_SPEED_FRACTION = 0.2
FEEDBACK_DESIGNS = ('sampled', 'tustin')
LINEARISATION_POINTS = ('encoders', 'features')
LINEARISE_AT = 'encoders'


def check_inputs(p_hat: ArrayLike, q_encoder: ArrayLike
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Return features p_hat and encoder angles as (6,) arrays; InvalidInputError if not."""
    p_hat = np.asarray(p_hat, dtype=float)
    q_encoder = np.asarray(q_encoder, dtype=float)
    if p_hat.shape != (6,) or not np.all(np.isfinite(p_hat)):
        raise InvalidInputError('features must be 6 finite numbers')
    if q_encoder.shape != (6,) or not np.all(np.isfinite(q_encoder)):
        raise InvalidInputError('encoder angles must be 6 finite numbers')
    return p_hat, q_encoder


def feature_error(s: NDArray[np.float64], s_target: NDArray[np.float64]
                  ) -> NDArray[np.float64]:
    """
    Return the error e = s - s* of every servo law (ViSP vpServo, Chaumette & Hutchinson 2006).

    The one sign convention: each law drives e to zero with a correction along -e.
    """
    return s - s_target


def check_reachable(pose: ArrayLike, params: 'RobotParams' = IRB4600) -> None:
    """Raise ibvs_model.UnreachablePoseError when no IK branch reaches ``pose`` (eq. 43)."""
    ik_solutions(pose, params)


class JointLoop:
    """
    Inner joint loop of one robot (section 4.1), one call per physics step.

    v = G_c,d(q_ref - q) (:func:`.youla.inner_controller_discrete`), then eq. (26)
    u = M(q) v + h(q, qdot): 'ideal' actuators (the paper) apply u as it is.

    'limited' actuators (the IRB 4600 speed limits ``qd_max`` and ``torque_limits``):

    1. q_ref, the feedforward's goal plus q_feedback (:func:`makes_own_move`), is
       shaped by a :class:`.governor.ReferenceGovernor` into the time-optimal,
       jerk-limited, synchronised move r toward it, so that the linear loop stays out of
       saturation: speed ``speed_margin`` * qd_max, acceleration ``acceleration_margin`` *
       max(torque_limits - |h|, 0.1 torque_limits) / diag(M), i.e. a share of what the
       torque left after gravity and Coriolis buys on each joint now;
    2. v = r'' + G_c,d(r - q): the move's own acceleration is fed forward (the inverse of
       the double integrator of eq. 27, the part of T_forward a shaped move needs), so the
       loop tracks r without the lag a reference of nonzero acceleration leaves behind a
       G_c alone, and G_c corrects what remains;
    3. v is clipped so that the joint speed after the step stays within qd_max
       (|qdot + v dt| <= qd_max), and u is clipped to +-torque_limits;
    4. anti-windup: the acceleration actually achieved, v_a = M^-1 (u_sat - h), less r'',
       conditions the controller state (Hanus, :class:`.filters.StateSpaceFilter`).
    """

    def __init__(self, tau_in: float, dt: float, actuators: str = ACTUATORS[0],
                 qd_max: ArrayLike = IRB4600.qd_max, torque_limits: ArrayLike | None = None,
                 speed_margin: float = SPEED_MARGIN,
                 acceleration_margin: float = ACCELERATION_MARGIN,
                 synchronised: bool = True) -> None:
        """
        Design G_c,d at sample time ``dt``; limits are needed in 'limited' mode only.

        ``synchronised``: the governor moves the joints together (:func:`synchronised_move`).
        """
        if actuators not in ACTUATORS:
            raise ValueError(f'actuators must be one of {ACTUATORS}, got {actuators!r}')
        self.dt = float(dt)
        self.actuators = actuators
        self.qd_max = np.asarray(qd_max, dtype=float)
        self.torque_limits = (None if torque_limits is None
                              else np.asarray(torque_limits, dtype=float))
        self.acceleration_margin = float(acceleration_margin)
        self.governor = None
        if actuators == 'limited':
            if self.torque_limits is None or self.torque_limits.shape != (6,) \
                    or np.any(self.torque_limits <= 0.0):
                raise ValueError('limited actuators need 6 positive torque limits')
            if not (0.0 < speed_margin <= 1.0 and 0.0 < acceleration_margin <= 1.0):
                raise ValueError('speed and acceleration margins must be in (0, 1]')
            self.governor = ReferenceGovernor(dt, speed_margin * self.qd_max,
                                              jerk_rise_s=JERK_RISE_S,
                                              synchronised=synchronised)
        self.filter = StateSpaceFilter(youla.inner_controller_discrete(tau_in, dt), 6)
        self.saturated = np.zeros(6, dtype=bool)
        self.reference = None

    def reset(self) -> None:
        """Forget the controller state (the governor restarts from the next q)."""
        self.filter.reset()
        self.saturated[:] = False
        self.reference = None
        if self.governor is not None:
            self.governor.state = None

    def step(self, q_ref: ArrayLike, q: ArrayLike, qdot: ArrayLike,
             mass: ArrayLike | None = None, bias: ArrayLike | None = None
             ) -> NDArray[np.float64]:
        """
        Return the joint torques u (6,) for this step and advance G_c one sample.

        ``mass`` M(q) (6, 6) and ``bias`` h(q, qdot) (6,) come from a dynamics model;
        None means the bare double integrator (M = I, h = 0), as in the model-only loop.
        """
        error = np.asarray(q_ref, dtype=float) - np.asarray(q, dtype=float)
        mass = np.eye(6) if mass is None else np.asarray(mass, dtype=float)
        bias = np.zeros(6) if bias is None else np.asarray(bias, dtype=float)
        v = self.filter.output(error)
        if self.actuators == 'ideal':
            self.filter.step(error)
            return mass @ v + bias
        qdot = np.asarray(qdot, dtype=float)
        if self.governor.r is None:
            self.governor.reset(q, qdot)
        spare = np.maximum(self.torque_limits - np.abs(bias), 0.1 * self.torque_limits)
        self.reference = self.governor.step(
            q_ref, self.acceleration_margin * spare / np.abs(np.diag(mass)))
        error = self.reference - np.asarray(q, dtype=float)
        r_acc = self.governor.state[2]
        v = r_acc + self.filter.output(error)
        v_lim = np.clip(v, (-self.qd_max - qdot) / self.dt, (self.qd_max - qdot) / self.dt)
        u = mass @ v_lim + bias
        u_sat = np.clip(u, -self.torque_limits, self.torque_limits)
        torque_hit = u_sat != u
        applied = np.linalg.solve(mass, u_sat - bias) if np.any(torque_hit) else v_lim
        self.saturated = torque_hit | (v_lim != v)
        self.filter.step(error, applied=applied - r_acc)
        return u_sat


def makes_own_move(command_interface: str, actuators: str) -> bool:
    """
    Return whether the joint controller makes the time-optimal move to the goal itself.

    Through the position interface (:class:`.position_interface.PositionShaper`) and with
    'limited' actuators (:class:`JointLoop`) the joint reference is the governor's move
    toward the feedforward's goal (:attr:`Feedforward.goal`) plus q_feedback: the
    feedforward is then its start and goal only (T_forward inverts the ideal inner loop;
    through the governor its reference would only be clipped). With 'ideal' actuators (the
    paper) the reference is T_forward's trajectory.
    """
    return command_interface == 'position' or actuators == 'limited'


def synchronised_move(feedforward_method: str) -> bool:
    """
    Return whether the governor moves the joints together, for ``feedforward_method``.

    A feedforward plans a move to its goal: every joint arrives at once, on the straight
    joint-space line from rest (the paper's law, 'switching'). With 'hold' (the velocity
    laws, 'ibvs' and 'pbvs') there is no move to plan: the reference is the law's stream of
    joint corrections, one per frame, each asked of its joint, and each joint follows its
    own as fast as it can (tied to the slowest, the joints the law asks least of would
    lag what it asked, and its integrator, clamped per joint, would wind the path off).
    """
    return feedforward_method != 'hold'


def limited_time_optimal_s(q_start: ArrayLike, goal: ArrayLike, torque_limits: ArrayLike,
                           qd_max: ArrayLike = IRB4600.qd_max) -> float:
    """
    Return the time-optimal bound (s) of a move with 'limited' actuators, rest to rest.

    The duration of Ruckig's synchronised move from ``q_start`` to ``goal`` (6,) under the
    limits :class:`JointLoop`'s governor plans within, without its margins: ``qd_max``, the
    accelerations ``torque_limits`` buy on the bare double integrator (M = I, h = 0: the
    model loop's plant) and jerk a / :data:`.governor.JERK_RISE_S`. No move of that plant
    from rest reaches ``goal`` sooner with these limits; what the loop takes beyond is the
    excess a benchmark reports (the position interface's bound:
    :func:`.position_interface.time_optimal_s`).
    """
    governor = ReferenceGovernor(1e-3, qd_max, jerk_rise_s=JERK_RISE_S)
    governor.reset(q_start)
    return float(governor.plan(np.asarray(goal, dtype=float), torque_limits).duration)


#: Longest feedforward trajectory (samples): 60 s at 1 kHz. With the paper's values the
#: output of T_forward has settled after about 2 s (Feedforward.trajectory).
MAX_FEEDFORWARD_SAMPLES = 60_000
#: The feedforward has settled when this many samples in a row each moved at most this
#: much (rad): far below what the encoders or the physics resolve.
SETTLED_RAD = 1e-15
SETTLED_SAMPLES = 10
#: ... or once FLOOR_SAMPLES samples in a row have each moved by at most FLOOR_RAD (rad): the
#: filter's rounding floor (:meth:`Feedforward.trajectory`).
FLOOR_RAD = 1e-9
FLOOR_SAMPLES = 2000


class Feedforward:
    """
    Feedforward of section 4.3: q_target = IK(target) (eq. 43) filtered by T_forward.

    Initial condition: :meth:`start` puts the filter at rest at the current joints q0, and
    the target enters as a step right after t = 0: the first :meth:`step` (t = 0) runs the
    filter on q0, so q_ff(0) = q(0) exactly, and every later step on q_target. (Feeding
    the target at t = 0 instead would make q_ff(0) = q0 + D (q_target - q0), D ~ 15 at
    1 kHz: the biproper filter's first answer to a step.)
    ``feedforward_ratio``: T_forward's double pole sits at ``feedforward_ratio`` tau_in
    (eq. 44-45; the paper's 0.1, :data:`.youla.FEEDFORWARD_RATIO`): every joint then
    follows q(t) = q0 + s(t) (q_target - q0) with s the step response of
    ((1 - p_f) / (z - p_f))^2 (z + 1) / 2, the same straight line in joint space for any
    ratio, faster for a smaller one (peak joint speed about 0.37 |q_target - q0| /
    (feedforward_ratio tau_in)).
    ``feedforward_method`` (:data:`FEEDFORWARD_METHODS`): 'sampled' (default,
    :func:`.youla.feedforward_discrete`, the inverse of the sampled inner loop) or 'tustin'
    / 'zoh' (eq. 44 discretised by scipy), or 'hold': no feedforward, q_ff = q(0) at every
    step (the servo laws whose feedback carries the whole move, :mod:`.servo_laws`); the
    target is still checked reachable.
    """

    def __init__(self, pose: ArrayLike, tau_in: float, dt: float,
                 params: 'RobotParams' = IRB4600,
                 feedforward_ratio: float = FEEDFORWARD_RATIO,
                 feedforward_method: str = FEEDFORWARD_METHODS[0]) -> None:
        """Check the target is reachable (eq. 43) and design T_forward at ``dt``."""
        self.pose = np.asarray(pose, dtype=float)
        self.params = params
        check_reachable(self.pose, params)
        if feedforward_method not in FEEDFORWARD_METHODS:
            raise ValueError(f'feedforward_method must be one of {FEEDFORWARD_METHODS}, got '
                             f'{feedforward_method!r}')
        self.hold = feedforward_method == 'hold'
        if feedforward_method in ('sampled', 'hold'):
            design = youla.feedforward_discrete(tau_in, dt, feedforward_ratio)
        else:
            design = youla.feedforward(tau_in, feedforward_ratio).discretise(
                dt, 'bilinear' if feedforward_method == 'tustin' else 'zoh')
        self.filter = StateSpaceFilter(design, 6)
        self.q_target = None
        self.q_start = None

    @property
    def started(self) -> bool:
        """Return True once :meth:`start` has fixed the IK branch."""
        return self.q_target is not None

    @property
    def goal(self) -> NDArray[np.float64]:
        """Return where the feedforward comes to rest: q_target, or q0 for 'hold'."""
        if not self.started:
            raise RuntimeError('Feedforward.start(q0) first')
        return (self.q_start if self.hold else self.q_target).copy()

    def start(self, q0: ArrayLike) -> NDArray[np.float64]:
        """Choose the IK branch of the target (:func:`target_branch`), rest the filter at q0."""
        self.q_start = np.asarray(q0, dtype=float).copy()
        self.q_target = target_branch(self.pose, self.q_start, self.params)
        self.filter.reset(rest_input=self.q_start)
        return self.q_target

    def step(self) -> NDArray[np.float64]:
        """Return q_feedforward for the next sample (the first one is q0; 'hold': all)."""
        if not self.started:
            raise RuntimeError('Feedforward.start(q0) first')
        if self.hold:
            self.filter.steps += 1
            return self.q_start.copy()
        return self.filter.step(self.q_start if self.filter.steps == 0 else self.q_target)

    def trajectory(self, max_samples: int = MAX_FEEDFORWARD_SAMPLES, atol: float = SETTLED_RAD,
                   settled_samples: int = SETTLED_SAMPLES) -> NDArray[np.float64]:
        """
        Return q_feedforward at every physics step from t = 0 until it has settled.

        Row k is the output of sample k (t = k dt, eq. 44-45; row 0 is q0, see the class
        docstring). The filter is stable, linear and time-invariant with a constant input
        after t = 0, so its output converges to its DC gain times q_target; the trajectory
        ends once ``settled_samples`` consecutive samples have each moved by at most
        ``atol`` (rad) on every joint (measured with the paper's values: after 1021 to 1028
        samples in scenarios 1-3, and the filter then stays within 2e-16 rad of its last
        row), or once :data:`FLOOR_SAMPLES` samples in a row have each moved by at most
        :data:`FLOOR_RAD`: with a slower inner loop (tau_in 0.02 and above) rounding in the
        filter's states keeps the samples moving by about 1e-11 rad for ever, and what the
        tail has left to travel by then is far below what the encoders resolve (the
        paper's values end by the first rule, about 500 samples after their moves fell
        below FLOOR_RAD). ``max_samples`` bounds the length in any case.

        The rows are computed in blocks (:meth:`.StateSpaceFilter.held_outputs`: the
        filter's own recurrence for its first 10 s, its closed form for a slow loop's tail)
        and the two rules are checked on each block at once, so that a trajectory of the
        full ``max_samples`` costs milliseconds; the filter has then run on past the
        last row (:meth:`start` again to step it).
        """
        if max_samples < 2:
            raise ValueError(f'max_samples must be >= 2, got {max_samples}')
        if settled_samples < 1:
            raise ValueError(f'settled_samples must be >= 1, got {settled_samples}')
        rows = self.step()[np.newaxis]
        block = 1024
        while True:
            take = min(block, max_samples - len(rows))
            more = (np.tile(self.q_start, (take, 1)) if self.hold
                    else self.filter.held_outputs(self.q_target, take))
            rows = np.concatenate((rows, more))
            end = _settled_length(rows, ((atol, settled_samples), (FLOOR_RAD, FLOOR_SAMPLES)))
            if end is not None or len(rows) >= max_samples:
                return rows[:min(end or max_samples, max_samples)]
            block *= 2

    def pose_error(self) -> tuple[float, float]:
        """Return (m, rad) between FK(q_target) and the target pose: the IK residual."""
        return pose_error(forward_kinematics(self.q_target, self.params), self.pose)


#: The one margin (rad) inside the joint limits: :func:`target_branch` prefers a target
#: branch this far inside them, the velocity laws keep their reference this far inside
#: (``joint_limit_margin_rad``, :mod:`.servo_laws`), and so does the safety envelope's final
#: guarantee (:class:`.envelope.EnvelopeConfig`).
JOINT_LIMIT_MARGIN_RAD = 0.05


def _settled_length(rows: NDArray[np.float64], rules) -> int | None:
    """
    Return the length at which ``rows`` first meets one of ``rules``, else None.

    A rule (limit, count) is met at row i when rows 1 ... i, the last ``count`` of them,
    have each moved by at most ``limit`` (max over columns) from the row before; the
    length is then i + 1 (:meth:`Feedforward.trajectory`).
    """
    moved = np.max(np.abs(np.diff(rows, axis=0)), axis=1)
    ends = []
    for limit, count in rules:
        still = np.concatenate(([0], np.cumsum(moved <= limit)))
        full = np.flatnonzero(still[count:] - still[:-count] == count)
        if full.size:
            ends.append(int(full[0]) + count + 1)
    return min(ends) if ends else None


def target_branch(pose: ArrayLike, q0: ArrayLike, params: 'RobotParams' = IRB4600
                  ) -> NDArray[np.float64]:
    """
    Return the IK branch of ``pose`` the feedforward goes to from ``q0`` (eq. 43).

    The branch nearest ``q0`` inside the reach cone with q0's shoulder and elbow
    (:func:`ibvs_model.ik_branch.nearest_branch_ik`): no arm flip on the way; one at least
    :data:`JOINT_LIMIT_MARGIN_RAD` inside every joint limit if there is one, so that
    the feedforward's straight joint-space line from q0 stays out of that margin (the box
    of the limits is convex), else the nearest in the cone. When q0 is
    itself outside the cone or no such branch exists, the branch nearest q0 whatever it
    is (:func:`ibvs_model.inverse_kinematics`, the former choice). Where the nearest
    branch is inside the cone on q0's arm (the paper's scenarios) both are the same.
    """
    q0 = np.asarray(q0, dtype=float)
    if in_cone(q0, params):
        for margin in (JOINT_LIMIT_MARGIN_RAD, 0.0):
            try:
                return nearest_branch_ik(pose, q0, params, same_arm_as=q0, margin_rad=margin)
            except InvalidInputError:
                raise
            except ModelError:
                pass
    return inverse_kinematics(pose, params, seed=q0)


@dataclass(frozen=True)
class FeedbackUpdate:
    """What one frame of the adaptive feedback computed (for /diagnostics and tests)."""

    q_feedback: np.ndarray
    q_estimate: np.ndarray
    singular_values: np.ndarray
    rank: int
    condition: float
    error_norm: float
    correction: np.ndarray
    clipped: bool
    held: bool


class AdaptiveFeedback:
    """
    Adaptive Youla feedback of section 4.2, one :meth:`update` per camera frame.

    Per frame: the linearisation point (``linearise_at``, below), C1 = J there (eq. 31), its
    SVD (eq. 34, :func:`.decoupling.decouple`), the joint-space correction
    dq = -C1^+ e = C1^+ (p_bar - p_hat) (e = p_hat - p_bar, :func:`feature_error`) and
    q_feedback = k_d(z) dq (eq. 38-41 in the form G_C = C1^+ k). The dynamic part k acts on
    dq, after the time-varying C1^+, so the integrator holds a joint correction that does
    not jump when C1 is updated.
    ``svd_rcond`` and ``svd_damping`` go to :func:`.decoupling.decouple`.
    ``feedback_design``: 'sampled' (default, :func:`.youla.outer_controller_discrete`) or
    'tustin'.

    Linearisation point. The paper evaluates C1 at q~ = F^-1(p_hat) (eq. 42), the angles at
    which the MODEL robot would show the measured features: ``linearise_at='features'``.
    The default 'encoders' evaluates it at the encoder angles q_T, where the robot is. The
    two agree when the model is right (they differ by d_q, 0.5 deg at most in the paper's
    scenarios); with a wrong model (Figure 13) F^-1(p_hat) is the pose of another robot,
    whose joint axes point elsewhere, and the loop gain J_true C1^+ drifts away from the
    identity. q~ is still computed: it checks the features (F^-1 raises on features no pose
    explains) and is reported.

    Model-only loop (:mod:`.closed_loop`), scenario 1, position error after 2 s / 3 s with
    L2 at 50 % and with L4 at 50 %: the two linearisation points against the two trust
    regions (below):

    ==========================  ===================  ====================
    C1 at, trust region          L2 50 % [mm]         L4 50 % [mm]
    ==========================  ===================  ====================
    q~, whole vector scaled      47 / 0.26            24 / 12
    q~, per channel              5.6 / 0.03           64 / 74
    q_T, whole vector scaled     14 / 0.24            136 / 35
    q_T, per channel (default)   0.12 / 0.00          7.4 / 0.25
    ==========================  ===================  ====================

    Two guards keep the sampled loop out of trouble the paper's continuous loop never
    meets (both inactive near the target, where the design of eq. 36 holds unchanged):

    - trust region: C1 describes F only near the linearisation point. Each decoupled
      channel i (eq. 34) asks for c_i = (u_i . e) / sigma_i rad along v_i; a channel that
      asks for more than ``max_correction_rad`` is clipped to it, on its own, as each SISO loop
      of a decoupled design saturates on its own. This matters on the first frame: it sees
      the whole start-to-target error, which the feedforward removes within ~10 ms but which
      a 30 Hz sample would otherwise hold, and integrate, for 33 ms (0.44 m excursion in
      scenario 1 without it). Scaling the whole correction down instead lets one weak
      channel (sigma_5 ~ 2 px/rad, the tool's tilt) throttle all the others, and the
      Figure 13 sweep creeps (table above).
    - conditional integration (anti-windup): while any encoder joint moves faster than
      ``hold_speed_fraction`` times the speed it is allowed (``speed_limits``: the rated
      speed, or the position interface's cap), the arm is still slewing under the
      feedforward and the image error says nothing the feedback should integrate; the
      frame is then not integrated and q_feedback is held. With limited actuators the
      slew takes ~1 s; integrating it overshoots by 0.2 m (model-only loop).
    - the move's own error (``own_move``, where the joint controller makes the time-optimal
      move to the feedforward's goal itself, :func:`makes_own_move`): while the encoders are
      farther than ``max_correction_rad`` (2-norm) from where the joint reference is heading,
      the goal q_T (:func:`target_branch` from the first frame's encoders) plus q_feedback,
      the image error is the planned move's, which the move removes: the frame is held too.
      This holds the frames exposed before the arm starts, which the speed rule cannot tell
      from a finished move (without latency the first two frames of a limited-actuator run:
      integrated, they leave 0.013 rad in the integrator and a 22 mm overshoot on a 0.23 s
      move). With the paper's T_forward (ideal actuators) no such rule: its frames are
      integrated as published.
    """

    def __init__(self, model: 'CameraRobotModel', pose: ArrayLike, tau_in: float,
                 omega_n: float, zeta: float, dt: float, svd_rcond: float = SVD_RCOND,
                 svd_damping: float = SVD_DAMPING, feedback_design: str = FEEDBACK_DESIGNS[0],
                 max_correction_rad: float = MAX_CORRECTION_RAD,
                 hold_speed_fraction: float = HOLD_SPEED_FRACTION,
                 linearise_at: str = LINEARISE_AT, p_target: ArrayLike | None = None,
                 speed_limits: ArrayLike | None = None, own_move: bool = False) -> None:
        """
        Set p_bar and design k.

        p_bar is ``p_target`` (6,) when given (a taught target: features measured with the
        tool at the target pose), else F(q_target), the target markers projected (eq. 30).
        ``speed_limits`` (6,) rad/s: the speeds the arm is allowed, which the hold rule
        takes its fraction of (:func:`.node_params.allowed_joint_speeds`); default the
        model robot's rated qd_max. ``own_move``: the joint controller makes its own move to
        the goal (:func:`makes_own_move`), which the hold rule then leaves to it.
        """
        youla.check_bandwidth_rule(tau_in, omega_n)
        if linearise_at not in LINEARISATION_POINTS:
            raise ValueError(f'linearise_at must be one of {LINEARISATION_POINTS}, got '
                             f'{linearise_at!r}')
        self.linearise_at = linearise_at
        self.model = model
        self.pose = np.asarray(pose, dtype=float)
        markers = model.params.fiducials_E @ self.pose[:3, :3].T + self.pose[:3, 3]
        self.p_target = model.camera.project(markers).reshape(6)
        if p_target is not None:
            p_target = np.asarray(p_target, dtype=float).reshape(-1)
            if p_target.shape != (6,) or not np.all(np.isfinite(p_target)):
                raise ValueError('p_target must be 6 finite values (u_l, u_r, v per marker)')
            self.p_target = p_target
        if feedback_design not in FEEDBACK_DESIGNS:
            raise ValueError(f'feedback_design must be one of {FEEDBACK_DESIGNS}, got '
                             f'{feedback_design!r}')
        if feedback_design == 'sampled':
            k = youla.outer_controller_discrete(tau_in, omega_n, zeta, dt)
        else:
            k = youla.outer_controller(tau_in, omega_n, zeta).discretise(dt, 'bilinear')
        self.filter = StateSpaceFilter(k, 6)
        self.svd_rcond = svd_rcond
        self.svd_damping = svd_damping
        self.max_correction_rad = float(max_correction_rad)
        self.hold_speed_fraction = float(hold_speed_fraction)
        self.speed_limits = np.asarray(model.params.qd_max if speed_limits is None
                                       else speed_limits, dtype=float)
        if self.speed_limits.shape != (6,) or not np.all(self.speed_limits > 0.0):
            raise ValueError(f'speed_limits must be 6 values > 0, got {speed_limits}')
        self.own_move = bool(own_move)
        self.goal = None
        self.last = None

    @property
    def q_feedback(self) -> NDArray[np.float64]:
        """Return the latest output of k (zeros before the first frame)."""
        return self.filter.last_output.copy()

    def update(self, p_hat: ArrayLike, q_encoder: ArrayLike,
               qdot_encoder: ArrayLike | None = None, measured: bool = True,
               t: float | None = None) -> 'FeedbackUpdate':
        """
        Return the :class:`FeedbackUpdate` of one frame and advance k one sample.

        ``measured`` and ``t`` (the frame time) are ignored: the paper's law integrates
        estimated features too (the signature is that of :mod:`.servo_laws`).

        Raises ibvs_model.ModelError (bad features, no triangulation, no IK branch); the
        state is then unchanged and the caller holds the previous q_feedback.
        """
        p_hat, q_encoder = check_inputs(p_hat, q_encoder)
        q_est = self.model.inverse(p_hat, q_encoder[5], seed=q_encoder)
        q_lin = q_est if self.linearise_at == 'features' else q_encoder
        dec = decouple(self.model.jacobian(q_lin), self.svd_rcond, self.svd_damping)
        error = feature_error(p_hat, self.p_target)
        channels = -dec.channels(error)
        clipped = bool(np.any(np.abs(channels) > self.max_correction_rad))
        if clipped:
            channels = np.clip(channels, -self.max_correction_rad, self.max_correction_rad)
        correction = dec.joints(channels)
        held = qdot_encoder is not None and bool(np.any(
            np.abs(qdot_encoder) > self.hold_speed_fraction * self.speed_limits))
        if self.own_move:
            if self.goal is None:
                self.goal = target_branch(self.pose, q_encoder, self.model.params)
            rest = self.goal + self.filter.last_output
            held = held or float(np.linalg.norm(rest - q_encoder)) > self.max_correction_rad
        q_fb = self.filter.last_output.copy() if held else self.filter.step(correction)
        self.last = FeedbackUpdate(q_fb.copy(), q_est, dec.s, dec.rank, dec.condition,
                                   float(np.linalg.norm(error)), correction, clipped, held)
        return self.last

    def reset(self) -> None:
        """Forget the integrator (q_feedback back to 0) and the goal."""
        self.filter.reset()
        self.goal = None
        self.last = None
