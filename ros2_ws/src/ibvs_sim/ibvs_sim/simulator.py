"""
The plant of the paper's Figure 3 without ROS: physics, encoders, camera frames, sim time.

Time (docs/design.md §4). Step k is at t_k = k * dt_ns integer nanoseconds, dt_ns =
round(1e9 / physics_rate_hz). Camera frame n is due at n * T_cam, T_cam =
round(1e9 / camera_rate_hz) ns, and rendered from the state of the first physics step at or
after that time; its stamp is the sim time of that step
(ibvs_common.timing.frame_stamp_ns), so an image and the joint state it shows carry the
same stamp. The camera period need not be a whole number of steps: 30 Hz frames on a 1 kHz
physics grid, the paper's values, are stamped 0, 34, 67, 100 ms, ... (up to 0.67 ms after
n * T_cam).

Joint disturbance (the paper's d_q, eq. 30): true angle = encoder angle + d_q, so the
encoders read q_T = q - d_q. The start pose of a scenario is reached by the TRUE angles:
q(0) = IK(start pose) of the simulated robot (which may have scaled L2 and L4, Figure 13).

A real camera (:mod:`.camera_effects`). Images are rendered with the true camera
(``camera``) and get the image noise of ``effects``; a frame may be lost (both images).
``calibrated_camera`` is what a calibration with the set pose and focal-length errors gives:
the one to publish to the controllers. With ``teach_pose``, ``teach_images`` is the stereo
pair of the tool placed at that flange pose (the true robot's IK), rendered with the true
camera and noise before the run, as a user teaches a target on the real cell.
"""

from fractions import Fraction

from ibvs_common.params import ParameterError
from ibvs_common.shared_params import start_joints
from ibvs_common.teach import FrameMean
from ibvs_model import (forward_kinematics, forward_kinematics_batch, inverse_kinematics,
                        look_at, ModelError, paper, pose_error, StereoCamera,
                        StereoIntrinsics)
from ibvs_model.ik_branch import nearest_branch_ik
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .camera_effects import calibrated_intrinsics, calibrated_pose, CameraEffects
from .node_params import SimConfig
from .world import RendererError, World


class ConfigError(ParameterError):
    """A configuration the simulator cannot run; ``param`` names the parameter at fault."""

    def __init__(self, param: str, message: str) -> None:
        """Keep the parameter's name and the reason."""
        super().__init__(f"parameter '{param}': {message}", param)


