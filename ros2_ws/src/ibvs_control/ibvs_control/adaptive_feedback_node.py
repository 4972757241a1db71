"""
adaptive_feedback_node: the adaptive Youla feedback of section 4.2, one q_feedback a frame.

Per frame, the law ``servo_law`` picks (:mod:`.servo_laws`; the paper's is
:class:`.controllers.AdaptiveFeedback`): q~ = F^-1(p_hat), C1 = J, SVD decoupling and
q_feedback = k_d(z) C1^+ (p_bar - p_hat) (eq. 38-42), with the frame's encoder joints
(:class:`.frame_lockstep.FrameLockstep`). Every frame is answered, one it cannot use with
the held q_feedback. Each used frame's image error and the model's pose error (FK of its
encoder angles against the target) go on /diagnostics; a local minimum of the image error
(:mod:`.minimum_watch`) goes on /ibvs/feedback_status, which the joint controller relays.

Its topics and parameters: docs/nodes.md (generated from what it opens and :data:`PARAMS`).
Determinism, staleness, rejections and the servo laws: docs/nodes.md.
"""

from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PolygonStamped
from ibvs_common import contract
from ibvs_common.conversions import (ignored_joints, InputError, joint_state, position_bounds,
                                     read_feature_status, read_features, read_joints,
                                     velocity_bounds)
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.kit import (config, forget_on_back, Inputs, publisher, StereoCameraInput,
                             subscription, WaitReporter)
from ibvs_common.node_main import run
from ibvs_common.params import ParameterError
from ibvs_common.sim_time import node_time_ns
from ibvs_common.sync import Rejection
from ibvs_common.timing import feedback_action_ns, ns_to_seconds
from ibvs_model import CameraRobotModel, IRB4600, ModelError
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Int8

from .controllers import feature_error
from .frame_lockstep import FrameLockstep
from .minimum_watch import MinimumWatch
from .node_params import (AdaptiveFeedbackConfig, check_servo_law, LIVE_PARAMS, still_speeds,
                          target_from)
from .prediction import Predictor
from .servo_laws import law_class
from .servo_status import ServoStatus

#: The node's typed configuration, built by ``ibvs run`` before any node starts.
CONFIG = AdaptiveFeedbackConfig
PARAMS = CONFIG.params()
RULES = CONFIG.RULES


def _read_state(msg: JointState) -> tuple:
    """Return the positions and velocities of a /joint_states (InputError if bad)."""
    return (read_joints(msg, bound=position_bounds()),
            read_joints(msg, 'velocity', bound=velocity_bounds()))


#: Encoder joint states kept for matching frames (2 s at 1 kHz); most frames buffered.
HISTORY = 2000


