"""
The camera-and-robot model F (eq. 30), its Jacobian C1 (eq. 31-32) and inverse F^-1 (eq. 42).

F maps joint angles q to the six image coordinates of the two fiducials,
p_I = [u_l1, u_r1, v1, u_l2, u_r2, v2] (eq. 2-3, 21-22). Both fiducials lie on the tool
axis z6, which is the joint-6 axis, so joint 6 moves no feature: C1 has rank 5 and its
null space is spanned by e6 (docs/design.md §5). F^-1 therefore recovers q1..q5 from the
features and takes q6 from the caller.
"""

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validate import as_array
from .camera import StereoCamera
from .errors import InvalidInputError
from .robot import (fiducial_points, forward_kinematics_batch, ik_position_axis, IRB4600,
                    joint_frames, RobotParams)


class CameraRobotModel:
    """F, C1 and F^-1 for one robot geometry and one calibrated stereo camera."""

    def __init__(self, camera: StereoCamera, params: RobotParams = IRB4600) -> None:
        """
        Combine a :class:`StereoCamera` and :class:`RobotParams` (paper section 4.2).

        Parameters
        ----------
        camera : StereoCamera
            The calibrated stereo camera.
        params : RobotParams
            The robot's geometry.

        """
        if not isinstance(camera, StereoCamera):
            raise InvalidInputError('camera must be a StereoCamera')
        if not isinstance(params, RobotParams):
            raise InvalidInputError('params must be a RobotParams')
        self.camera = camera
        self.params = params

    def markers(self, q: ArrayLike) -> NDArray[np.float64]:
        """
        Return the two fiducial points in {O}, eq. (8)-(10).

        Parameters
        ----------
        q : array_like, shape (6,)
            Joint angles (rad).

        Returns
        -------
        ndarray, shape (2, 3)
            P1 and P2 in {O} (m).

        """
        return fiducial_points(q, self.params)

    def features(self, q: ArrayLike) -> NDArray[np.float64]:
        """
        Return p_I = F(q), eq. (30): both fiducials projected in both images.

        Parameters
        ----------
        q : array_like, shape (6,)
            Joint angles (rad).

        Returns
        -------
        ndarray, shape (6,)
            p_I = [u_l1, u_r1, v1, u_l2, u_r2, v2] (px).

        """
        return self.camera.project(self.markers(q)).reshape(6)

    def features_batch(self, qs: ArrayLike) -> NDArray[np.float64]:
        """
        Return F(q) (eq. 30) for each row of ``qs``: :meth:`features` of many postures at once.

        The poses by :func:`.robot.forward_kinematics_batch` (bit for bit
        :func:`.robot.forward_kinematics`), the markers and their projections as arrays;
        each row equals :meth:`features` of that row to rounding.

        Parameters
        ----------
        qs : array_like, shape (m, 6)
            Joint angles (rad), one posture per row.

        Returns
        -------
        ndarray, shape (m, 6)
            p_I of each row (px).

        """
        tfs = forward_kinematics_batch(qs, self.params)
        points = np.einsum('kj,nij->nki', self.params.fiducials_E, tfs[:, :3, :3]) \
            + tfs[:, None, :3, 3]
        return self.camera.project(points.reshape(-1, 3)).reshape(-1, 6)

    def jacobian(self, q: ArrayLike) -> NDArray[np.float64]:
        """
        Return C1 = J(q) = dF/dq, eq. (31), by the chain rule (no differencing).

        Rows of marker k: d(u_l, u_r, v)/dp^O at the marker times dp^O/dq, where column i
        of dp^O/dq is z_{i-1} x (p - o_{i-1}).

        Parameters
        ----------
        q : array_like, shape (6,)
            Joint angles (rad).

        Returns
        -------
        ndarray, shape (6, 6)
            C1 (px / rad); its last column is zero (joint 6 moves no feature).

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

    def inverse(self, p_image: ArrayLike, q6: float,
                seed: ArrayLike | None = None) -> NDArray[np.float64]:
        """
        Return q = F^-1(p_I) (eq. 42), with the unobservable q6 given.

        Triangulates both fiducials, takes the flange position from P1 and the tool axis
        from P2 - P1, and solves the inverse kinematics (eq. 43) for q1..q5 on the branch
        nearest ``seed``.

        Parameters
        ----------
        p_image : array_like, shape (6,)
            p_I (px).
        q6 : float
            Joint 6's angle (rad), which p_I does not determine.
        seed : array_like, shape (6,), optional
            Joint angles the branch is chosen nearest to; default zeros with q6.

        Returns
        -------
        ndarray, shape (6,)
            q (rad).

        """
        p_image = as_array(p_image, (6,), 'p_image')
        points = self.camera.triangulate(p_image.reshape(2, 3))
        axis = points[1] - points[0]
        if np.linalg.norm(axis) < 1e-6:
            raise InvalidInputError('p_image: both fiducials triangulate to the same point')
        return ik_position_axis(points[0], axis, float(q6), self.params, seed)

    def in_view(self, q: ArrayLike, margin_px: float = 0.0) -> NDArray[np.bool_]:
        """
        Return a bool per fiducial: in front of the camera and inside both images.

        Parameters
        ----------
        q : array_like, shape (6,)
            Joint angles (rad).
        margin_px : float
            Shrinks the images on every side (:meth:`StereoCamera.in_view`).

        Returns
        -------
        ndarray of bool, shape (2,)

        """
        return self.camera.in_view(self.markers(q), margin_px)
