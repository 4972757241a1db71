"""
The camera-and-robot model F (eq. 30), its Jacobian C1 (eq. 31-32) and inverse F^-1 (eq. 42).

F maps joint angles q to the six image coordinates of the two fiducials,
p_I = [u_l1, u_r1, v1, u_l2, u_r2, v2] (eq. 2-3, 21-22). Both fiducials lie on the tool
axis z6, which is the joint-6 axis, so joint 6 moves no feature: C1 has rank 5 and its
null space is spanned by e6 (docs/design.md §5). F^-1 therefore recovers q1..q5 from the
features and takes q6 from the caller.
"""

import numpy as np

from ._validate import as_array
from .camera import StereoCamera
from .errors import InvalidInputError
from .robot import fiducial_points, ik_position_axis, IRB4600, joint_frames, RobotParams


class CameraRobotModel:
    """F, C1 and F^-1 for one robot geometry and one calibrated stereo camera."""

    def __init__(self, camera, params=IRB4600):
        """Combine a :class:`StereoCamera` and :class:`RobotParams` (paper section 4.2)."""
        if not isinstance(camera, StereoCamera):
            raise InvalidInputError('camera must be a StereoCamera')
        if not isinstance(params, RobotParams):
            raise InvalidInputError('params must be a RobotParams')
        self.camera = camera
        self.params = params

    def markers(self, q):
        """Return the two fiducial points in {O} (2, 3), eq. (8)-(10)."""
        return fiducial_points(q, self.params)

    def features(self, q):
        """Return p_I = F(q) (6,), eq. (30): both fiducials projected in both images."""
        return self.camera.project(self.markers(q)).reshape(6)

    def jacobian(self, q):
        """
        Return C1 = J(q) = dF/dq (6, 6), eq. (31), by the chain rule (no differencing).

        Rows of marker k: d(u_l, u_r, v)/dp^O at the marker times dp^O/dq, where column i
        of dp^O/dq is z_{i-1} x (p - o_{i-1}).
        """
        frames = joint_frames(q, self.params)
        z_axes = frames[:6, :3, 2]
        origins = frames[:6, :3, 3]
        jac = np.empty((6, 6))
        for k, point_E in enumerate(self.params.fiducials_E):
            p = frames[6, :3, :3] @ point_E + frames[6, :3, 3]
            dp_dq = np.cross(z_axes, p - origins).T
            jac[3 * k:3 * k + 3] = self.camera.projection_jacobian(p) @ dp_dq
        return jac

    def inverse(self, p_image, q6, seed=None):
        """
        Return q = F^-1(p_I) (eq. 42), with the unobservable q6 given.

        Triangulates both fiducials, takes the flange position from P1 and the tool axis
        from P2 - P1, and solves the inverse kinematics (eq. 43) for q1..q5 on the branch
        nearest ``seed`` (default: zeros with q6).
        """
        p_image = as_array(p_image, (6,), 'p_image')
        points = self.camera.triangulate(p_image.reshape(2, 3))
        axis = points[1] - points[0]
        if np.linalg.norm(axis) < 1e-6:
            raise InvalidInputError('p_image: both fiducials triangulate to the same point')
        return ik_position_axis(points[0], axis, float(q6), self.params, seed)

    def in_view(self, q, margin_px=0.0):
        """Return a bool per fiducial: in front of the camera and inside both images."""
        return self.camera.in_view(self.markers(q), margin_px)
