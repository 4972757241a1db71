"""
The PyBullet world of the simulator (the plant of the paper's Figure 3); no ROS here.

The IRB 4600 with screwdriver and fiducials, torque controlled, and the ZED 2 stereo pair
that renders it.

Dynamics (docs/design.md §5). The URDF of :mod:`ibvs_model.urdf` is loaded with its own
inertias (URDF_USE_INERTIA_FROM_FILE), the default velocity motors are switched off
(VELOCITY_CONTROL with force 0), joint and body damping are zero, and each step applies the
commanded joint torques with TORQUE_CONTROL. Gravity is -9.81 m/s^2 along z of {O}. PyBullet
integrates semi-implicitly: qd_{k+1} = qd_k + h qdd_k, q_{k+1} = q_k + h qd_{k+1}, with a
fixed step h = 1 / physics_rate_hz.

Rendering: the pure geometry (OpenGL matrices of the pinhole lenses, supersampling, the
windows around the fiducials) is :mod:`ibvs_sim.rendering`; the World holds one
:class:`ibvs_sim.rendering.Renderer`, our OpenGL renderer (:mod:`.gl_renderer`), given
PyBullet's visual shapes once and their link poses at each image, without shadows.
Lighting is mostly ambient, without specular highlights, so that a marker keeps its hue all
over its disc.
"""

from collections.abc import Iterable
from pathlib import Path
import tempfile
from typing import TYPE_CHECKING

from ibvs_common.process import quiet_output
from ibvs_common.shared_params import PHYSICS_RATE_HZ
from ibvs_model import IRB4600
from ibvs_model.camera import StereoCamera
from ibvs_model.scene import MARKER_RADIUS_M
from ibvs_model.urdf import JOINT_NAMES, write_urdf
import numpy as np
from numpy.typing import ArrayLike, NDArray

with quiet_output():  # PyBullet writes its build time as it loads
    import pybullet

from .gl_renderer import (box_triangles, cylinder_triangles, GLRenderer, GLRendererError,
                          obj_triangles, Shape, transformed)
from .node_params import MOUNT_HEIGHT_M
from .rendering import (box_downsample, DEFAULT_FOCUS_SUPERSAMPLING,  # noqa: F401 (re-export)
                        DEFAULT_SUPERSAMPLING, FAR_M, focus_windows, ground_obj, lens_poses,
                        MAX_FOCUS_SUPERSAMPLING, MAX_SUPERSAMPLING, NEAR_M, projection_matrix,
                        RenderDevice, Renderer, supersampled, view_matrix, window_intrinsics)

if TYPE_CHECKING:
    from ibvs_model.camera import StereoIntrinsics
    from ibvs_model.robot import RobotParams

#: Ground plane: a square facing up (:func:`ibvs_sim.rendering.ground_obj`), this grey, this
#: many metres each side of {O}, ``mount_height_m`` below the robot's base plane z = 0 of {O}.
GROUND_RGBA = (0.55, 0.55, 0.55, 1.0)
GROUND_HALF_SIZE_M = 6.0
#: The robot stands on a riser (a box under its base, this half size and colour) whose top is
#: the base plane (its height: :data:`.node_params.MOUNT_HEIGHT_M`).
RISER_HALF_SIZE_M = (0.4, 0.4)
RISER_RGBA = (0.35, 0.35, 0.38, 1.0)
#: Light: towards this direction of {O}, from above and behind the camera (the lighting of
#: :mod:`.gl_renderer`).
LIGHT_DIRECTION = (0.3, -1.0, 2.0)
#: PyBullet's former renderers drew a URDF cylinder as the convex hull of a 32-gon prism
#: with a collision margin of 1 mm (bullet3 EGLRendererVisualShapeConverter:
#: setMargin(0.001)), i.e. 1 mm thicker and longer at each end than the URDF says; ours
#: draws the same, so that the thin rods across the markers (the quill, 2.5 mm, and the
#: shaft, 2 mm) cut the notches the detector was made for (measured at the target pose:
#: without it the detected vertical separation of the markers is 0.02 px off, 0.16 deg of
#: tool axis).
PYBULLET_CYLINDER_MARGIN_M = 0.001


class RendererError(RuntimeError):
    """The World cannot draw: no OpenGL context opens here, or a shape is not supported."""


def _pose_matrix(position, quaternion):
    tf = np.eye(4)
    tf[:3, :3] = np.array(pybullet.getMatrixFromQuaternion(quaternion)).reshape(3, 3)
    tf[:3, 3] = position
    return tf


