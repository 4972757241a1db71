"""
A local minimum of the image error, told by the model's pose: the rule, without ROS.

A law that descends the image error e = p_hat - p_bar (classic IBVS, q_dot = -lambda J^+ e)
stops wherever J^+ e = 0: at the target (e = 0), or where e lies outside what any joint
motion changes (Chaumette 1998, "Potential problems of stability and convergence in
image-based and position-based visual servoing": local minima). Six features of two markers
on the tool axis have such minima: the image error settles a few tenths of a pixel from
its target, steady, with the tool centimetres and tens of degrees off (docs/servo_laws.md).
Seen from the image alone the loop has converged.

The feedback node knows more: through the camera-and-robot model, the encoders' angles q
of each frame put the tool at FK(q), which it compares with the target pose. The rule
(:func:`disagree`): the image error of a measured frame is small but not nil
(IMAGE_FLOOR_PX < |e| <= IMAGE_NEAR_PX) while the model puts the tool far from the target
(more than FAR_POSITION_M or FAR_AXIS_DEG); :class:`MinimumWatch` reports it
(:attr:`.servo_status.ServoStatus.LOCAL_MINIMUM`) once that has held on every measured
frame for STALL_WINDOW_S with the loop at rest (the encoders' angles and the law's
q_feedback each within STALL_RAD over the window). The run's metrics read the same rule
with the true pose (ibvs_analysis.convergence: the miss reason 'local minimum').

The bounds, and why:

- IMAGE_NEAR_PX = 1 px: at the paper's target 1 mm of tool motion moves the features by
  0.3 px sideways (docs/results.md), so an image error under 1 px is what a tool a few
  millimetres off in the directions the features see gives; the features cannot tell it
  from the target by much more.
- IMAGE_FLOOR_PX = 0.1 px: a loop that converged on its features leaves less: the
  detector's own error is 0.002-0.004 px (docs/speed.md) and the camera noise and the
  taught target's a few hundredths. Below it the features sit on their target as well as
  the camera can tell, and a pose error the model then sees is the model's own (the paper's
  link lengths scaled, Figure 13; a calibration error with the model's target features),
  not a minimum the law is held in: such a run is a model's miss, not this one.
- FAR_POSITION_M = 20 mm, FAR_AXIS_DEG = 5 deg: twenty and ten times the project's success
  bound (1 mm, 0.5 deg; ibvs_analysis.convergence), and beyond what the model's own
  errors make of a tool at the target: the paper's encoder offsets d_q (scenario 1) put
  FK(q) about 10 mm and 0.6 deg from the target when the tool is on it. The tool axis is
  the direction the features see worst (0.038 px per degree of tilt), so a minimum lies
  mostly there.
- STALL_WINDOW_S = 1 s, STALL_RAD = 1e-3 rad: thirty frames at 30 fps, over which no joint
  and no q_feedback moved by more than about 1 mm at the tool (1e-3 rad at 1-2 m): the
  loop at rest, not passing through on its way.
"""

import math

from ibvs_model import forward_kinematics, IRB4600, tool_axis_angle
from ibvs_model.robot import RobotParams
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .servo_status import ServoStatus, Verdict

#: The image error (px) under which the features say the tool is at the target.
IMAGE_NEAR_PX = 1.0
#: The image error (px) under which the features sit on their target as well as the camera
#: can tell: a loop that converged on its features.
IMAGE_FLOOR_PX = 0.1
#: The model's pose error beyond which the tool is far from the target: position (m) or
#: tool axis (deg).
FAR_POSITION_M = 0.02
FAR_AXIS_DEG = 5.0
#: How long (s, frame times) the disagreement must hold with the loop at rest, and how far
#: (rad) any joint and any q_feedback may move over that time.
STALL_WINDOW_S = 1.0
STALL_RAD = 1e-3


def model_pose_error(q: ArrayLike, target: ArrayLike, params: RobotParams = IRB4600
                     ) -> tuple[float, float]:
    """Return (position m, tool axis deg) of FK(``q``) against the ``target`` pose (4x4)."""
    pose = forward_kinematics(q, params)
    target = np.asarray(target, dtype=float)
    return (float(np.linalg.norm(pose[:3, 3] - target[:3, 3])),
            math.degrees(float(tool_axis_angle(pose[:3, :3], target[:3, :3]))))


def disagree(image_error_px: float, position_error_m: float, axis_error_deg: float) -> bool:
    """
    Return whether the image says near and the pose says far (module docstring).

    ``image_error_px``: |p_hat - p_bar| of a measured frame; the errors: of the tool's pose
    against the target's (the model's in the node, the truth's in a run's metrics).
    """
    return (IMAGE_FLOOR_PX < image_error_px <= IMAGE_NEAR_PX
            and (position_error_m > FAR_POSITION_M or axis_error_deg > FAR_AXIS_DEG))


def describe(image_error_px: float, position_error_m: float, axis_error_deg: float) -> str:
    """Return the words of a disagreement: the image error against the pose error."""
    return (f'image error {image_error_px:.2f} px, yet the tool is '
            f'{position_error_m * 1e3:.1f} mm and {axis_error_deg:.1f} deg from the target')


class MinimumWatch:
    """
    Whether the loop rests in a local minimum of the image error (module docstring).

    Parameters
    ----------
    target : array_like, shape (4, 4)
        The target pose T_E^O the model's pose is compared with.
    params : RobotParams
        The model's robot (its FK).

    """

    def __init__(self, target: ArrayLike, params: RobotParams = IRB4600) -> None:
        """Start with nothing seen: NO_WARNING."""
        self.target = np.asarray(target, dtype=float)
        self.params = params
        #: The newest frame's (image error px, model position error m, axis error deg).
        self.errors: tuple[float, float, float] | None = None
        self._since: float | None = None  # the frame time the disagreement at rest began
        self._low: NDArray[np.float64] | None = None
        self._high: NDArray[np.float64] | None = None
        self.verdict = Verdict(ServoStatus.NO_WARNING, 'ok')

    def offer(self, t_s: float, image_error_px: float, q_encoder: ArrayLike,
              q_feedback: ArrayLike, measured: bool = True) -> Verdict:
        """
        Take one frame (its time, image error, encoder angles, the law's q_feedback).

        Returns the verdict: LOCAL_MINIMUM once the disagreement held at rest for
        STALL_WINDOW_S of frame times, else NO_WARNING. A frame whose features were not
        measured (estimated from the model, eq. 46) says nothing of the image: the watch
        starts again.
        """
        position, axis = model_pose_error(q_encoder, self.target, self.params)
        self.errors = (float(image_error_px), position, axis)
        joints = np.concatenate([np.asarray(q_encoder, float), np.asarray(q_feedback, float)])
        if not (measured and disagree(image_error_px, position, axis)):
            self._since = None
        elif self._since is None or np.any(np.maximum(self._high, joints)
                                           - np.minimum(self._low, joints) > STALL_RAD):
            self._since, self._low, self._high = t_s, joints, joints  # (again) from here
        else:
            self._low, self._high = np.minimum(self._low, joints), np.maximum(self._high, joints)
        if self._since is not None and t_s - self._since >= STALL_WINDOW_S:
            self.verdict = Verdict(ServoStatus.LOCAL_MINIMUM,
                                   f'{describe(*self.errors)} (the model: FK of the '
                                   f'encoders), at rest for {t_s - self._since:.1f} s: a local '
                                   'minimum of the image error; the law cannot leave it')
        else:
            self.verdict = Verdict(ServoStatus.NO_WARNING, 'ok')
        return self.verdict
