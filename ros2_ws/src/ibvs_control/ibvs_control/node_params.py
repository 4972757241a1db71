"""
Parameters of the three control nodes and their start-time checks (no message handling).

Shared parameters come from :mod:`ibvs_common.shared_params`; the ones below belong to this
package. The checks turn a configuration the controllers cannot work with into a
:class:`ibvs_common.params.ParameterError` that names the parameter, so that the node stops
at start (exit code 2, ibvs_common.node_main.run) instead of misbehaving later.
"""

from ibvs_common.params import Param, ParameterError
from ibvs_model import IRB4600, ModelError

from . import controllers, youla

FEEDFORWARD_METHOD = Param(
    'feedforward_method', 'sampled',
    "T_forward (eq. 44-45) at the physics rate: 'sampled' (inverse of the sampled inner "
    "loop, no overshoot) or 'tustin' / 'zoh' (eq. 44 discretised by scipy)", '-',
    choices=('sampled', 'tustin', 'zoh'))
FEEDBACK_DESIGN = Param(
    'feedback_design', 'sampled',
    "outer controller k at the camera period: 'sampled' (eq. 37-41 on the ZOH plant: eq. 36 "
    "at the frames) or 'tustin' (k(s) discretised)", '-', choices=('sampled', 'tustin'))
SVD_RCOND = Param('svd_rcond', controllers.RCOND,
                  'singular values of C1 below svd_rcond * sigma_1 are not inverted', '-',
                  low=0.0, high=0.1, low_open=True)
SVD_DAMPING = Param('svd_damping', controllers.DAMPING,
                    'Tikhonov damping of the inverted singular values of C1 (0: exact)',
                    'px/rad', low=0.0, high=100.0)
MAX_CORRECTION = Param('max_correction_rad', controllers.MAX_CORRECTION,
                       'trust region of the linearisation: largest correction one '
                       'decoupled channel of C1^+ (p_bar - p_hat) integrates per frame', 'rad',
                       low=0.0, high=10.0, low_open=True)
LINEARISE_AT = Param('linearise_at', controllers.LINEARISE_AT,
                     "where C1 (eq. 31) is evaluated: 'encoders' (the encoder angles q_T) or "
                     "'features' (q~ = F^-1(p_hat), the paper's eq. 42; less robust to a wrong "
                     'robot model)', '-', choices=controllers.LINEARISATION_POINTS)
HOLD_SPEED = Param('hold_speed_fraction', controllers.HOLD_SPEED,
                   'the feedback holds (does not integrate) while an encoder joint moves '
                   'faster than this fraction of its speed limit', '-',
                   low=0.0, high=10.0, low_open=True)
TORQUE_LIMITS = Param('torque_limits', [0.0] * 6,
                      "'limited' actuators: torque limit per joint; 0 takes the URDF's "
                      'joint effort', 'N m', low=0.0, high=1e6, length=6)
SPEED_MARGIN = Param('speed_margin', 0.95, "'limited' actuators: the governor's speed "
                     'as a fraction of the IRB 4600 speed limits', '-', low=0.0, high=1.0,
                     low_open=True)
ACCELERATION_MARGIN = Param('acceleration_margin', 0.5, "'limited' actuators: share of "
                            'the torque left after h(q, qdot) that the governor may use', '-',
                            low=0.0, high=1.0, low_open=True)


def check_gains(values):
    """Raise ParameterError naming 'omega_n' unless 1 / omega_n > tau_in (paper, eq. 36)."""
    try:
        youla.check_bandwidth_rule(values['tau_in'], values['omega_n'])
    except ValueError as exc:
        raise ParameterError(
            f"parameter 'omega_n' = {values['omega_n']!r} is invalid with tau_in = "
            f"{values['tau_in']!r}: {exc}; allowed: omega_n < 1 / tau_in") from None


def target_from(values, params=IRB4600):
    """
    Return the target pose of 'target_position' / 'target_rotation', checked reachable.

    Raises ParameterError naming 'target_rotation' (not a rotation) or 'target_position'
    (no IK branch within the joint limits, eq. 43).
    """
    try:
        pose = controllers.target_pose(values['target_position'], values['target_rotation'])
    except ValueError as exc:
        raise ParameterError(f"parameter 'target_rotation' = {values['target_rotation']!r} "
                             f'is invalid: {exc}; allowed: a rotation matrix, row-major') \
            from None
    try:
        controllers.check_reachable(pose, params)
    except ModelError as exc:
        raise ParameterError(f"parameter 'target_position' = {values['target_position']!r} "
                             f'is invalid: unreachable target: {exc}; allowed: a pose with '
                             'an IK branch within the joint limits') from None
    return pose
