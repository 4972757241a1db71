"""Classic image-based visual servoing on the stereo features (no ROS)."""

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from .base import (AdaptiveGain, FEATURE_FALLBACKS, JOINT_LIMIT_MARGIN_RAD, VelocityLaw,
                   WINDUP_HORIZON_S)
from ..controllers import check_inputs, feature_error, FeedbackUpdate
from ..decoupling import decouple, SVD_RCOND

if TYPE_CHECKING:
    from ibvs_model.combined import CameraRobotModel


class ClassicIBVS(VelocityLaw):
    """
    Classic IBVS, integrated at the camera rate: q_feedback += T qdot, one frame at a time.

    qdot = -lambda(|e|) C1^+ e, e = p_hat - p_bar (ViSP vpServo::computeControlLaw with the
    eye-to-hand task L_s J_robot; Chaumette & Hutchinson 2006, eq. 4; Corke, Robotics,
    Vision and Control, eq. 15.11). Here L_s J_robot is our stereo C1 = dF/dq (eq. 31) at
    the encoder angles: both cameras' image Jacobians of both markers times the robot's
    point Jacobians; its truncated/damped pseudo-inverse (:func:`.decoupling.decouple` with
    ``svd_rcond`` and ``svd_damping``, rank 5) leaves q6 alone. For small errors e decays
    as exp(-lambda t). No trust region: the law is the textbook one, with the textbook
    safeguards of :class:`.base.VelocityLaw` (anti-windup, joint limits).
    """

    name = 'ibvs'
    options = VelocityLaw.options + ('svd_damping',)

    def __init__(self, model: 'CameraRobotModel', pose: ArrayLike, dt: float,
                 gain: AdaptiveGain | None = None, svd_rcond: float = SVD_RCOND,
                 svd_damping: float = 0.0, p_target: ArrayLike | None = None,
                 feature_fallback: str = FEATURE_FALLBACKS[0],
                 windup_horizon_s: float = WINDUP_HORIZON_S,
                 joint_limit_margin_rad: float = JOINT_LIMIT_MARGIN_RAD) -> None:
        """
        Project the target markers (p_bar = F(q_target), eq. 30); ``dt`` the camera period.

        ``p_target``: a taught p_bar (6,) instead (the features measured at the target).
        """
        super().__init__(model, pose, dt, gain, svd_rcond, p_target, feature_fallback,
                         windup_horizon_s, joint_limit_margin_rad)
        self.svd_damping = svd_damping

    def update(self, p_hat: ArrayLike, q_encoder: ArrayLike,
               qdot_encoder: ArrayLike | None = None, measured: bool = True,
               t: float | None = None) -> FeedbackUpdate:
        """Return the :class:`.controllers.FeedbackUpdate` of one frame."""
        p_hat, q_encoder = check_inputs(p_hat, q_encoder)
        error = feature_error(p_hat, self.p_target)
        dec = decouple(self.model.jacobian(q_encoder), self.svd_rcond, self.svd_damping)
        norm = float(np.linalg.norm(error))
        correction = -self.gain(norm) * self.dt * (dec.pinv @ error)
        return self._integrate(q_encoder, dec, norm, correction, measured)