class Simulator:
    """
    The simulated IRB 4600 with its stereo camera, advanced one physics step at a time.

    ``config``: the sim_node parameters (:class:`.node_params.SimConfig`, each value checked
    there). ``teach_pose``: a flange pose T_E^O whose stereo pair to render before the run
    (module docstring), or None. ``render``: False builds no renderer (physics only; a
    frame is then taken without images, :meth:`take_frame`). ``start_pose``: a flange pose
    T_E^O to start at instead of the scenario's (solved as ``teach_pose`` is), or None.

    Raises :class:`ConfigError` at construction for what no single parameter's range
    says: a camera rate above the physics rate, a start pose (or a pose to teach) the
    simulated robot cannot reach, a camera eye and look-at point that give no camera pose,
    and an OpenGL renderer that cannot start here (named as ``publish_images``).
    """

    def __init__(self, config: SimConfig = SimConfig(),
                 teach_pose: ArrayLike | None = None, render: bool = True,
                 start_pose: ArrayLike | None = None) -> None:
        """Check the combinations, solve the start pose and build the PyBullet world."""
        self.config = config
        self.dt_ns = config.timing.step_ns  # frames no faster than steps: the timing's check
        self.camera_period_ns = config.timing.camera_period_ns
        self.frames_exact = self.camera_period_ns % self.dt_ns == 0
        self.scenario = config.scenario
        self.d_q = config.plant.d_q
        self.params = config.plant.robot
        target = paper.scenario_start_pose(config.scenario)
        try:
            given = start_joints(config.start_joints)
        except ParameterError as exc:
            raise ConfigError('start_joints', str(exc)) from None
        if given is not None:  # a task's start (start_joints): the true angles as given
            target = forward_kinematics(given, self.params)
        try:
            if start_pose is not None:  # the tool held at the target: the teach's IK
                target = np.asarray(start_pose, dtype=float)
                self.q_start = inverse_kinematics(target, self.params)
            else:
                # The branch nearest q = 0 inside the reach cone (no over-the-head arm).
                self.q_start = nearest_branch_ik(target, np.zeros(6), self.params) \
                    if given is None else given
        except ModelError as exc:
            if start_pose is not None:
                raise ConfigError('start_at_target', 'the target pose is unreachable by the '
                                  f'simulated robot: {exc}') from None
            raise ConfigError('scenario', f'start pose of scenario {config.scenario} is '
                              f'unreachable by the simulated robot (l2_scale = '
                              f'{config.plant.l2_scale}, l4_scale = {config.plant.l4_scale}): '
                              f'{exc}') from None
        self.start_residual = pose_error(forward_kinematics(self.q_start, self.params), target)
        intrinsics = StereoIntrinsics.zed2(config.resolution, config.pub_downscale_factor)
        try:
            self.camera = StereoCamera(intrinsics,
                                       look_at(config.camera_eye, config.camera_look_at))
        except ModelError as exc:
            raise ConfigError('camera_look_at', f'camera_eye = {list(config.camera_eye)}, '
                              f'camera_look_at = {list(config.camera_look_at)}: {exc}') \
                from None
        self.effects = CameraEffects(config.image_noise_stddev, config.frame_drop_probability,
                                     config.camera_seed)
        self.calibrated_camera = StereoCamera(
            calibrated_intrinsics(intrinsics, config.focal_length_error),
            calibrated_pose(self.camera.pose_C_O, config.camera_pose_error_xyz_m,
                            config.camera_pose_error_rpy_deg))
        self.render_supersampling = config.render_supersampling
        self.render_marker_supersampling = config.render_marker_supersampling
        try:
            self.world = World(self.params, float(Fraction(10 ** 9, self.dt_ns)),
                               mount_height_m=config.mount_height_m, render=render)
        except RendererError as exc:  # the parameter that asks for images
            raise ConfigError('publish_images', f'{exc} (false: the physics only, no images)') \
                from None
        self.teach_q = self.teach_images = None
        if teach_pose is not None:
            try:
                self.teach_q = inverse_kinematics(teach_pose, self.params)
            except ModelError as exc:
                raise ConfigError('target_position', f'the target pose to teach is '
                                  f'unreachable by the simulated robot: {exc}') from None
            self.world.reset(self.teach_q)
            self.teach_images = self._teach(config.teach_frames)
        self.world.reset(self.q_start)
        self.k = 0
        self.next_frame = 0
        self.frames_lost = 0
        self.last_torque = np.zeros(6)

    @property
    def t_ns(self) -> int:
        """Return the sim time of the current step, integer nanoseconds."""
        return self.k * self.dt_ns

    def close(self) -> None:
        """Release the PyBullet client."""
        self.world.close()

    def true_state(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Return the true joint angles and velocities."""
        return self.world.joint_state()

    def encoders(self, state: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """
        Return what the encoders read: (q - d_q, qd), the paper's q_T and its rate.

        ``state``: the :meth:`true_state` of this step, if the caller has it already.
        """
        q, qd = self.world.joint_state() if state is None else state
        return q - self.d_q, qd

    def tool_pose(self) -> NDArray[np.float64]:
        """Return the true flange pose T_E^O (eq. 7) of the simulated robot."""
        return forward_kinematics(self.world.joint_state()[0], self.params)

    def tool_poses(self, qs: ArrayLike) -> NDArray[np.float64]:
        """Return T_E^O of true joint angles ``qs`` (n, 6), each bit for bit :meth:`tool_pose`."""
        return forward_kinematics_batch(qs, self.params)

    def frame_due(self) -> int | None:
        """Return when the camera frame to take at this step was due (n * T_cam ns), or None."""
        stamp = self.next_frame * self.camera_period_ns
        return stamp if stamp <= self.t_ns else None

    def take_frame(self, render: bool = True
                   ) -> tuple[int, tuple[NDArray[np.uint8], NDArray[np.uint8]] | None, bool]:
        """
        Return (stamp ns, (left, right) images or None, lost) of the frame due now; advance n.

        The stamp is this step's sim time. ``lost``: the camera lost this frame
        (``frame_drop_probability``); its images are then None and nothing is rendered.
        With ``render`` False a kept frame is only counted (images off). The images are
        rendered with the true camera, noise added.
        """
        if self.frame_due() is None:
            raise RuntimeError(f'no frame due at t = {self.t_ns} ns')
        stamp = self.t_ns
        self.next_frame += 1
        if self.effects.frame_lost():
            self.frames_lost += 1
            return stamp, None, True
        return stamp, (self._render() if render else None), False

    def skip_frame(self) -> int:
        """
        Return when the frame due now was due (ns) and advance n, taking no frame.

        A camera that is not there (sim_node's ``camera_outage_s``): nothing is rendered,
        no loss drawn, nothing counted as lost.
        """
        stamp = self.frame_due()
        if stamp is None:
            raise RuntimeError(f'no frame due at t = {self.t_ns} ns')
        self.next_frame += 1
        return stamp

    def _draw(self):
        """Return the stereo pair of the current state as the true camera sees it."""
        return self.world.render_stereo(self.camera, self.render_supersampling,
                                        self.world.marker_spheres(),
                                        self.render_marker_supersampling)

    def _render(self):
        """Return the stereo pair of the current state: true camera, image noise added."""
        return self.effects.noisy(self._draw())

    def _teach(self, frames):
        """
        Return the teach pair: ``frames`` noisy pairs of the still tool, averaged.

        One frame is :meth:`_render`'s pair. More are the pixelwise mean of as many 8-bit
        pairs, each with its own noise, rounded to 8 bits (:class:`ibvs_common.teach.
        FrameMean`, the rule ``ibvs teach`` follows on a cell): what a user who holds the tool
        still at the target and averages the camera's frames gets (the scene is static, so
        the pair is drawn once and only the noise differs; without noise, that one pair).
        """
        if frames == 1 or self.effects.noise_stddev == 0.0:
            return self._render()
        clean = self._draw()
        mean = FrameMean()
        for _ in range(frames):
            mean.add(self.effects.noisy(clean))
        return mean.mean()

    def hold_torque(self) -> NDArray[np.float64]:
        """Return the torque that stops the arm where it is in one step (World.hold_torque)."""
        return self.world.hold_torque()

    def move_to(self, q: ArrayLike, qd: ArrayLike) -> None:
        """
        Set the true joints to ``q`` with speed ``qd`` as the next step's state; k += 1.

        ``q``, ``qd``: the position drive's output (:class:`.position_servo.PositionServo`).
        No torque is modelled: ``last_torque`` becomes None.
        """
        q, qd = np.asarray(q, dtype=float), np.asarray(qd, dtype=float)
        if q.shape != (6,) or qd.shape != (6,) or not np.all(np.isfinite(q)) \
                or not np.all(np.isfinite(qd)):
            raise ValueError('q and qd must be 6 finite values each')
        self.world.reset(q, qd)
        self.k += 1
        self.last_torque = None

    def step(self, torque: ArrayLike | None = None) -> NDArray[np.float64]:
        """
        Apply ``torque`` (6,) for one step, or the holding torque when None; then k += 1.

        Returns the torque applied.
        """
        torque = self.hold_torque() if torque is None else np.asarray(torque, dtype=float)
        if torque.shape != (6,) or not np.all(np.isfinite(torque)):
            raise ValueError('torque must be 6 finite values')
        self.world.step(torque)
        self.k += 1
        self.last_torque = torque
        return torque