class AdaptiveFeedbackNode(Node):
    """F^-1, C1, SVD and the Youla controller per frame (module docstring)."""

    def __init__(self, **kwargs: Any) -> None:
        """Declare and check the parameters and create the interfaces."""
        super().__init__('adaptive_feedback_node', **kwargs)
        self.config = c = config(self, AdaptiveFeedbackConfig)
        values = c.values()
        self.gain = check_servo_law(values)
        self.law = law_class(c.servo_law)
        self.needs_status = (self.law.needs_measured(values)
                             or (c.latency_compensation == 'internal_model'
                                 and c.model_error_transport == 'joints'))
        self.pose = target_from(values)
        self.camera_ns = c.timing.camera_period_ns
        latency_ns, step_ns = c.timing.latency_ns, c.timing.step_ns
        self._predictor = None
        self.stale_timeout_ns = c.timing.stale_timeout_ns
        self.feedback = None
        self._camera = None
        self._taught = c.target.taught
        self._p_target = None
        self.last_fresh_ns = None
        self.first_joint_ns = None
        self.frozen = False
        self._envelope_seen = set()
        self.frames = 0
        self.diagnostics = Diagnostics(self, 'adaptive feedback')
        self._inputs = Inputs(self.diagnostics, self.now_ns, c.timing.frame_lead_ns)
        self.diagnostics.update(state='waiting for camera', frames=0)
        self.diagnostics.log_progress(self._progress)
        self._pub = publisher(self, JointState, contract.Q_FEEDBACK, contract.RELIABLE)
        self._pub_status = publisher(self, Int8, contract.FEEDBACK_STATUS, contract.LATCHED)
        self._minimum = None  # the local-minimum watch, built with the law
        self._status = None  # the status published last
        self.camera_input = StereoCameraInput(self, self.diagnostics, values, self._on_camera)
        # The resolved name: the runner remaps it to /stereo/joint_states (one a frame).
        joints = subscription(self, JointState, contract.JOINT_STATES, self._on_joint_state,
                              contract.RELIABLE)
        self._joints_topic = joints.topic_name
        self._lockstep = FrameLockstep(HISTORY, self.needs_status,
                                       joints_name=joints.topic_name,
                                       status_name=contract.FEATURE_STATUS,
                                       full_note='waiting for the camera model',
                                       action_ns=(lambda t: feedback_action_ns(
                                           t, latency_ns, step_ns))
                                       if c.latency_compensation == 'encoders' else None)
        subscription(self, PolygonStamped, contract.FEATURES, self._on_features,
                     contract.RELIABLE)
        # A restarted simulator or an NTP step: the new time line's inputs are taken (the
        # law keeps its integrator: q_feedback is held until fresh frames come)
        forget_on_back(self, self._inputs, self._lockstep)
        if self._taught:
            subscription(self, PolygonStamped, contract.TARGET_FEATURES, self._on_target,
                         contract.LATCHED)
        if self.needs_status:
            subscription(self, DiagnosticArray, contract.FEATURE_STATUS, self._on_status,
                         contract.RELIABLE)
        self.waiting = WaitReporter(self, self._waiting)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.get_logger().info(f"servo law '{self.law.name}'")

    def _missing(self):
        """Return what the oldest pending frame still waits for (empty: nothing pending)."""
        t_ns = self._lockstep.frames.first_ns
        if t_ns is None:
            return []
        missing = []
        if self.feedback is None:
            missing += self.camera_input.missing()
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
        shown = self.diagnostics.values
        error = shown.get('image_error_norm_px')
        error = 'no image error yet' if error is None else f'image error norm {error:.3f} px'
        return f"{self.frames} frames answered, {error} ({self.law.name}, {shown['state']})"

    def _waiting(self):
        """Return the 'waiting' line (the wait reporter's), and say it on /diagnostics."""
        missing = self._missing()
        self.diagnostics.update(waiting_for='; '.join(missing) or 'nothing')
        return 'waiting: ' + '; '.join(missing) if missing else None

    def _on_set_parameters(self, parameters):
        """
        Take the live gains of ``ros2 param set`` (:data:`.node_params.LIVE_PARAMS`).

        Each value is checked as at start (its range, then lambda_inf <= lambda_0 with the
        others' current values); a refusal names the parameter and the allowed values. The
        law's gain is rebuilt at once (the velocity laws'; the paper's law has none, and
        says so). rclpy refuses the read-only parameters before this is called.
        """
        live = {spec.name: spec for spec in LIVE_PARAMS}
        values = {name: self.get_parameter(name).value for name in live}
        for parameter in parameters:
            if parameter.name not in live:
                continue  # use_sim_time and the like: rclpy's own
            try:
                values[parameter.name] = live[parameter.name].check(parameter.value)
            except ParameterError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        try:
            gain = check_servo_law({**self.config.values(), **values})
        except ParameterError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        changed = [p.name for p in parameters if p.name in live]
        if changed:
            self.gain = gain
            law = self.feedback
            while law is not None and 'law' in vars(law):  # inside the safety envelope
                law = law.law
            uses = law is not None and hasattr(law, 'gain')
            if uses:
                law.gain = gain
            unused = '' if uses or self.feedback is None else \
                f" (servo law '{self.law.name}' has no such gain)"
            self.get_logger().info(f"{', '.join(changed)} set: {gain}{unused}")
        return SetParametersResult(successful=True)

    # -- inputs ----------------------------------------------------------------------------
    def _on_camera(self, camera, source):
        """Keep a new camera (the camera input's); build the law if the target is here."""
        self._camera = camera
        if camera is None:  # counted by the camera input; a new pair is awaited
            self.camera_input.forget_infos()
            return
        self._try_camera(source)

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
        """Build the servo law once the camera and the target are here; ``source`` came last."""
        if self._camera is None:
            return
        if self._taught and self._p_target is None:
            self.diagnostics.update(state=f'waiting for the taught {contract.TARGET_FEATURES}')
            return
        try:
            model = CameraRobotModel(self._camera, IRB4600)
            self._predictor = Predictor(self.config.latency_compensation, model, self.pose,
                                        still_speeds(self.config.values()),
                                        self.config.model_error_transport)
            self.feedback = self.law.create(
                model, self.pose,
                ns_to_seconds(self.camera_ns), gain=self.gain, p_target=self._p_target,
                **self.config.law_settings())
        except ModelError as exc:
            # e.g. the target behind the camera: nothing to servo on; counted under the
            # input that completed the model, and the camera inputs are awaited again.
            self.diagnostics.reject(source, type(exc).__name__, str(exc))
            self._camera = None
            self.camera_input.forget_infos()
            return
        self.camera_input.hold()
        self._minimum = MinimumWatch(self.pose, model.params)
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
        got = self._inputs.read(self._joints_topic, msg, _read_state, ordered=False)
        if got is None:
            return
        t_ns, (q, qd) = got
        self.diagnostics.note_ignored(self._joints_topic, ignored_joints(msg))
        rejection = self._lockstep.offer_joints(t_ns, (q, qd))
        if rejection is not None:
            self.diagnostics.reject(self._joints_topic, *rejection)
            return
        if self.first_joint_ns is None:
            self.first_joint_ns = t_ns
        self._watch_timeout(t_ns)
        self._drain()

    def _on_features(self, msg):
        got = self._inputs.read(contract.FEATURES, msg, ordered=False)
        if got is None:
            return
        t_ns = got[0]
        try:
            features = read_features(msg)
        except InputError as exc:
            # Counted now; answered with the held q_feedback in its turn (the joint
            # controller waits for an answer to every frame).
            self._inputs.reject(contract.FEATURES, exc, '; q_feedback held')
            features = exc
        rejection = self._lockstep.offer_frame(t_ns, features)
        if rejection is not None:
            self.diagnostics.reject(contract.FEATURES, *rejection)
            return
        self._drain()

    def _on_status(self, msg):
        """Keep whether the frame of this /ibvs/feature_status stamp was measured."""
        got = self._inputs.read(contract.FEATURE_STATUS, msg, read_feature_status, ordered=False)
        if got is None:
            return
        t_ns, status = got
        rejection = self._lockstep.offer_status(t_ns, status)
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
            self.waiting.progress()
            self._answer(*ready)

    def _answer(self, t_ns, features, joints, status=True):
        # status: the frame's FeatureStatus, or True where the node takes none
        measured = status is True or status.measured
        shows_arm = status is True or (status.measured and status.blend_weight == 0.0)
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
            measured_features = features
            try:
                with self.diagnostics.timing.section('prediction'):
                    q_action, qd_action = self._lockstep.action_joints()[1]
                    features, q, qd = self._predictor.inputs(
                        self.feedback.q_feedback, features, joints[0], joints[1], q_action,
                        qd_action, measured=shows_arm)
                with self.diagnostics.timing.section('feedback_update'):
                    update = self.feedback.update(features, q, qd, measured=measured,
                                                  t=ns_to_seconds(t_ns))
            except ModelError as exc:
                self.diagnostics.reject(source, type(exc).__name__,
                                        f'{exc}; q_feedback held')
            else:
                self._fresh(t_ns, update)
                self._watch_minimum(t_ns, measured_features, joints[0], measured)
        self.diagnostics.timing.reached(t_ns)
        self.frames += 1
        if self._status is None:
            self._report(ServoStatus.NO_WARNING)
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
            rank=update.rank,
            q_estimate=update.q_estimate, correction_clipped=update.clipped)
        counts = getattr(self.feedback, 'counts', None)  # the safety envelope's, if on
        if counts is not None:
            summary = ', '.join(f'{code.name} {n}' for code, n in sorted(counts.items()))
            self.diagnostics.update(envelope_interventions=summary or 'none')
            if set(counts) - self._envelope_seen:
                self._envelope_seen |= set(counts)
                self.get_logger().info(f'safety envelope at {t_ns * 1e-9:.3f} s: {summary}')

    def _watch_minimum(self, t_ns, features, q_encoder, measured):
        """Show the image and model pose errors; report a local minimum's start and end."""
        error_px = float(np.linalg.norm(feature_error(features, self.feedback.p_target)))
        verdict = self._minimum.offer(ns_to_seconds(t_ns), error_px, q_encoder,
                                      self.feedback.q_feedback, measured)
        _, position, axis = self._minimum.errors
        local = verdict.status == ServoStatus.LOCAL_MINIMUM
        self.diagnostics.update(image_error_norm_px=error_px, model_position_error_m=position,
                                model_tool_axis_error_deg=axis, local_minimum=local)
        if verdict.status == (ServoStatus.NO_WARNING if self._status is None else self._status):
            return
        if local:
            self.get_logger().warn(f'{verdict.status.name} at {t_ns * 1e-9:.3f} s: '
                                   f'{verdict.detail}')
        else:
            self.get_logger().info(f'no longer in a local minimum at {t_ns * 1e-9:.3f} s')
        self.diagnostics.alert('local_minimum', verdict.detail if local else None)
        self._report(verdict.status)

    def _report(self, status):
        """Publish ``status`` on /ibvs/feedback_status (a change, or the first)."""
        self._status = status
        self._pub_status.publish(Int8(data=int(status)))

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
