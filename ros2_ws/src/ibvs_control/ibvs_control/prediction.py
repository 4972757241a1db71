"""
The camera's latency inside the Youla design: the encoder-fed Smith predictor (no ROS).

The outer loop of section 4.2 is designed for the plant P_d = ZOH{T_in} (eq. 29, 35) at
the camera period. A real camera delivers a frame d after its exposure (a ZED 2 at 30 fps:
67-100 ms), and the q_feedback computed from it acts from then on: the loop's plant is
P_d z^-d, which the design does not know (its damping falls from 0.71 at 0 to 0.22 at
100 ms; unstable from about 190 ms with the paper's gains).

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
Jacobian's error, not J qdot d as without the predictor (docs/design.md §5).
"""

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from ibvs_model.combined import CameraRobotModel

#: ``latency_compensation``'s choices, the first the default: 'encoders', the prediction
#: (P) fed by the encoders at the action time; 'none', the paper's law exactly as published
#: (the frame's own encoder angles, the delay unknown to the design).
LATENCY_COMPENSATIONS = ('encoders', 'none')


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
