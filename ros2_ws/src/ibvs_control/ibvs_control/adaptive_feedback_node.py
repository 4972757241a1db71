"""
adaptive_feedback_node: the adaptive Youla feedback of section 4.2, one q_feedback a frame.

Inputs: the camera model from /stereo/{left,right}/camera_info and /stereo/pose
(ibvs_common.conversions.camera_from_msgs), the encoder joints /joint_states, and the
features /ibvs/features (stamp t_f = the frame's). Target features p_bar
(``target_features_source``): 'model', F(q_target), the target markers projected with the
calibrated camera (eq. 30); or 'taught', the latched /ibvs/target_features that the feature
node measured on a stereo pair of the tool at the target pose (no frame is answered before
it has come). Per frame (:class:`.controllers.AdaptiveFeedback`):
q~ = F^-1(p_hat) (eq. 42) with q6 and the IK branch from the encoder joints, C1 = J (eq.
31) at the encoder angles (default) or at q~ (``linearise_at``: 'features', the paper's
choice), SVD decoupling (eq. 34, rank 5), q_feedback = k_d(z) C1^+ (p_bar - p_hat)
(eq. 38-41), discretised at the camera period.

Determinism (docs/design.md §4). The encoder joints of frame t_f are those of the first
/joint_states stamped at or after t_f (the simulator renders frame n from the first physics
step at or after n * T_cam and publishes that step's joint state with it), kept in a short
history by stamp. A frame waits until the camera model and that joint state have arrived;
frames are processed in stamp order (the rule: :class:`.frame_lockstep.FrameLockstep`, plain
Python, tested without rclpy).

Every frame is answered by one /ibvs/q_feedback stamped t_f, so that the joint controller,
which waits for it, never stalls: a frame that cannot be used (NaN or wrong number of
points, no triangulation or IK: rejected and counted on /diagnostics; older than
``stale_timeout_s`` of sim time: rejected as stale) is answered with the held q_feedback,
its integrator frozen. A frame the camera lost (/stereo/frame_lost) brings no features and
gets no answer: the controller skips that sample and q_feedback holds (the joint controller
holds it too). Sim time "now" is the newest /joint_states stamp (deterministic in
lockstep, unlike the arrival of /clock). When no usable frame has come for
``stale_timeout_s`` of sim time, the feedback is marked frozen (WARN on /diagnostics) and
logged; it resumes with the next fresh frame. A frame not newer than the last one
answered is rejected, not answered. Every stamp goes through the one stamp rule
(:func:`ibvs_common.conversions.read_stamp`): a malformed one, or one more than
``stale_timeout_s`` and a camera period ahead of the newest time the node knows (its clock,
its newest joint state; 0 before either) is rejected and never stored, so that it cannot
make every later input look stale; joint states beyond ``POSITION_BOUND_RAD`` or faster
than ``SPEED_BOUND_RAD_S`` (:mod:`ibvs_common.conversions`) are rejected too. Each CameraInfo
is checked on its own (:func:`ibvs_common.conversions.check_camera_info`: size, focal
length, principal point, baseline), the pair together
(:func:`ibvs_common.conversions.intrinsics_from_infos`), and one that differs from the pair
the camera model was built from is refused ('camera_info changed': the model is built
once); a camera pose looking away from the robot is refused; each is counted under its
topic's resolved name. /diagnostics: singular
values of C1, condition number, rank used, image error norm.

Servo law (``servo_law``, :mod:`.servo_laws`): 'paper' (default) is the above. 'ibvs'
(classic IBVS) and 'pbvs' (position-based) integrate a velocity command per frame and
carry the whole move (the feedforward node then holds q(0): feedforward_method 'hold',
checked at start); 'switching' runs the paper's feedback from the first measured frame
after the feedforward has settled. A law that needs to know whether a frame was measured
or estimated (eq. 46) (:meth:`.servo_laws.ServoLaw.needs_measured`: 'switching', and
'ibvs' / 'pbvs' with ``feature_fallback`` 'hold') also waits, per frame, for
/ibvs/feature_status of the same stamp (read by
:func:`ibvs_common.conversions.read_feature_status`; measured: the detector found both
markers in both images, blended or not). The others do not subscribe to it.
"""

from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PolygonStamped, PoseStamped
from ibvs_common import contract, intra_process
from ibvs_common.conversions import (camera_from_msgs, check_camera_info, InputError,
                                     joint_state, pose_stamped, position_bounds,
                                     read_camera_pose, read_feature_status, read_features,
                                     read_joints, read_stamp, stamp_lead_ns, velocity_bounds)
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.node_main import run
from ibvs_common.params import declare
from ibvs_common.shared_params import (CAMERA_POSE, camera_pose_from, CAMERA_RATE_HZ,
                                       STALE_TIMEOUT_S, TARGET_FEATURES_SOURCE,
                                       TARGET_POSITION, TARGET_ROTATION)