class World:
    """
    One PyBullet physics client with the robot (``params``) on a riser and a ground plane.

    ``physics_rate_hz``, ``mount_height_m``: as the parameters of these names
    (:class:`.node_params.SimConfig`, which checks them). ``mount_height_m``: height of the robot's
    base plane (z = 0 of {O}) above the floor,
    which the riser fills under the base; 0 puts the robot on the floor (no riser). Riser
    and floor are drawn only: they are not in the paper's model and nothing collides with
    them, so a tool driven below the floor goes on moving but the camera no longer sees it.

    ``render``: build the :attr:`renderer` (:class:`.gl_renderer.GLRenderer`, on a standalone
    EGL context of its own: any number of Worlds), which draws PyBullet's visual shapes
    (``getVisualShapeData``) at the link poses PyBullet computes; :class:`RendererError` if
    it cannot. False: physics only, no OpenGL loaded, and nothing to render with.
    """

    def __init__(self, params: 'RobotParams' = IRB4600,
                 physics_rate_hz: float = PHYSICS_RATE_HZ.default, with_tool: bool = True,
                 mount_height_m: float = MOUNT_HEIGHT_M.default, render: bool = True) -> None:
        """Connect a DIRECT client, load the URDF and set the dynamics (module docstring)."""
        self.mount_height_m = float(mount_height_m)
        self.params = params
        self.dt = 1.0 / physics_rate_hz
        self._client = pybullet.connect(pybullet.DIRECT)
        #: What draws the images (:class:`ibvs_sim.rendering.Renderer`); None: render false.
        self.renderer: Renderer | None = None
        try:
            self._setup(with_tool, render)
        except Exception:
            self.close()
            raise

    def _call(self, func, *args, **kwargs):
        return func(*args, physicsClientId=self._client, **kwargs)

    def _setup(self, with_tool, render):
        floor = -self.mount_height_m
        with tempfile.TemporaryDirectory(prefix='ibvs_sim_') as tmp:
            path = write_urdf(Path(tmp) / 'irb4600.urdf', self.params, with_tool)
            self.body = self._call(pybullet.loadURDF, str(path), useFixedBase=True,
                                   flags=pybullet.URDF_USE_INERTIA_FROM_FILE)
            ground = Path(tmp) / 'ground.obj'
            ground.write_text(ground_obj(GROUND_HALF_SIZE_M))
            shape = self._call(pybullet.createVisualShape, pybullet.GEOM_MESH,
                               fileName=str(ground), rgbaColor=GROUND_RGBA)
            self.ground = self._call(pybullet.createMultiBody, baseMass=0.0,
                                     baseVisualShapeIndex=shape, basePosition=(0.0, 0.0, floor))
            self._setup_bodies(with_tool, floor)
            if render:  # while the mesh files exist
                self._renderer_setup()

    def _setup_bodies(self, with_tool, floor):
        """Find the links and joints, set the dynamics and the colours, add the riser."""
        self.links = {}
        joints = {}
        for j in range(self._call(pybullet.getNumJoints, self.body)):
            info = self._call(pybullet.getJointInfo, self.body, j)
            joints[info[1].decode()] = j
            self.links[info[12].decode()] = j
        self.joints = [joints[name] for name in JOINT_NAMES]
        self._call(pybullet.setGravity, 0.0, 0.0, -9.81)
        self._call(pybullet.setPhysicsEngineParameter, fixedTimeStep=self.dt, numSubSteps=0,
                   deterministicOverlappingPairs=1)
        self._call(pybullet.setJointMotorControlArray, self.body, self.joints,
                   pybullet.VELOCITY_CONTROL, forces=[0.0] * 6)
        for link in [-1] + list(self.links.values()):
            self._call(pybullet.changeDynamics, self.body, link, linearDamping=0.0,
                       angularDamping=0.0, jointDamping=0.0)
        self.riser = (self._box((*RISER_HALF_SIZE_M, self.mount_height_m / 2.0), floor / 2.0,
                                RISER_RGBA) if self.mount_height_m > 0.0 else None)

    def _renderer_setup(self):
        """
        Build the :attr:`renderer` of every visual shape of the world's bodies.

        A part is one (body, link): the links of the robot move, the robot's base, the
        ground and the riser do not, so their poses are taken once here.
        """
        bodies = [self.body, self.ground] + ([self.riser] if self.riser is not None else [])
        parts, shapes, static = {}, [], {}
        for body in bodies:
            for data in self._call(pybullet.getVisualShapeData, body):
                link, kind, dims, mesh, xyz, quat, rgba = data[1:8]
                if kind == pybullet.GEOM_BOX:
                    tris = box_triangles(np.asarray(dims) / 2.0)
                elif kind == pybullet.GEOM_CYLINDER:  # dims: (length, radius)
                    tris = cylinder_triangles(dims[1] + PYBULLET_CYLINDER_MARGIN_M,
                                              dims[0] + 2.0 * PYBULLET_CYLINDER_MARGIN_M)
                elif kind == pybullet.GEOM_MESH:
                    tris = obj_triangles(Path(mesh.decode()).read_text(), dims)
                else:
                    raise RendererError(f'visual geometry {kind} of body {body} link {link} '
                                        'is not supported')
                part = parts.setdefault((body, link), len(parts))
                shapes.append(Shape(part, *transformed(*tris, _pose_matrix(xyz, quat)),
                                    tuple(rgba[:3])))
                if body != self.body or link < 0:
                    static[part] = self._base_frame(body)
        robot_links = sorted(link for body, link in parts if body == self.body and link >= 0)
        try:
            self.renderer = GLRenderer(shapes, NEAR_M, FAR_M, LIGHT_DIRECTION)
        except GLRendererError as exc:
            raise RendererError(f'the OpenGL renderer cannot start here: {exc}') from None
        self._gl_links = robot_links
        self._gl_link_parts = [parts[(self.body, link)] for link in robot_links]
        self._gl_poses = np.empty((len(parts), 4, 4))
        for part, pose in static.items():
            self._gl_poses[part] = pose

    def _base_frame(self, body):
        """Return the pose in {O} of the frame of ``body``'s base (its URDF base link)."""
        position, quaternion = self._call(pybullet.getBasePositionAndOrientation, body)
        # PyBullet's base pose is that of the base's inertial frame; the visuals hang off the
        # link frame, which lies at the inverse of the local inertial frame from it.
        info = self._call(pybullet.getDynamicsInfo, body, -1)
        inertial = _pose_matrix(info[3], info[4])
        return _pose_matrix(position, quaternion) @ np.linalg.inv(inertial)

    def _gl_part_poses(self):
        """Return the poses (P, 4, 4) of the parts of :meth:`_renderer_setup` now."""
        states = self._call(pybullet.getLinkStates, self.body, self._gl_links,
                            computeForwardKinematics=True)
        for part, state in zip(self._gl_link_parts, states):
            self._gl_poses[part] = _pose_matrix(state[4], state[5])
        return self._gl_poses

    def _box(self, half_extents, z_centre, rgba):
        """Add a static box (visual only) centred on the z axis of {O}; return its body."""
        shape = self._call(pybullet.createVisualShape, pybullet.GEOM_BOX,
                           halfExtents=half_extents, rgbaColor=rgba)
        return self._call(pybullet.createMultiBody, baseMass=0.0, baseVisualShapeIndex=shape,
                          basePosition=(0.0, 0.0, z_centre))

    @property
    def render_device(self) -> RenderDevice | None:
        """Return what draws the images (GL_RENDERER, hardware or not); None: render false."""
        return None if self.renderer is None else self.renderer.device

    def close(self) -> None:
        """Release the renderer and disconnect the client (idempotent)."""
        if self.renderer is not None:
            self.renderer.close()
            self.renderer = None
        if self._client is not None and self._call(pybullet.isConnected):
            pybullet.disconnect(physicsClientId=self._client)
        self._client = None

    def reset(self, q: ArrayLike, qd: ArrayLike | None = None) -> None:
        """Set the true joint angles (and velocities, default 0) without dynamics."""
        q = np.asarray(q, float)
        qd = np.zeros(6) if qd is None else np.asarray(qd, float)
        for j, angle, rate in zip(self.joints, q, qd):
            self._call(pybullet.resetJointState, self.body, j, float(angle), float(rate))

    def joint_state(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return the true joint angles and velocities, two (6,) arrays."""
        states = self._call(pybullet.getJointStates, self.body, self.joints)
        return (np.array([s[0] for s in states]), np.array([s[1] for s in states]))

    def inverse_dynamics(self, q: ArrayLike, qd: ArrayLike, qdd: ArrayLike
                         ) -> NDArray[np.float64]:
        """Return tau = M(q) qdd + C(q, qd) qd + g(q) from PyBullet's inverse dynamics."""
        return np.array(self._call(pybullet.calculateInverseDynamics, self.body,
                                   [float(v) for v in q], [float(v) for v in qd],
                                   [float(v) for v in qdd]))

    def hold_torque(self) -> NDArray[np.float64]:
        """
        Return the torque that stops the arm where it is within this step.

        tau = ID(q, qd, -qd / h): with semi-implicit Euler, qd_{k+1} = 0 and q_{k+1} = q_k.
        An arm at rest gets its gravity torque. (An ideal brake: the real arm would need its
        braking distance.)
        """
        q, qd = self.joint_state()
        return self.inverse_dynamics(q, qd, -qd / self.dt)

    def step(self, torque: ArrayLike) -> None:
        """Apply ``torque`` (6,) N m for one step of h seconds and advance the physics."""
        self._call(pybullet.setJointMotorControlArray, self.body, self.joints,
                   pybullet.TORQUE_CONTROL, forces=[float(t) for t in torque])
        self._call(pybullet.stepSimulation)

    def link_pose(self, name: str) -> NDArray[np.float64]:
        """Return the 4x4 pose in {O} of the URDF frame of link ``name`` (PyBullet's FK)."""
        state = self._call(pybullet.getLinkState, self.body, self.links[name],
                           computeForwardKinematics=True)
        return _pose_matrix(state[4], state[5])

    def marker_spheres(self) -> list[tuple[NDArray[np.float64], float]]:
        """Return the fiducials as (centre (3,) in {O}, radius m) pairs (none without tool)."""
        return [(self.link_pose(name)[:3, 3], MARKER_RADIUS_M)
                for name in ('marker_1', 'marker_2') if name in self.links]

    def render_stereo(self, camera: StereoCamera, supersampling: int = 1,
                      focus: Iterable[tuple[ArrayLike, float]] = (),
                      focus_supersampling: int = DEFAULT_FOCUS_SUPERSAMPLING
                      ) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
        """
        Return (left, right) RGB images (H, W, 3) uint8 seen by ``camera`` (eq. 16-22).

        ``camera`` is an :class:`ibvs_model.StereoCamera`; both lenses share its intrinsics.
        ``supersampling``: samples per pixel along each axis, 1 to MAX_SUPERSAMPLING
        (:mod:`ibvs_sim.rendering`, pixel integration); the cost grows with its square.
        ``focus``: spheres (centre in {O}, radius m), e.g. :meth:`marker_spheres`, whose
        images are rendered again with ``focus_supersampling`` (1 to MAX_FOCUS_SUPERSAMPLING)
        samples per pixel along each axis in the windows of :func:`focus_windows`.
        """
        if not isinstance(camera, StereoCamera):
            raise TypeError('camera must be an ibvs_model.StereoCamera')
        if supersampling not in range(1, MAX_SUPERSAMPLING + 1):
            raise ValueError(f'supersampling must be an int in [1, {MAX_SUPERSAMPLING}], '
                             f'got {supersampling!r}')
        if focus_supersampling not in range(1, MAX_FOCUS_SUPERSAMPLING + 1):
            raise ValueError('focus_supersampling must be an int in '
                             f'[1, {MAX_FOCUS_SUPERSAMPLING}], got {focus_supersampling!r}')
        return tuple(self._render_lenses(lens_poses(camera), camera.intrinsics, supersampling,
                                         tuple(focus), focus_supersampling))

    def render_lens(self, pose: ArrayLike, intrinsics: 'StereoIntrinsics', supersampling: int = 1,
                    focus: Iterable[tuple[ArrayLike, float]] = (),
                    focus_supersampling: int = DEFAULT_FOCUS_SUPERSAMPLING
                    ) -> NDArray[np.uint8]:
        """
        Return the RGB image (H, W, 3) uint8 of one lens at ``pose`` (T of its optical frame).

        The arguments are those of :meth:`render_stereo`, checked there.
        """
        return self._render_lenses([pose], intrinsics, supersampling, tuple(focus),
                                   focus_supersampling)[0]

    def _render_lenses(self, poses, intrinsics, supersampling, focus, focus_supersampling):
        """
        Return the images of lenses at ``poses``, drawn in one go.

        The passes (each lens's image, then its marker windows) at the link poses of now,
        drawn by one :meth:`ibvs_sim.rendering.Renderer.render_passes`; the full images
        leave out what the windows cover. The other arguments are those of
        :meth:`render_stereo`.
        """
        if self.renderer is None:
            raise RendererError('this World was built with render false: it draws nothing')
        k = supersampled(intrinsics, supersampling)
        passes, lens_windows = [], []
        for pose in poses:
            view = view_matrix(pose)
            windows = []
            if focus and focus_supersampling > supersampling:
                windows = focus_windows(intrinsics, pose, focus)
            passes.append((view, projection_matrix(k), k.width, k.height,
                           [tuple(supersampling * c for c in w) for w in windows]))
            for window in windows:
                fine = supersampled(window_intrinsics(intrinsics, window), focus_supersampling)
                passes.append((view, projection_matrix(fine), fine.width, fine.height, ()))
            lens_windows.append(windows)
        drawn = iter(self.renderer.render_passes(self._gl_part_poses(), passes))
        images = []
        for windows in lens_windows:
            image = box_downsample(next(drawn), supersampling)
            for u0, v0, u1, v1 in windows:
                image[v0:v1, u0:u1] = box_downsample(next(drawn), focus_supersampling)
            images.append(image)
        return images
