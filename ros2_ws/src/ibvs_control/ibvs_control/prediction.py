"""
The camera's latency inside the Youla design: the encoder-fed Smith predictor (no ROS).

The outer loop of section 4.2 is designed for the plant P_d = ZOH{T_in} (eq. 29, 35) at
the camera period. A real camera delivers a frame d after its exposure (a ZED 2 at 30 fps:
67-100 ms), and the q_feedback computed from it acts from then on: the loop's plant is
P_d z^-d, which the design does not know: its damping falls with the delay until the loop
goes unstable (docs/design.md §4.2).

For a stable plant with delay, Youla's parameterisation (eq. 38-41) gives every stabilising
controller as C = Q / (1 - P0 Q) with Q stable, P0 = P_d z^-d the nominal plant. Choosing
Q = M_T / P_d, the design the paper makes without delay, gives the closed loop
T = P0 Q = M_T z^-d: the designed response, delayed, and nothing else. Written with the
undelayed design k = M_T / (P_d (1 - M_T)) (eq. 41) it is

    C = k / (1 + k P_d (1 - z^-d)),

the discrete Smith predictor: k acts on the measurement y(t - d) plus what the plant did in
the last d, P_d u (t) - P_d u (t - d). On this arm the plant's output is not a model's
guess: the encoders give q at any time (250 Hz on a cell, every physics step in lockstep)
and the camera-and-robot model F (eq. 30-32) maps it to the image. The prediction of the
features at the action time t_a from a frame exposed at t_e is then

    s_hat(t_a) = s(t_e) + F(q(t_a)) - F(q(t_e))                                     (P)

so the feedback acts on F(q(t_a)) + [s(t_e) - F(q(t_e))]: the features where the arm is
now, plus the part the model does not explain (d_q, the calibration's and the robot's
errors, the target's), which is all that is still delayed. With a perfect model and the true
delay this is s(t_a) exactly; with no latency (t_a = t_e) it is s(t_e), the paper's law
unchanged. The same frame is linearised (eq. 31) and its hold rule judged at q(t_a).

A wrong delay or model costs only through the delayed part: the loop through the arm has
no delay left, and the model-mismatch term [s - F(q)] changes only as fast as the mismatch
changes with the pose (slowly near the target), so an error of the assumed delay of
delta seconds leaves a perturbation of about J_err qdot delta, with J_err the
Jacobian's error, not J qdot d as without the predictor (docs/design.md §4.2).

The internal-model form predicts to the end of the move instead of its present: to the rest
pose q_rest = q_target + q_feedback the joint references are heading for (the feedforward's
target, IK eq. 43, plus the correction held), s_hat = s(t_e) + F(q_rest) - F(q(t_e)). The
feedback then integrates only what the feedforward does not explain (the image's
disagreement with the model, whatever the arm is doing), and its loop runs through the
model's static map at q_rest alone: no delay and no arm dynamics in it at all, so it can
integrate through the slew (no hold rule) and converges while the arm still moves. Its cost:
the mismatch it integrates on the way is that of poses other than the target's, which the
later frames correct. It is not the identity without latency.
"""

from typing import Optional, TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .controllers import target_branch

if TYPE_CHECKING:
    from ibvs_model.combined import CameraRobotModel

#: ``latency_compensation``'s choices, the first the default: 'encoders', the prediction
#: (P) fed by the encoders at the action time; 'internal_model', (P) to the rest pose the
#: joint references are heading for (:class:`Predictor`); 'none', the paper's law exactly as
#: published (the frame's own encoder angles, the delay unknown to the design).
LATENCY_COMPENSATIONS = ('encoders', 'internal_model', 'none')


def predicted_features(model: 'CameraRobotModel', p_hat: ArrayLike, q_exposure: ArrayLike,
                       q_action: ArrayLike) -> NDArray[np.float64]:
    """
    Return s_hat(t_a) = p_hat + F(q_action) - F(q_exposure), the prediction (P).

    Parameters
    ----------
    model : CameraRobotModel
        The controllers' camera-and-robot model F (eq. 30).
    p_hat : array_like, shape (6,)
        The frame's features (px), exposed at t_e.
    q_exposure : array_like, shape (6,)
        The encoder angles at t_e (rad).
    q_action : array_like, shape (6,)
        The encoder angles at t_a, when the frame's q_feedback starts to act (rad).

    Returns
    -------
    ndarray, shape (6,)
        The predicted features (px); ``p_hat`` itself (a float copy) when the two joint
        vectors are equal, so that without latency the law sees exactly what it saw before.

    """
    p_hat = np.array(p_hat, dtype=float)
    q_exposure = np.asarray(q_exposure, dtype=float)
    q_action = np.asarray(q_action, dtype=float)
    if np.array_equal(q_exposure, q_action):
        return p_hat
    return p_hat + (model.features(q_action) - model.features(q_exposure))


class Predictor:
    """
    What a servo law is given for one frame under ``latency_compensation`` (module docstring).

    Parameters
    ----------
    mode : str
        One of :data:`LATENCY_COMPENSATIONS`.
    model : CameraRobotModel
        The controllers' F.
    pose : array_like, shape (4, 4)
        The target flange pose (for the internal model's q_target, the feedforward's IK
        branch from the first frame's encoders, :func:`.controllers.target_branch`).

    """

    def __init__(self, mode: str, model: 'CameraRobotModel', pose: ArrayLike) -> None:
        """Check ``mode``; nothing is known of the move yet."""
        if mode not in LATENCY_COMPENSATIONS:
            raise ValueError(f'latency_compensation must be one of {LATENCY_COMPENSATIONS}, '
                             f'got {mode!r}')
        self.mode = mode
        self.model = model
        self.pose = np.asarray(pose, dtype=float)
        self.q_target: Optional[NDArray[np.float64]] = None

    def inputs(self, q_feedback: ArrayLike, p_hat: ArrayLike, q_exposure: ArrayLike,
               qd_exposure: ArrayLike | None, q_action: ArrayLike | None = None,
               qd_action: ArrayLike | None = None) -> tuple:
        """
        Return (features, joints, joint speeds) for the law's update of one frame.

        ``q_feedback``: the law's output before this frame; the exposure's encoders and, for
        'encoders', those of the action time. 'none': the frame as it is; 'encoders': (P)
        to the action time, its encoders and speeds; 'internal_model': (P) to q_rest, q_rest
        and no speeds (nothing to hold for).
        """
        if self.mode == 'none':
            return p_hat, q_exposure, qd_exposure
        if self.mode == 'encoders':
            return (predicted_features(self.model, p_hat, q_exposure, q_action), q_action,
                    qd_action)
        if self.q_target is None:
            self.q_target = target_branch(self.pose, q_exposure, self.model.params)
        q_rest = self.q_target + np.asarray(q_feedback, dtype=float)
        return predicted_features(self.model, p_hat, q_exposure, q_rest), q_rest, None
