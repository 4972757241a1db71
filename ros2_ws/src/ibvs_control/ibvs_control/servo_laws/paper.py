"""The paper's law as a servo law: the adaptive Youla feedback of section 4.2 (no ROS)."""

from typing import Any, TYPE_CHECKING

from numpy.typing import ArrayLike

from .base import ServoLaw
from ..controllers import AdaptiveFeedback

if TYPE_CHECKING:
    from ibvs_model.combined import CameraRobotModel


class Paper(AdaptiveFeedback, ServoLaw):
    """
    The paper's feedback, :class:`.controllers.AdaptiveFeedback`, unchanged (eq. 38-41).

    q_feedforward is T_forward IK(target) (eq. 43-45); it integrates every frame the
    feature node sends, measured, blended or estimated (eq. 46).
    """

    name = 'paper'
    options = ('svd_rcond', 'svd_damping', 'feedback_design', 'max_correction_rad',
               'hold_speed_fraction', 'linearise_at', 'p_target', 'speed_limits', 'own_move')
    holding = 'holding (arm slewing)'

    @classmethod
    def build(cls, model: 'CameraRobotModel', pose: ArrayLike, dt: float,
              **settings: Any) -> 'Paper':
        """Return the feedback with the Youla design's ``tau_in``, ``omega_n``, ``zeta``."""
        return cls(model, pose, settings['tau_in'], settings['omega_n'], settings['zeta'], dt,
                   **{k: settings[k] for k in cls.options if k in settings})