from ibvs_common.sim_time import node_time_ns
from ibvs_common.sync import Rejection
from ibvs_common.timing import ns_to_seconds, period_ns, seconds_to_ns
from ibvs_model import CameraRobotModel, IRB4600, ModelError
import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, JointState

from .frame_lockstep import FrameLockstep
from .node_params import (check_gains, check_servo_law, FEEDFORWARD_METHOD, LAMBDA_0,
                          LAMBDA_INF, LAMBDA_SLOPE, LAW_PARAMS, law_settings, SERVO_LAW,
                          target_from)
from .servo_laws import law_class

PARAMS = (CAMERA_RATE_HZ, TARGET_POSITION, TARGET_ROTATION, STALE_TIMEOUT_S,
          TARGET_FEATURES_SOURCE, SERVO_LAW, FEEDFORWARD_METHOD, LAMBDA_0, LAMBDA_INF,
          LAMBDA_SLOPE, CAMERA_POSE) + LAW_PARAMS

#: Steady-clock period of the 'waiting' log.
WAIT_LOG_S = 1.0
#: Encoder joint states kept for matching frames (2 s at 1 kHz); most frames buffered.
HISTORY = 2000


class AdaptiveFeedbackNode(Node):
    """F^-1, C1, SVD and the Youla controller per frame (module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare and check the parameters and create the interfaces."""
        super().__init__('adaptive_feedback_node', **kwargs)
        self.values = values = declare(self, PARAMS)
        check_gains(values)
        self.gain = check_servo_law(values)
        self.law = law_class(values['servo_law'])
        self.needs_status = self.law.needs_measured(values)
        self.pose = target_from(values)
        self.camera_ns = period_ns(values['camera_rate_hz'])
        self.stale_timeout_ns = seconds_to_ns(values['stale_timeout_s'])
        self.lead_ns = stamp_lead_ns(values['stale_timeout_s'], self.camera_ns)
        self.feedback = None
        self._infos = [None, None]
        self._camera_pose = None
        self._taught = values['target_features_source'] == 'taught'
        self._p_target = None
        self.last_fresh_ns = None
        self.first_joint_ns = None
        self.frozen = False
        self._envelope_seen = set()
        self.frames = 0
        self.diagnostics = Diagnostics(self, 'adaptive feedback')
        self.diagnostics.update(state='waiting for camera', frames=0)
        self.diagnostics.log_progress(self._progress)
        # The frames' messages between nodes of one process pass as objects, and through
        # DDS to readers elsewhere (ibvs_common.intra_process); latched ones take DDS only.
        self._pub = intra_process.publisher(self, JointState, contract.Q_FEEDBACK,
                                            contract.RELIABLE)
        # The resolved names (the ZED wrapper's under a remap): rejections are counted there.
        self._info_topics = [
            intra_process.subscription(self, CameraInfo, topic,
                                       lambda m, i=i: self._on_info(i, m),
                                       contract.IMAGES).topic_name
            for i, topic in enumerate((contract.LEFT_INFO, contract.RIGHT_INFO))]
        calibrated = camera_pose_from(values)
        if calibrated is None:
            self.create_subscription(PoseStamped, contract.STEREO_POSE, self._on_pose,
                                     contract.LATCHED)
        else:  # a hand-eye calibration's result, as a parameter
            self._camera_pose = pose_stamped(calibrated, 0)
        # The resolved name: the runner remaps it to /stereo/joint_states (one a frame).
        joints = intra_process.subscription(self, JointState, contract.JOINT_STATES,
                                            self._on_joint_state, contract.RELIABLE)
        self._joints_topic = joints.topic_name
        self._lockstep = FrameLockstep(HISTORY, self.needs_status,
                                       joints_name=joints.topic_name,
                                       status_name=contract.FEATURE_STATUS,
                                       full_note='waiting for the camera model')
        intra_process.subscription(self, PolygonStamped, contract.FEATURES,
                                   self._on_features, contract.RELIABLE)
        if self._taught:
            self.create_subscription(PolygonStamped, contract.TARGET_FEATURES,
                                     self._on_target, contract.LATCHED)
        if self.needs_status:
            intra_process.subscription(self, DiagnosticArray, contract.FEATURE_STATUS,
                                       self._on_status, contract.RELIABLE)
        self._steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._answered_since_log = True
        self.create_timer(WAIT_LOG_S, self._log_waiting, clock=self._steady)
        self.get_logger().info(f"servo law '{self.law.name}'")

    def _missing(self):
        """Return what the oldest pending frame still waits for (empty: nothing pending)."""
        t_ns = self._lockstep.frames.first_ns
        if t_ns is None:
            return []
        missing = []
        if self.feedback is None:
            inputs = ((self._info_topics[0], self._infos[0]),
                      (self._info_topics[1], self._infos[1]),
                      (contract.STEREO_POSE, self._camera_pose))
            missing += [topic for topic, msg in inputs if msg is None]
            if self._taught and self._p_target is None:
                missing.append(contract.TARGET_FEATURES)
            if not missing:
                missing.append('a usable camera model')
        missing += self._lockstep.waiting_for(t_ns)
        return [f'frame {t_ns} ns waits for ' + ', '.join(missing)] if missing else []

    def _progress(self):
        """Return the progress line: frames answered, the image error norm, the state."""
        if not self.frames:
            return None
        values = self.diagnostics.values
        error = values.get('image_error_norm_px')
        error = 'no image error yet' if error is None else f'image error norm {error:.3f} px'
        return f"{self.frames} frames answered, {error} ({self.law.name}, {values['state']})"

    def _log_waiting(self):
        missing = self._missing()
        if missing and not self._answered_since_log:
            self.get_logger().info('waiting: ' + '; '.join(missing))
        self.diagnostics.update(waiting_for='; '.join(missing) or 'nothing')
        self._answered_since_log = False

    # -- inputs ----------------------------------------------------------------------------
    def _on_info(self, index, msg):
        topic = self._info_topics[index]
        try:
            check_camera_info(msg)
        except InputError as exc:
            self.diagnostics.reject(topic, exc.reason, exc.detail)
            return
        if self.feedback is not None:  # the camera model is built once: it must not change
            built = self._infos[index]
            if (msg.width, msg.height, tuple(msg.p)) != (built.width, built.height,
                                                         tuple(built.p)):
                self.diagnostics.reject(topic, 'camera_info changed',
                                        'the camera model is built once, from the first '
                                        'usable pair; this one differs from it')
            return
        self._infos[index] = msg
        self._try_camera(topic)

    def _on_pose(self, msg):
        try:
            read_camera_pose(msg)
        except InputError as exc:
            self.diagnostics.reject(contract.STEREO_POSE, exc.reason, exc.detail)
            return
        if self.feedback is not None:
            return
        self._camera_pose = msg
        self._try_camera(contract.STEREO_POSE)

    def _on_target(self, msg):
        try:
            p_target = read_features(msg)
        except InputError as exc:
            self.diagnostics.reject(contract.TARGET_FEATURES, exc.reason, exc.detail)
            return
        if self.feedback is not None:
            return
        self._p_target = p_target
        self._try_camera(contract.TARGET_FEATURES)

    def _try_camera(self, source):
        """Build the servo law once every camera input is here; ``source`` came last."""
        if self._camera_pose is None or None in self._infos:
            return
        if self._taught and self._p_target is None:
            self.diagnostics.update(state=f'waiting for the taught {contract.TARGET_FEATURES}')
            return
        try:
            camera = camera_from_msgs(self._infos[0], self._infos[1], self._camera_pose)
            self.feedback = self.law.create(
                CameraRobotModel(camera, IRB4600), self.pose, ns_to_seconds(self.camera_ns),
                gain=self.gain, p_target=self._p_target, **law_settings(self.values))
        except (InputError, ModelError) as exc:
            # e.g. the target behind the camera: nothing to servo on; counted under the
            # input that completed the model, and the camera inputs are awaited again.
            reason = exc.reason if isinstance(exc, InputError) else type(exc).__name__
            self.diagnostics.reject(source, reason, str(exc))
            self._infos = [None, None]
            return
        self.diagnostics.update(state='running', servo_law=self.law.name,
                                p_target=self.feedback.p_target)
        self.get_logger().info(
            f'camera model ready; {"taught" if self._taught else "model"} target features '
            f'p_bar = '
            f'{np.round(self.feedback.p_target, 2).tolist()} px')
        self._drain()

    def now_ns(self) -> int:
        """Return the newest time the node knows: its clock and its newest joint state."""
        return node_time_ns(self, self._lockstep.joints.newest)

    def _on_joint_state(self, msg):
        try:
            t_ns = read_stamp(msg.header.stamp, self.now_ns(), self.lead_ns)
            q = read_joints(msg, bound=position_bounds())
            qd = read_joints(msg, 'velocity', bound=velocity_bounds())
        except InputError as exc:
            self.diagnostics.reject(self._joints_topic, exc.reason, exc.detail)
            return
        rejection = self._lockstep.offer_joints(t_ns, (q, qd))
        if rejection is not None:
            self.diagnostics.reject(self._joints_topic, *rejection)
            return
        if self.first_joint_ns is None:
            self.first_joint_ns = t_ns
        self._watch_timeout(t_ns)
        self._drain()

    def _on_features(self, msg):
        try:
            t_ns = read_stamp(msg.header.stamp, self.now_ns(), self.lead_ns)
        except InputError as exc:
            self.diagnostics.reject(contract.FEATURES, exc.reason, exc.detail)
            return
        try:
            features = read_features(msg)
        except InputError as exc:
            # Counted now; answered with the held q_feedback in its turn (the joint
            # controller waits for an answer to every frame).
            self.diagnostics.reject(contract.FEATURES, exc.reason,
                                    f'{exc.detail}; q_feedback held')
            features = exc
        rejection = self._lockstep.offer_frame(t_ns, features)
        if rejection is not None:
            self.diagnostics.reject(contract.FEATURES, *rejection)
            return
        self._drain()

    def _on_status(self, msg):
        """Keep whether the frame of this /ibvs/feature_status stamp was measured."""
        try:
            t_ns = read_stamp(msg.header.stamp, self.now_ns(), self.lead_ns)
            status = read_feature_status(msg)
        except InputError as exc:
            self.diagnostics.reject(contract.FEATURE_STATUS, exc.reason, exc.detail)
            return
        rejection = self._lockstep.offer_status(t_ns, status.measured)
        if rejection is not None:
            self.diagnostics.reject(contract.FEATURE_STATUS, *rejection)
            return
        self._drain()

    # -- processing ------------------------------------------------------------------------
    def _drain(self):
        """Answer the pending frames in order, as far as their inputs have arrived."""
        while self.feedback is not None:
            ready = self._lockstep.pop_ready()
            if ready is None:
                return
            self._answered_since_log = True
            self._answer(*ready)

    def _answer(self, t_ns, features, joints, measured=True):
        source = contract.FEATURES
        now_ns = self._lockstep.joints.newest
        if isinstance(features, InputError):
            pass  # counted when it came; the held q_feedback answers it
        elif isinstance(joints, Rejection):
            self.diagnostics.reject(self._joints_topic, joints.reason,
                                    f'frame {t_ns} ns: {joints.detail}; q_feedback held')
        elif now_ns - t_ns > self.stale_timeout_ns:
            self.diagnostics.reject(source, 'stale features',
                                    f'frame {t_ns} ns is {(now_ns - t_ns) * 1e-9:.3f} s old '
                                    f'(> {self.stale_timeout_ns * 1e-9:g} s): integrator frozen, '
                                    'q_feedback held')
        else:
            try:
                with self.diagnostics.timing.section('feedback_update'):
                    update = self.feedback.update(features, joints[0], joints[1],
                                                  measured=measured, t=ns_to_seconds(t_ns))
            except ModelError as exc:
                self.diagnostics.reject(source, type(exc).__name__,
                                        f'{exc}; q_feedback held')
            else:
                self._fresh(t_ns, update)
        self.diagnostics.timing.reached(t_ns)
        self.frames += 1
        self._pub.publish(joint_state(t_ns, position=self.feedback.q_feedback))
        self.diagnostics.update(frames=self.frames, q_feedback=self.feedback.q_feedback)

    def _fresh(self, t_ns, update):
        self.last_fresh_ns = t_ns
        if self.frozen:
            self.frozen = False
            self.get_logger().info(f'fresh features at {t_ns * 1e-9:.6f} s: feedback resumes')
            self.diagnostics.set_level(DiagnosticStatus.OK, 'ok')
        self.diagnostics.update(
            state=self.law.holding if update.held else 'running',
            singular_values=update.singular_values, condition_number=update.condition,
            rank=update.rank, image_error_norm_px=update.error_norm,
            q_estimate=update.q_estimate, correction_clipped=update.clipped)
        counts = getattr(self.feedback, 'counts', None)  # the safety envelope's, if on
        if counts is not None:
            summary = ', '.join(f'{code.name} {n}' for code, n in sorted(counts.items()))
            self.diagnostics.update(envelope_interventions=summary or 'none')
            if set(counts) - self._envelope_seen:
                self._envelope_seen |= set(counts)
                self.get_logger().info(f'safety envelope at {t_ns * 1e-9:.3f} s: {summary}')

    def _watch_timeout(self, now_ns):
        """Mark the feedback frozen once no usable frame came for stale_timeout_s."""
        since = self.last_fresh_ns if self.last_fresh_ns is not None else self.first_joint_ns
        if self.frozen or self.feedback is None or now_ns - since <= self.stale_timeout_ns:
            return
        self.frozen = True
        message = (f'no usable features for {(now_ns - since) * 1e-9:.3f} s of sim time: '
                   'integrator frozen, q_feedback held')
        self.get_logger().warn(message)
        self.diagnostics.set_level(DiagnosticStatus.WARN, message)
        self.diagnostics.update(state='frozen (features timed out)')


def main(args: list[str] | None = None) -> None:
    """Run the adaptive feedback node (``ros2 run ibvs_control adaptive_feedback_node``)."""
    run(AdaptiveFeedbackNode, args=args, name='adaptive_feedback_node')


if __name__ == '__main__':
    main()
