"""
sim_node: the simulated plant (paper Figure 3), a PyBullet IRB 4600 seen by a ZED 2.

One class per time mode, which follows from ``command_interface``
(:func:`ibvs_common.shared_params.lockstep`): 'effort' runs
:class:`.lockstep_sim.LockstepSim`, which steps on each effort command of the
current stamp (/joint_effort_commands), 'position' :class:`.free_running_sim.FreeRunningSim`,
which runs on its own at ``real_time_factor`` and follows position references
(/forward_position_controller/commands or /joint_trajectory_controller/joint_trajectory).

Each step (:meth:`SimNode.publish_step`) publishes, when /clock is due (``clock_rate_hz``),
the true flange poses and joint states of the steps since the last /clock
(/ibvs/tool_path, /ibvs/joint_path), then /clock; /joint_states (encoder angles q - d_q,
velocities, the last torque, ``extra_joints`` at 0) as the mode says; and on a camera
frame's step the rendered stereo pair with its CameraInfo (``camera_topics``: this
project's /stereo/* or zed_wrapper's names) or, for a lost frame, a Header on
/stereo/frame_lost. /stereo/pose (latched) carries the calibrated camera, the images show
the true one (:mod:`.camera_effects`); with target_features_source 'taught' the stereo
pair at the target goes out latched on /stereo/teach/{left,right}/image_raw.

Step 0 goes out once every reader the ``min_*_subscribers`` parameters name is matched
and the command topic has ``min_command_publishers`` publishers (until then a line a
second says what is missing); ``start_at_target`` starts the arm at the target pose (the
tool held there, to teach it); with ``duration_s`` the node stops
stepping at that sim time and stays up. Parameters: :class:`.node_params.SimNodeConfig`
(docs/parameters.md). Bad input is rejected, logged and counted on /diagnostics. The
contract in full: docs/nodes.md, docs/design.md §3 and §4.
"""

import time
from typing import Any

from geometry_msgs.msg import PoseStamped
from ibvs_common import contract
from ibvs_common.conversions import (camera_infos, image_msg, joint_path, joint_state,
                                     ns_stamp, path_msg, pose_stamped)
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.kit import config as kit_config, publisher, WaitReporter
from ibvs_common.node_main import run
from ibvs_common.timing import period_ns, seconds_to_ns
from nav_msgs.msg import Path
import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header
from trajectory_msgs.msg import JointTrajectory

from .free_running_sim import FreeRunningSim
from .lockstep_sim import LockstepSim
from .node_params import SimNodeConfig
from .simulator import Simulator

#: The node's typed configuration, built by ``ibvs run`` before any node starts.
CONFIG = SimNodeConfig
PARAMS = CONFIG.params()
#: ``SimNodeConfig.interface.lockstep`` -> the class that runs its time mode. The node reads its
#: ``clock_rate_hz``, ``frame_joint_subscribers``, ``delivery_delay_ns``, ``stamp_offset_ns``,
#: ``held_steps`` and ``command_sub`` and calls ``publish_joints``, ``exposes``, ``start``,
#: ``stop`` and ``waiting_line``.
MODES = {True: LockstepSim, False: FreeRunningSim}
#: Rules between parameters, run at start and by ``ibvs run`` before any node starts.
RULES = CONFIG.RULES

#: camera_topics -> (image topics, camera_info topics, frame ids, encoding, QoS).
CAMERA_OUTPUTS = {
    'ibvs': ((contract.LEFT_IMAGE, contract.RIGHT_IMAGE),
             (contract.LEFT_INFO, contract.RIGHT_INFO),
             (contract.LEFT_CAMERA_FRAME, contract.RIGHT_CAMERA_FRAME), 'rgb8',
             contract.IMAGES),
    'zed_wrapper': ((contract.ZED_LEFT_IMAGE, contract.ZED_RIGHT_IMAGE),
                    (contract.ZED_LEFT_INFO, contract.ZED_RIGHT_INFO),
                    (contract.ZED_LEFT_FRAME, contract.ZED_RIGHT_FRAME),
                    contract.ZED_ENCODING, contract.ZED_IMAGES),
}
#: Steady-clock period of the readiness poll before the start.
START_POLL_S = 0.02


