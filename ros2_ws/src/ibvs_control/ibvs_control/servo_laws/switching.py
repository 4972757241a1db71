"""Feedforward alone, then the paper's feedback: the switching law (no ROS)."""

from collections.abc import Mapping
from typing import Any, TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .base import ServoLaw
from .paper import Paper
from ..controllers import AdaptiveFeedback, check_inputs, feature_error, FeedbackUpdate

if TYPE_CHECKING:
    from ibvs_model.combined import CameraRobotModel

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


class Switching(ServoLaw):
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
    at ``feedforward_ratio`` tau_in (:data:`SWITCHING_FEEDFORWARD_RATIO`, the class's
    ``feedforward``), slow enough for the simulated arm to follow.
    """

    name = 'switching'
    feedforward = {'feedforward_ratio': SWITCHING_FEEDFORWARD_RATIO}
    options = ('switch_settle_s',)
    holding = 'feedforward only (before the switch)'

    @classmethod
    def build(cls, model: 'CameraRobotModel', pose: ArrayLike, dt: float,
              **settings: Any) -> 'Switching':
        """Wrap the paper's feedback made from the same ``settings``."""
        own = {k: settings[k] for k in cls.options if k in settings}
        return cls(Paper.build(model, pose, dt, **settings), **own)

    @classmethod
    def needs_measured(cls, settings: Mapping[str, Any]) -> bool:
        """Return True: the switch waits for a measured frame."""
        return True

    def __init__(self, feedback: AdaptiveFeedback,
                 switch_settle_s: float = SWITCH_SETTLE_S) -> None:
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
    def q_feedback(self) -> NDArray[np.float64]:
        """Return the feedback's output (zeros before the switch)."""
        return self.feedback.q_feedback

    def ready(self, t: float, qdot_encoder: ArrayLike | None, measured: bool) -> bool:
        """Return True when the frame at ``t`` (s) may switch the feedback on."""
        if not measured or t - self.t0 < self.switch_settle_s:
            return False
        limit = self.feedback.hold_speed_fraction * self.feedback.speed_limits
        return qdot_encoder is None or bool(np.all(np.abs(qdot_encoder) <= limit))

    def update(self, p_hat: ArrayLike, q_encoder: ArrayLike,
               qdot_encoder: ArrayLike | None = None, measured: bool = True,
               t: float | None = None) -> FeedbackUpdate:
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
        error = feature_error(p_hat, self.feedback.p_target)
        self.last = FeedbackUpdate(self.q_feedback, q_encoder, np.zeros(6), 0, float('inf'),
                                   float(np.linalg.norm(error)), np.zeros(6), False, True)
        return self.last

    def reset(self) -> None:
        """Back to feedforward alone."""
        self.feedback.reset()
        self.t0 = None
        self.switched_at = None
        self.last = None
