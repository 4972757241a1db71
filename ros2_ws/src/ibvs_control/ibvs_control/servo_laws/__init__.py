"""
Servo laws: the paper's and three beside it, each a class behind one interface (no ROS).

Each law turns one camera frame (features p_hat, encoder angles q_T and speeds) into a
q_feedback (6,) that the joint controller adds to q_feedforward: q_ref = q_feedforward +
q_feedback (joint_controller_node, unchanged). Each is a :class:`.base.ServoLaw` that
declares what it needs (its feedforward, its options, whether it reads whether a frame was
measured); :data:`LAWS` is the registry, :func:`law_class` the one check of a name. Every
law's error is e = s - s* (:func:`ibvs_control.controllers.feature_error`).

===========  ===========================================  ===================================
law          q_feedforward (``feedforward_method``)        q_feedback
===========  ===========================================  ===================================
paper        T_forward IK(target), eq. 43-45               k(z) C1^+ (-e), eq. 38-41
switching    T_forward IK(target), eq. 43-45, slower (*)   0 until the switch, then as paper
ibvs         q(0), held ('hold')                            integral of -lambda C1^+ e
pbvs         q(0), held ('hold')                            integral of J^-1 (-lambda e_pose)
===========  ===========================================  ===================================

(*) ``feedforward_ratio`` :data:`.switching.SWITCHING_FEEDFORWARD_RATIO` instead of the
paper's 0.1 (the class's ``feedforward``).

For ibvs and pbvs the feedforward holds the initial joints, so q_feedback carries the whole
move from q(0): q_ref = q(0) + sum of the velocity commands times the camera period, kept
within the joint limits and within reach of the actuators (:func:`.base.guard_reference`).
With ``feature_fallback`` 'estimate' (default) they take every frame the feature node sends
(measured, blended or model-estimated out of view, eq. 46), as the paper's law does; with
'hold' they hold still on a frame not measured (ViSP's examples stop the robot when a
feature is lost).

Adding a law: one module with a :class:`.base.ServoLaw` subclass, and one line in
:data:`LAWS`.
"""

from typing import Any, TYPE_CHECKING

from numpy.typing import ArrayLike

from .base import (AdaptiveGain, FEATURE_FALLBACKS, guard_reference, JOINT_LIMIT_MARGIN_RAD,
                   LAMBDA_0, LAMBDA_INF, LAMBDA_SLOPE, ServoLaw, target_features,
                   VelocityLaw, WINDUP_HORIZON_S)
from .ibvs import ClassicIBVS
from .paper import Paper
from .pbvs import axis_error, PBVS, SUBSTEPS, tool_from_markers
from .switching import SWITCH_SETTLE_S, Switching, SWITCHING_FEEDFORWARD_RATIO

if TYPE_CHECKING:
    from ibvs_model.combined import CameraRobotModel

#: The registry: every servo law, the default (the paper's) first.
LAWS = (Paper, Switching, ClassicIBVS, PBVS)
#: The ``servo_law`` names, in registry order.
SERVO_LAWS = tuple(law.name for law in LAWS)

__all__ = ['AdaptiveGain', 'axis_error', 'ClassicIBVS', 'FEATURE_FALLBACKS',
           'feedforward_overrides', 'guard_reference', 'JOINT_LIMIT_MARGIN_RAD', 'LAMBDA_0',
           'LAMBDA_INF', 'LAMBDA_SLOPE', 'law_class', 'LAWS', 'make_law', 'Paper', 'PBVS',
           'SERVO_LAWS', 'ServoLaw', 'SUBSTEPS', 'SWITCH_SETTLE_S', 'Switching',
           'SWITCHING_FEEDFORWARD_RATIO', 'target_features', 'tool_from_markers',
           'VelocityLaw', 'WINDUP_HORIZON_S']


def law_class(name: str) -> type[ServoLaw]:
    """Return the :class:`.base.ServoLaw` subclass named ``name``; ValueError if none."""
    for law in LAWS:
        if law.name == name:
            return law
    raise ValueError(f'servo_law must be one of {SERVO_LAWS}, got {name!r}')


def feedforward_overrides(name: str) -> dict[str, Any]:
    """Return the feedforward parameters that go with the law ``name`` (a new dict)."""
    return dict(law_class(name).feedforward)


def make_law(name: str, model: 'CameraRobotModel', pose: ArrayLike, dt: float,
             **settings: Any) -> ServoLaw:
    """
    Return the servo law ``name`` for ``model``, target ``pose``, camera period ``dt`` (s).

    ``settings``: node parameter values by name (``tau_in``, ``svd_rcond``, ...), plus
    ``gain`` (:class:`.base.AdaptiveGain`) and ``p_target`` (a taught p_bar); each law
    takes those it declares (``options``) and keeps its defaults for the others.
    """
    return law_class(name).create(model, pose, dt, **settings)