class SimNode(Node):
    """PyBullet IRB 4600 and ZED 2; the time mode steps it (module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare and check the parameters, build the simulator, the interfaces, the mode."""
        super().__init__('sim_node', **kwargs)
        self.sim = None
        #: The (stamp ns, true q) and the /joint_states of the steps since the last batch.
        self._tool_poses, self._joint_states = [], []
        try:
            self._setup()
        except BaseException:
            # No half-built node for the garbage collector: main() cannot destroy it.
            self.destroy_node()
            raise

    def _setup(self):
        config = self.config = kit_config(self, SimNodeConfig)
        self._duration_ns = seconds_to_ns(config.duration_s)
        self.finished = False
        self._extra_joints = list(config.extra_joints)
        #: The frames rendered and not yet delivered, (due ns, stamp ns, images or None
        #: when lost, lost), in order (the mode's delivery_delay_ns after their exposure,
        #: stamped its stamp_offset_ns after it).
        self._deliveries = []
        self.frames_published = 0
        self.frames_outage = 0
        self._next_clock_ns = 0
        self.last_clock_ns = None
        target = config.target.pose if config.target.taught or config.start_at_target else None
        teach_pose = target if config.target.taught else None
        # Physics only (publish_images false): no renderer to load.
        self.sim = Simulator(config, teach_pose=teach_pose, render=config.publish_images,
                             start_pose=target if config.start_at_target else None)
        pos_err, rot_err = self.sim.start_residual
        self.get_logger().info(
            ('at the target' if config.start_at_target else f'scenario {self.sim.scenario}')
            + ': true start angles '
            f'{np.round(np.degrees(self.sim.q_start), 3).tolist()} deg (IK residual '
            f'{pos_err:.2e} m, {rot_err:.2e} rad); d_q '
            f'{np.round(np.degrees(self.sim.d_q), 3).tolist()} deg; renderer '
            f'{self.sim.world.renderer or "off"}; '
            f'{"exact" if self.sim.frames_exact else "nearest-step"} frame times')

        self.diagnostics = Diagnostics(self, 'simulator')
        self.diagnostics.update(step=0, sim_time_s=0.0, waiting_for_ns=-1, frames=0,
                                frames_lost=0, held_steps=0, start_residual_m=pos_err)
        device = self.sim.world.render_device
        if device is not None:  # what draws the images: reported in the run's metrics
            self.diagnostics.update(render_device=device.gl_renderer,
                                    render_hardware=device.hardware)
        self._pub_clock = publisher(self, ClockMsg, contract.CLOCK, contract.RELIABLE)
        self.pub_joints = publisher(self, JointState, contract.JOINT_STATES, contract.RELIABLE)
        self.pub_frame_joints = publisher(self, JointState, contract.FRAME_JOINT_STATES,
                                          contract.RELIABLE)
        self._pub_tool = publisher(self, Path, contract.TOOL_PATH, contract.RELIABLE)
        self._pub_joint_path = publisher(self, JointTrajectory, contract.JOINT_PATH,
                                         contract.RELIABLE)
        self._pub_images = self._pub_infos = ()
        image_topics, info_topics, self._camera_frames, self._encoding, qos = \
            CAMERA_OUTPUTS[config.camera_topics]
        if config.publish_images:
            self._pub_images = tuple(publisher(self, Image, topic, qos) for topic in image_topics)
            self._pub_infos = tuple(publisher(self, CameraInfo, topic, qos)
                                    for topic in info_topics)
        self._pub_lost = publisher(self, Header, contract.FRAME_LOST, contract.RELIABLE)
        # The controllers get the calibrated camera; the images show the true one.
        self._pose_pub = publisher(self, PoseStamped, contract.STEREO_POSE, contract.LATCHED)
        self._pose_pub.publish(pose_stamped(self.sim.calibrated_camera.pose_C_O, 0))
        self._teach_pubs = ()
        if self.sim.teach_images is not None:
            self._teach_pubs = tuple(
                publisher(self, Image, topic, contract.LATCHED)
                for topic in (contract.TEACH_LEFT_IMAGE, contract.TEACH_RIGHT_IMAGE))
            for pub, image, frame in zip(self._teach_pubs, self.sim.teach_images,
                                         (contract.LEFT_CAMERA_FRAME,
                                          contract.RIGHT_CAMERA_FRAME)):
                pub.publish(image_msg(image, 0, 'rgb8', frame))
        self.steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.mode = MODES[config.interface.lockstep](self, config)
        self.clock_period_ns = period_ns(self.mode.clock_rate_hz)

        self.started = False
        self.frames = 0
        self._start_timer = self.create_timer(START_POLL_S, self._try_start,
                                              clock=self.steady)
        self.waiting = WaitReporter(self, self._waiting)
        self._progress_mark = None
        self.diagnostics.log_progress(self._progress)

    def destroy_node(self) -> None:
        """Publish the last batches (the end of a run), release PyBullet with the node."""
        if self.context.ok():
            self._publish_tool_path()
            self._publish_joint_path()
        if self.sim is not None:
            self.sim.close()
        return super().destroy_node()

    def _missing(self):
        """Return what the start still waits for (empty when it can start)."""
        config = self.config
        missing = []
        have = self.mode.command_sub.get_publisher_count()
        if have < config.min_command_publishers:
            missing.append(f'{config.min_command_publishers - have} more publisher(s) on '
                           f'{self.mode.command_sub.topic_name}')
        for pub, wanted in ((self.pub_joints, config.min_joint_state_subscribers),
                            (self.pub_frame_joints, self.mode.frame_joint_subscribers),
                            (self._pub_tool, config.min_tool_path_subscribers),
                            (self._pub_joint_path, config.min_joint_path_subscribers)):
            have = pub.get_subscription_count()
            if have < wanted:
                missing.append(f'{wanted - have} more subscriber(s) on {pub.topic_name}')
        for pub in self._pub_images:
            if pub.get_subscription_count() < 1:
                missing.append(f'a subscriber on {pub.topic_name}')
        for pub in self._pub_infos:
            have = pub.get_subscription_count()
            if have < config.min_camera_info_subscribers:
                missing.append(f'{config.min_camera_info_subscribers - have} more '
                               f'subscriber(s) on {pub.topic_name}')
        return missing

    def _try_start(self):
        if self.started or self._missing():
            return
        self.started = True
        self._start_timer.cancel()
        self.get_logger().info('starting at t = 0: publishing step 0')
        self._progress_mark = (time.monotonic(), self.sim.t_ns)
        self.publish_step()
        self.mode.start()

    def _progress(self):
        """Return the progress line: sim time, real-time factor since the last, frames."""
        if self._progress_mark is None:
            return None
        now, t_ns = time.monotonic(), self.sim.t_ns
        wall0, t0_ns = self._progress_mark
        self._progress_mark = (now, t_ns)
        rtf = (t_ns - t0_ns) * 1e-9 / max(now - wall0, 1e-9)
        end = f' of {self._duration_ns * 1e-9:g} s' if self._duration_ns else ''
        state = 'stopped at duration_s' if self.finished else f'real-time factor {rtf:.3f}'
        return (f't = {t_ns * 1e-9:.3f} s{end} (step {self.sim.k}), {state}, '
                f'{self.frames} frames ({self.sim.frames_lost} lost)')

    def advance(self) -> None:
        """After a physics step: stop at duration_s, else publish the new step's outputs."""
        if self._duration_ns and self.sim.t_ns >= self._duration_ns:
            self._finish()
            return
        self.publish_step()

    def _finish(self):
        """Stop stepping at duration_s: the last batches and /clock out, then say so."""
        self.finished = True
        self.mode.stop()
        t_ns = self.sim.t_ns
        self._publish_tool_path()
        self._publish_joint_path()
        self._pub_clock.publish(ClockMsg(clock=ns_stamp(t_ns)))
        self.last_clock_ns = t_ns
        self.diagnostics.update(step=self.sim.k, sim_time_s=t_ns * 1e-9, waiting_for_ns=-1,
                                finished=True)
        self.get_logger().info(
            f'stopped at t = {t_ns * 1e-9:.3f} s (duration_s {self._duration_ns * 1e-9:g}): '
            'no further step; the nodes stay up until stopped (SIGINT: Ctrl-C, or '
            'ibvs_nodes_stop of docs/running.md)')

    def _waiting(self):
        """Return the wait reporter's line: the start, or what the mode waits for."""
        if self.finished:
            return None
        if not self.started:
            return 'waiting to start for ' + ', '.join(self._missing())
        return self.mode.waiting_line()

    def publish_step(self) -> None:
        """Publish the outputs of the current step (module docstring, in this order)."""
        sim = self.sim
        t_ns = sim.t_ns
        timing = self.diagnostics.timing
        clock_due = t_ns >= self._next_clock_ns
        state = sim.true_state()
        with timing.section('tool_path'):
            if clock_due:
                self._publish_tool_path()
            self._tool_poses.append((t_ns, state[0]))  # T_E^O in a batch, at publication
        frame_step = sim.frame_due() is not None
        with timing.section('step_messages'):
            if clock_due:
                self._publish_joint_path()
                self._pub_clock.publish(ClockMsg(clock=ns_stamp(t_ns)))
                self.last_clock_ns = t_ns
                self._next_clock_ns = (t_ns // self.clock_period_ns + 1) * self.clock_period_ns
            q, qd = sim.encoders(state)
            joints = joint_state(t_ns, q, qd, sim.last_torque)
            self.mode.publish_joints(t_ns, joints, frame_step)
            self._joint_states.append(joints)
        if frame_step:
            if not self.mode.exposes(t_ns):
                sim.skip_frame()  # camera_outage_s: the camera is gone, it says nothing
                self.frames_outage += 1
            else:
                with timing.section('render'):
                    stamp, images, lost = sim.take_frame(render=self.config.publish_images)
                self.frames += 1
                self._deliveries.append((stamp + self.mode.delivery_delay_ns,
                                         stamp + self.mode.stamp_offset_ns,
                                         None if lost else images, lost))
        while self._deliveries and self._deliveries[0][0] <= t_ns:
            self._deliver(*self._deliveries.pop(0)[1:])
        timing.reached(t_ns)
        self.diagnostics.update(step=sim.k, sim_time_s=t_ns * 1e-9, waiting_for_ns=t_ns,
                                frames=self.frames, frames_lost=sim.frames_lost,
                                held_steps=self.mode.held_steps)

    def with_extra_joints(self, joints: JointState) -> JointState:
        """Return ``joints`` with the extra_joints at 0 (a new message), or itself."""
        if not self._extra_joints:
            return joints
        msg = JointState(header=joints.header, name=list(joints.name) + self._extra_joints)
        zeros = [0.0] * len(self._extra_joints)
        msg.position = list(joints.position) + zeros
        msg.velocity = list(joints.velocity) + zeros if len(joints.velocity) else []
        msg.effort = list(joints.effort) + zeros if len(joints.effort) else []
        return msg

    def _deliver(self, stamp, images, lost):
        """Publish a frame as its camera stamps it: its images and CameraInfo, or lost."""
        if lost:
            self._pub_lost.publish(Header(stamp=ns_stamp(stamp),
                                          frame_id=contract.CAMERA_FRAME))
        elif images is not None:
            with self.diagnostics.timing.section('image_messages'):
                frames = self._camera_frames
                infos = camera_infos(self.sim.calibrated_camera.intrinsics, stamp, frames)
                for pub, info_pub, image, info, frame in zip(
                        self._pub_images, self._pub_infos, images, infos, frames):
                    pub.publish(image_msg(image, stamp, self._encoding, frame))
                    info_pub.publish(info)
            self.frames_published += 1
            self.diagnostics.update(frames_published=self.frames_published,
                                    frames_outage=self.frames_outage)

    def _publish_tool_path(self):
        """Publish the true tool poses of the steps since the last batch, if any."""
        if self._tool_poses:
            stamps, qs = zip(*self._tool_poses)
            self._pub_tool.publish(path_msg(list(zip(stamps, self.sim.tool_poses(qs)))))
            self._tool_poses = []

    def _publish_joint_path(self):
        """Publish the /joint_states of the steps since the last batch, if any."""
        if self._joint_states:
            self._pub_joint_path.publish(joint_path(self._joint_states))
            self._joint_states = []


def main(args: list[str] | None = None) -> None:
    """Run the simulator node (``ros2 run ibvs_sim sim_node``)."""
    run(SimNode, args=args, name='sim_node')


if __name__ == '__main__':
    main()
