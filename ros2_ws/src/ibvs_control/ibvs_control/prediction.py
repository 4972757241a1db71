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
target, IK eq. 43, plus the correction held). The feedback then integrates only what the
feedforward does not explain (the image's disagreement with the model, whatever the arm is
doing), and its loop runs through the model's static map at q_rest alone: no delay and no
arm dynamics in it at all, so it can integrate through the slew (no hold rule) and converges
while the arm still moves. The disagreement is seen at the pose of the frame and must be
carried to q_rest. Carried in the image (``model_error_transport: image``, the default),
s_hat = s(t_e) + F(q_rest) - F(q(t_e)), a joint offset seen at one pose is another pose's
image error, and the correction integrated on the way is wrong by as much as the two poses'
Jacobians differ (most in the wrist, which a long swing turns). ``joints`` carries it in
joint space instead: each measured frame's disagreement, as the joint offset d_hat that
explains it to first order, and the rest r that no joint offset does,

    d_hat = J(q_e)^+ (s(t_e) - F(q_e)),     r = s(t_e) - F(q_e + d_hat),
    s_hat = F(q_rest + d_hat) + r                                                  (M)

(J^+ the damped pseudo-inverse of :func:`.decoupling.decouple`, the law's damping): to first
order exact for an offset of the encoders (the cell's d_q) at every pose, and (P) at the
frame's own pose (q_rest = q_e gives s(t_e)). A frame the detector did not measure (the
model's estimate, or its blend) holds d_hat and r: it shows the model, not the arm. So does
a frame exposed while the arm slews: its disagreement carries the error of its stamp times
the image's speed, J qdot delta (at joint 1's rated 175 deg/s a millisecond is 0.175 deg of
d_hat), which the feedback would integrate and then take back; d_hat is taken from frames
exposed with every joint slower than ``hold_speed_fraction`` of its rated speed (an absolute
speed: the error is the speed's, whatever the cap), at rest before the move and as it ends,
and held through the fast part of the slew. It is not the identity without latency. Which is
better depends on what the model's error is: for an offset of the encoders alone (scenario
1's d_q) 'joints'; where the frames at the start show little of the error at the target (the
rehearsal of ``real_cell.yaml``, with its taught target), 'joints' waits for the end of the
slew where 'image' already integrates (docs/real_cell.md measures both).
"""

from typing import Optional, TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .controllers import SVD_DAMPING, target_branch
from .decoupling import decouple

if TYPE_CHECKING:
    from ibvs_model.combined import CameraRobotModel

#: ``latency_compensation``'s choices, the first the default: 'encoders', the prediction
#: (P) fed by the encoders at the action time; 'internal_model', (P) to the rest pose the
#: joint references are heading for (:class:`Predictor`); 'none', the paper's law exactly as
#: published (the frame's own encoder angles, the delay unknown to the design).
LATENCY_COMPENSATIONS = ('encoders', 'internal_model', 'none')

#: How the internal model carries a frame's disagreement with F to q_rest, the first the
#: default: 'image', unchanged in the image (P); 'joints', as the joint offset that explains
#: it (M).
MODEL_ERROR_TRANSPORTS = ('image', 'joints')


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
    still_speeds : array_like, shape (6,), optional
        The joint speeds (rad/s) under which a frame shows the arm still enough for the
        internal model to take d_hat from it (:meth:`still`):
        :func:`.node_params.still_speeds`. Default: every frame.
    transport : str
        One of :data:`MODEL_ERROR_TRANSPORTS`: how the internal model carries the
        disagreement to q_rest.

    """

    def __init__(self, mode: str, model: 'CameraRobotModel', pose: ArrayLike,
                 still_speeds: ArrayLike | None = None,
                 transport: str = MODEL_ERROR_TRANSPORTS[0]) -> None:
        """Check ``mode`` and ``transport``; nothing is known of the move yet."""
        if mode not in LATENCY_COMPENSATIONS:
            raise ValueError(f'latency_compensation must be one of {LATENCY_COMPENSATIONS}, '
                             f'got {mode!r}')
        if transport not in MODEL_ERROR_TRANSPORTS:
            raise ValueError(f'model_error_transport must be one of {MODEL_ERROR_TRANSPORTS}, '
                             f'got {transport!r}')
        self.transport = transport
        self.still_speeds = None if still_speeds is None else np.asarray(still_speeds,
                                                                         dtype=float)
        if self.still_speeds is not None and (self.still_speeds.shape != (6,)
                                              or not np.all(self.still_speeds > 0.0)):
            raise ValueError(f'still_speeds must be 6 values > 0, got {still_speeds}')
        self.mode = mode
        self.model = model
        self.pose = np.asarray(pose, dtype=float)
        self.q_target: Optional[NDArray[np.float64]] = None
        #: The internal model's joint offset d_hat and rest r (eq. M) of the last measured
        #: frame; None before the first.
        self.joint_offset: Optional[NDArray[np.float64]] = None
        self.rest: Optional[NDArray[np.float64]] = None

    def inputs(self, q_feedback: ArrayLike, p_hat: ArrayLike, q_exposure: ArrayLike,
               qd_exposure: ArrayLike | None, q_action: ArrayLike | None = None,
               qd_action: ArrayLike | None = None, measured: bool = True) -> tuple:
        """
        Return (features, joints, joint speeds) for the law's update of one frame.

        ``q_feedback``: the law's output before this frame; the exposure's encoders and, for
        'encoders', those of the action time. 'none': the frame as it is; 'encoders': (P)
        to the action time, its encoders and speeds; 'internal_model': (P) or (M) at
        q_rest (:attr:`transport`), q_rest and no speeds (nothing to hold for); (M)'s d_hat
        and r taken from the frame when it was
        ``measured`` with the arm :meth:`still` (or none was before it), else held.
        """
        if self.mode == 'none':
            return p_hat, q_exposure, qd_exposure
        if self.mode == 'encoders':
            return (predicted_features(self.model, p_hat, q_exposure, q_action), q_action,
                    qd_action)
        q_exposure = np.asarray(q_exposure, dtype=float)
        if self.q_target is None:
            self.q_target = target_branch(self.pose, q_exposure, self.model.params)
        q_rest = self.q_target + np.asarray(q_feedback, dtype=float)
        if self.transport == 'image':
            return predicted_features(self.model, p_hat, q_exposure, q_rest), q_rest, None
        if (measured and self.still(qd_exposure)) or self.joint_offset is None:
            self.joint_offset, self.rest = self.disagreement(p_hat, q_exposure)
        return self.model.features(q_rest + self.joint_offset) + self.rest, q_rest, None

    def still(self, qd: ArrayLike | None) -> bool:
        """Return whether the joint speeds ``qd`` (6,) are all under :attr:`still_speeds`."""
        if self.still_speeds is None or qd is None:
            return True
        return bool(np.all(np.abs(np.asarray(qd, dtype=float)) <= self.still_speeds))

    def disagreement(self, p_hat: ArrayLike, q_exposure: ArrayLike
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """
        Return (d_hat, r) of eq. (M): the frame's disagreement with F at ``q_exposure``.

        d_hat (6,) rad, the joint offset that explains it to first order; r (6,) px, what
        is left, so that F(q_exposure + d_hat) + r is ``p_hat`` exactly.
        """
        p_hat = np.asarray(p_hat, dtype=float)
        q_exposure = np.asarray(q_exposure, dtype=float)
        dec = decouple(self.model.jacobian(q_exposure), svd_damping=SVD_DAMPING)
        offset = dec.joints(dec.channels(p_hat - self.model.features(q_exposure)))
        return offset, p_hat - self.model.features(q_exposure + offset)
