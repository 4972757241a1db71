"""Position-based visual servoing of the flange point and the tool axis (no ROS)."""

from typing import TYPE_CHECKING

from ibvs_model import geometric_jacobian, InvalidInputError
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .base import (AdaptiveGain, FEATURE_FALLBACKS, JOINT_LIMIT_MARGIN_RAD, VelocityLaw,
                   WINDUP_HORIZON_S)
from ..controllers import check_inputs, FeedbackUpdate
from ..decoupling import decouple, SVD_RCOND

if TYPE_CHECKING:
    from ibvs_model.camera import StereoCamera
    from ibvs_model.combined import CameraRobotModel

#: Sub-steps of the PBVS integration over one camera period (:class:`PBVS`).
SUBSTEPS = 10


def tool_from_markers(camera: 'StereoCamera', p_hat: ArrayLike
                      ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
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


def axis_error(axis: ArrayLike, axis_target: ArrayLike) -> NDArray[np.float64]:
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
    e_t = t - t* and the axis error theta u (:func:`axis_error`, toward the target axis),
    e = [e_t, -theta u] = s - s*. The classic PBVS law (Chaumette & Hutchinson 2006,
    eq. 24-25 with the frame {O} as reference; Corke, Robotics, Vision and Control,
    eq. 15.3) asks the flange twist [v; omega] = -lambda e, mapped to joints by the
    robot's geometric Jacobian, qdot = J(q)^+ [v; omega] (SVD truncated at ``svd_rcond``,
    undamped: J's units are m/rad and 1), and integrated at the camera rate: the twist of
    a frame is held over the camera period and integrated in ``substeps`` steps with J
    updated along the way, from the joint reference. The flange then moves on the
    straight line from where it is to t* (dt/dt = -lambda e_t), whatever the image does.
    The gain is constant (``gain.lambda_0``): |e| mixes metres and radians.
    """

    name = 'pbvs'
    options = VelocityLaw.options + ('substeps',)

    def __init__(self, model: 'CameraRobotModel', pose: ArrayLike, dt: float,
                 gain: AdaptiveGain | None = None, svd_rcond: float = SVD_RCOND,
                 substeps: int = SUBSTEPS, p_target: ArrayLike | None = None,
                 feature_fallback: str = FEATURE_FALLBACKS[0],
                 windup_horizon_s: float = WINDUP_HORIZON_S,
                 joint_limit_margin_rad: float = JOINT_LIMIT_MARGIN_RAD) -> None:
        """
        Keep the target flange position and axis; ``dt`` the camera period.

        ``p_target``: taught features (6,) at the target; the target position and axis are
        then triangulated from them (:func:`tool_from_markers`), as a taught PBVS does.
        """
        super().__init__(model, pose, dt, gain, svd_rcond, p_target, feature_fallback,
                         windup_horizon_s, joint_limit_margin_rad)
        self.substeps = int(substeps)
        if p_target is None:
            self.t_target = self.pose[:3, 3].copy()
            self.axis_target = self.pose[:3, 2].copy()
        else:
            self.t_target, self.axis_target = tool_from_markers(model.camera, self.p_target)

    def pose_error(self, p_hat: ArrayLike) -> NDArray[np.float64]:
        """Return e = [t - t*, -theta u] (6,) of the measured features (m, rad)."""
        position, axis = tool_from_markers(self.model.camera, p_hat)
        return np.concatenate([position - self.t_target,
                               -axis_error(axis, self.axis_target)])

    def update(self, p_hat: ArrayLike, q_encoder: ArrayLike,
               qdot_encoder: ArrayLike | None = None, measured: bool = True,
               t: float | None = None) -> FeedbackUpdate:
        """Return the :class:`.controllers.FeedbackUpdate` of one frame."""
        p_hat, q_encoder = check_inputs(p_hat, q_encoder)
        error = self.pose_error(p_hat)
        twist = -self.gain.lambda_0 * error
        # The frame's twist, held over the camera period, integrated in sub-steps with J
        # re-evaluated on the way (model FK only): one Euler step of T would bend the path
        # by O((lambda T |e|)^2) (22 mm off the line from scenario 1 with lambda = 1 / s).
        q_ref = self.q_reference(q_encoder)
        correction = np.zeros(6)
        for _ in range(self.substeps):
            dec = decouple(geometric_jacobian(q_ref + correction, self.model.params),
                           self.svd_rcond)
            correction = correction + self.dt / self.substeps * (dec.pinv @ twist)
        return self._integrate(q_encoder, dec, float(np.linalg.norm(error)), correction,
                               measured)
