"""
feature_node: stereo images -> /ibvs/features p_I, measured (eq. 2-3) or estimated (eq. 46).

For each stereo frame, the features measured by the detector (:mod:`.detector`), or the
model's estimate F(q_T) at the frame's joint state when the markers are not found, blended
across a switch (:mod:`.blend`); the pairing rules are :class:`.stereo_pairing.StereoPairer`.
Each frame the detector may spend ``detection_budget_share`` of the camera period.

Its topics and parameters: docs/nodes.md (generated from what it opens and :data:`PARAMS`).
What it rejects and counts, the budget, the overlays and the taught target: docs/nodes.md.
"""

from functools import partial
import time

import cv2
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import PolygonStamped
from ibvs_common import contract
from ibvs_common.conversions import (feature_status_msg, features_msg, FeatureStatus,
                                     ignored_joints, image_msg, InputError, ns_stamp,
                                     position_bounds, read_joints)
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.kit import (config, forget_on_back, Inputs, publisher, StereoCameraInput,
                             subscription)
from ibvs_common.node_main import run
from ibvs_common.sim_time import node_time_ns
from ibvs_common.sync import Rejection
from ibvs_common.timing import ns_to_seconds, seconds_to_ns
from ibvs_model import BehindCameraError, CameraRobotModel, IRB4600
import numpy as np
from rclpy.node import Node
from sensor_msgs.msg import Image, JointState

from . import overlay
from .blend import BumplessSwitch
from .detector import Reason, StereoDetector
from .frame_stats import FrameStats
from .imageconv import image_view, rgb_pixels
from .node_params import FeatureConfig
from .stamp_offset import StampOffsetEstimator
from .stereo_pairing import Drop, Ready, StereoPairer

#: The node's typed configuration, built by ``ibvs run`` before any node starts.
CONFIG = FeatureConfig
PARAMS = CONFIG.params()
RULES = CONFIG.RULES
#: The overlay images (:mod:`.overlay`), one per lens.
DEBUG_IMAGES = {'left': contract.DEBUG_LEFT_IMAGE, 'right': contract.DEBUG_RIGHT_IMAGE}

_SIDES = ('left', 'right')
_LENS_FRAMES = {'left': contract.LEFT_CAMERA_FRAME, 'right': contract.RIGHT_CAMERA_FRAME}
#: OpenCV threads of this process: the detector's work is small (windows around the markers,
#: one pair at a time) and OpenCV's thread pool costs more than it shares out (measured:
#: docs/speed.md). The results are the same.
OPENCV_THREADS = 1
#: The taught target's budget (ms of estimated cost): one pair, once, before the run.
TEACH_BUDGET_MS = 1000.0


class FeatureNode(Node):
    """Publish p_I for every stereo frame: measured, estimated from q_T, or blended."""

    def __init__(self, **kwargs):
        """Declare and check the parameters, then create the subscriptions and publishers."""
        super().__init__('feature_node', **kwargs)
        self.config = c = config(self, FeatureConfig)
        cv2.setNumThreads(OPENCV_THREADS)
        self._config = c.detector_config()
        self._budget_ms = c.budget_ms
        self._switch = BumplessSwitch(c.blend_time_s, c.hold_model_error)
        self._stereo = StereoPairer(stale_timeout_ns=c.timing.stale_timeout_ns,
                                    history_ns=seconds_to_ns(c.joint_history_s),
                                    sides=_SIDES)
        self._camera_period_ns = c.timing.camera_period_ns
        self._offset = StampOffsetEstimator(
            seconds_to_ns(c.stamp_offset_window_s), self._camera_period_ns,
            initial_ns=seconds_to_ns(c.stamp_offset_initial_s)) \
            if c.estimates_stamp_offset else None
        self._stereo.exposure_offset_ns = seconds_to_ns(c.stamp_offset_initial_s)
        #: Each input's resolved topic name (the ZED wrapper's under a remap), which its
        #: rejections are counted under; filled as the subscriptions are created.
        self._topics = {}
        self._camera_problem = None
        self._model = None
        self._detector = None
        self._model_error = None
        self._last_measured = None
        self._stats = FrameStats(self._budget_ms)
        self._teach = {}
        self._teach_done = False
        self._debug_always = c.publish_debug_images
        self._taught_source = c.target.taught
        self._target_pose = c.target.pose
        self._target_features = None

        self._diag = Diagnostics(self, 'stereo fiducial features')
        self._inputs = Inputs(self._diag, self.now_ns, c.timing.frame_lead_ns)
        forget_on_back(self, self._inputs, self._stereo,
                       *([self._offset] if self._offset is not None else []))
        self._diag.update(mode='waiting', frames_published=0, frames_measured=0,
                          frames_estimated=0, frames_over_budget=0,
                          detection_budget_ms=self._budget_ms, last_switch_time_s='none',
                          switches=0)
        self._show_offset()
        self._images_in = dict.fromkeys(_SIDES, 0)
        self._diag.log_progress(self._progress)
        self._pub = publisher(self, PolygonStamped, contract.FEATURES, contract.RELIABLE)
        self._target_pub = publisher(self, PolygonStamped, contract.TARGET_FEATURES,
                                     contract.LATCHED)
        self._status_pub = publisher(self, DiagnosticArray, contract.FEATURE_STATUS,
                                     contract.RELIABLE)
        self._debug_pubs = {side: publisher(self, Image, topic, contract.IMAGES)
                            for side, topic in DEBUG_IMAGES.items()}
        # Each of a lens's inputs, left then right, in this order.
        for topics, on_message, qos, kind in (
                ((contract.LEFT_IMAGE, contract.RIGHT_IMAGE), self._on_image,
                 contract.IMAGES, ''),
                ((contract.TEACH_LEFT_IMAGE, contract.TEACH_RIGHT_IMAGE), self._on_teach,
                 contract.LATCHED, ' teach')):
            for side, topic in zip(_SIDES, topics):
                self._topics[side + kind] = subscription(self, Image, topic,
                                                         partial(on_message, side),
                                                         qos).topic_name
        self.camera_input = StereoCameraInput(self, self._diag, c.values(), self._on_camera,
                                              lambda source: self._try_frames())
        joints = subscription(self, JointState, contract.JOINT_STATES, self._on_joints,
                              contract.RELIABLE)
        # The resolved name: the runner remaps it to /stereo/joint_states (one a frame).
        self._topics['joints'] = joints.topic_name

    # --- inputs ----------------------------------------------------------------------

    def now_ns(self):
        """Return the newest time the node knows: its clock and its newest input's stamp."""
        return node_time_ns(self, self._stereo.newest_ns)

    def _progress(self):
        """Return the progress line: images in, features out, model fallbacks."""
        v = self._diag.values
        if not any(self._images_in.values()):
            return None
        return (f"images in {self._images_in['left']} left, {self._images_in['right']} right;"
                f" features out {v['frames_published']}: {v['frames_measured']} measured, "
                f"{v['frames_estimated']} model-estimated (fallback); mode {v['mode']}")

    def _on_image(self, side, msg):
        self._images_in[side] += 1
        # In order: an image of a stamp seen already would replace or follow its frame's.
        got = self._inputs.read(self._topics[side], msg)
        if got is None:
            return
        t_ns = got[0]
        try:
            image, error = image_view(msg), None
        except InputError as exc:
            image, error = None, Rejection(exc.reason, exc.detail)
        rejection = self._stereo.offer_image(side, t_ns, image, error)
        if rejection is not None:
            # The frame is skipped; its other image, if it comes, is dropped silently.
            self._diag.reject(self._topics[side], *rejection)
        self._try_frames()

    def _on_teach(self, side, msg):
        if self._teach_done:
            return
        try:
            self._teach[side] = image_view(msg)
        except InputError as exc:
            self._diag.reject(self._topics[f'{side} teach'], exc.reason, exc.detail)
            return
        self._try_frames()

    def _try_teach(self):
        """Measure p_bar on the teach pair once both images and the camera model are here."""
        if self._teach_done or len(self._teach) < 2 or self._detector is None:
            return
        self._teach_done = True
        (left, right), encoding = _one_encoding(self._teach['left'], self._teach['right'])
        k = self._detector.intrinsics
        if any(image.shape[:2] != (k.height, k.width) for image in (left, right)):
            size = (f'{left.shape[1]} x {left.shape[0]}, camera_info says '
                    f'{k.width} x {k.height}')
            self._diag.reject(self._topics['left teach'], 'size disagrees with camera_info',
                              size)
            self._teach_failed(f'its images are {size}')
            return
        detection = self._detector.detect(left, right, encoding, None, TEACH_BUDGET_MS)
        if not detection.ok:
            self._teach_failed(f'{detection.reason.value}: {detection.detail}')
            return
        self._target_pub.publish(features_msg(detection.features, ns_stamp(0)))
        self._target_features = detection.features
        self._diag.update(taught_target_px=detection.features)
        self.get_logger().info(f'taught target features p_bar = '
                               f'{np.round(detection.features, 3).tolist()} px')

    def _teach_failed(self, why):
        """
        Say at once that no target features will come: ERROR, and ``contract.TEACH_FAILED``.

        The teach pair is published once, latched: no other comes, and without p_bar no
        frame is answered. ``ibvs run`` ends the run on the value (its own exit code).
        """
        message = (f'taught target: markers not measured on the teach pair ({why}); no target '
                   'features')
        self.get_logger().error(message)
        self._diag.set_level(DiagnosticStatus.ERROR, message)
        self._diag.update(**{contract.TEACH_FAILED: why})
        self._diag.publish()

    def _on_joints(self, msg):
        topic = self._topics['joints']
        # Out of order: not offered, the state of that stamp is there already.
        got = self._inputs.read(topic, msg, take=False)
        if got is None:
            return
        t_ns = got[0]
        try:
            q = read_joints(msg, bound=position_bounds())
        except InputError as exc:
            self._diag.reject(topic, exc.reason, exc.detail)
            self._stereo.offer_bad_joints(t_ns, exc.reason)
        else:
            self._diag.note_ignored(topic, ignored_joints(msg))
            self._inputs.order.take(topic, t_ns)
            self._stereo.offer_joints(t_ns, q)
        # 250 joint states a second and mostly no frame waiting for one: nothing to decide.
        if len(self._stereo):
            self._try_frames()

    # --- frames ----------------------------------------------------------------------

    def _camera_ready(self):
        """Return why the camera model is not there, or None."""
        cameras = self.camera_input
        missing = [f'{s} camera_info' for s in _SIDES if s not in cameras.infos]
        if cameras.pose is None:
            missing.append('/stereo/pose')
        if missing:
            return 'no ' + ', '.join(missing) + ' yet'
        return self._camera_problem

    def _on_camera(self, camera, source):
        """Build the camera model, the detector and p_bar (model) from a new camera."""
        if camera is None:  # the lenses disagree: counted by the camera input
            self._model = self._detector = None
            reason = getattr(self.camera_input.error, 'reason', 'bad camera')
            self._camera_problem = f'usable camera_info ({reason})'
            return
        self._model = CameraRobotModel(camera, IRB4600)
        if not self._taught_source:  # p_bar = F(q_target): the target markers projected
            points = self._target_pose[:3, :3] @ IRB4600.fiducials_E.T \
                + self._target_pose[:3, 3:4]
            try:
                self._target_features = camera.project(points.T).reshape(6)
            except BehindCameraError:
                self._target_features = None
        self._detector = StereoDetector(camera.intrinsics, self._config)
        self._model_error = self._last_measured = None
        self._camera_problem = None

    def _try_frames(self):
        """Publish every frame that is complete; drop those that can never be."""
        camera_problem = self._camera_ready()
        self._try_teach()
        for event in self._stereo.poll(camera_problem):
            if isinstance(event, Drop):
                self._diag.reject('stereo frame', event.reason, event.detail)
            elif isinstance(event, Ready):
                self._process(event.t_ns, event.images, event.joints)
                self._update_offset()
            else:
                self._diag.update(waiting_for=', '.join(event.waiting))
        self._diag.update(pending_frames=len(self._stereo))

    def _process(self, stamp_ns, images, q):
        """
        Detect, estimate and publish the features of the stereo pair ``images``.

        ``stamp_ns``: the images' stamp; ``q``: the joint state at the exposure, stamp less
        the offset applied (:mod:`.stamp_offset`), which every output is stamped with.
        """
        started = time.perf_counter()
        t_ns = stamp_ns - self._stereo.exposure_offset_ns
        if t_ns < 0:
            self._diag.reject('stereo frame', 'exposure before time 0',
                              f'stamp {stamp_ns} ns less the stamp offset '
                              f'{self._stereo.exposure_offset_ns} ns')
            return
        k = self._detector.intrinsics
        for side in _SIDES:
            h, w = images[side][0].shape[:2]
            if (w, h) != (k.width, k.height):
                self._diag.reject(self._topics[side], 'size disagrees with camera_info',
                                  f'{w} x {h}, camera_info says {k.width} x {k.height}')
                return
        (left, right), encoding = _one_encoding(images['left'], images['right'])
        try:
            estimate = self._model.features(q)
        except BehindCameraError:
            estimate = None
        wall, cpu = time.perf_counter(), time.thread_time()
        detection = self._detector.detect(left, right, encoding, self._predict(estimate),
                                          self._budget_ms)
        wall, cpu = time.perf_counter() - wall, time.thread_time() - cpu
        self._diag.timing.add('detection', wall)  # what timing.section would measure
        self._diag.timing.reached(t_ns)
        self._record_detection(detection, wall * 1e3, cpu * 1e3)
        if not detection.ok and estimate is None:
            self._diag.reject('stereo frame', 'no estimate',
                              'a marker is behind the camera at q_T and none was measured')
            return
        previous = self._switch.source
        output = self._switch.update(t_ns, detection.features, estimate)
        self._pub.publish(features_msg(output, ns_stamp(t_ns)))
        self._publish_status(t_ns, detection)
        self._publish_overlays(t_ns, {'left': left, 'right': right}, encoding, detection,
                               estimate, output)
        self._stereo.published(stamp_ns)
        if detection.ok:
            if self._offset is not None:
                self._offset.offer(stamp_ns, detection.features)
            self._last_measured = detection.features
            if estimate is not None:
                self._model_error = detection.features - estimate
        elapsed_ms = (time.perf_counter() - started) * 1e3
        self._record(detection, previous, elapsed_ms)

    def _update_offset(self):
        """Fit the stamp offset when due, move the offset applied, show both."""
        if self._offset is None:
            return
        track = self._stereo.joints
        period = track.period_ns()
        try:
            self._offset.update(lambda t: track.at(t)[0], self._model.features_batch,
                                None if period is None else self._camera_period_ns / period)
        except BehindCameraError:
            pass  # a marker behind the camera somewhere in the window: the estimate held
        self._stereo.exposure_offset_ns = self._offset.advance()
        self._show_offset()

    def _show_offset(self):
        """Put the stamp offset on /diagnostics; log each change of its state."""
        if self._offset is None:
            why = 'lockstep: the stamps are the exposures' if self.config.lockstep \
                else 'stamp_offset_window_s 0'
            self._diag.update(
                stamp_offset_applied_ms=round(self._stereo.exposure_offset_ns * 1e-6, 3),
                stamp_offset_state=f'not estimated ({why})')
            return
        o = self._offset.current()
        estimate = 'none' if o.estimate_ns is None else round(o.estimate_ns * 1e-6, 3)
        sd = 'none' if o.sd_ns is None else round(o.sd_ns * 1e-6, 3)
        if o.state != self._diag.values.get('stamp_offset_state'):
            self.get_logger().info(f'stamp offset: {o.state} (estimate {estimate} ms, sd {sd} '
                                   f'ms, applied {o.applied_ns * 1e-6:.3f} ms)')
        self._diag.update(stamp_offset_ms=estimate, stamp_offset_sd_ms=sd,
                          stamp_offset_applied_ms=round(o.applied_ns * 1e-6, 3),
                          stamp_offset_state=o.state,
                          stamp_offset_excitation_px_s=round(o.excitation_px_s, 1))

    def _predict(self, estimate):
        """
        Return where the markers are expected: F(q_T) plus the last model error, or None.

        F(q_T) follows the arm from the joint state of the frame; the model error (measured
        minus estimated, at the last measured frame) changes slowly. Without an estimate,
        the last measurement; without either, None (the whole images are searched).
        """
        if estimate is None:
            return self._last_measured
        return estimate if self._model_error is None else estimate + self._model_error

    def _record_detection(self, detection, wall_ms, cpu_ms):
        """Count a pair over budget; keep the detection's times (:class:`.FrameStats`)."""
        d = self._diag
        if detection.reason is Reason.OVER_BUDGET:
            d.values['frames_over_budget'] += 1
            d.reject('stereo frame', 'detection over budget', detection.detail)
        # The CPU time is this thread's: OpenCV runs on it (OPENCV_THREADS).
        d.update(**self._stats.detection(wall_ms, cpu_ms, detection.cost_ms))

    def _publish_overlays(self, t_ns, images, encoding, detection, estimate, output):
        """Draw and publish each lens's overlay that someone listens to (module docstring)."""
        sides = [side for side in _SIDES if self._debug_always
                 or self._debug_pubs[side].get_subscription_count() > 0]
        if not sides:
            return
        reason = '' if detection.ok else f'{detection.reason.value}: {detection.detail}'
        mode = self._switch.mode
        target = self._target_features
        for side in sides:
            image = rgb_pixels(images[side], encoding)
            found = getattr(detection, side)
            drawn = overlay.draw(image, side, ns_to_seconds(t_ns), mode, reason, output, estimate,
                                 target, found.blobs if found is not None else ())
            self._debug_pubs[side].publish(image_msg(drawn, ns_stamp(t_ns), 'rgb8',
                                                     _LENS_FRAMES[side]))

    def _publish_status(self, t_ns, detection):
        """Publish this frame's mode on /ibvs/feature_status, stamped with the image stamp."""
        switch = self._switch
        reason = (contract.FEATURE_MEASURED if detection.ok
                  else f'{detection.reason.value}: {detection.detail}')
        status = FeatureStatus(switch.mode, switch.source, reason, switch.blend_weight(t_ns),
                               detection.search)
        self._status_pub.publish(feature_status_msg(
            status, t_ns, name=f'{self.get_name()}: features',
            hardware_id=self.get_fully_qualified_name()))

    def _record(self, detection, previous, elapsed_ms):
        d = self._diag
        counts = d.values
        counts['frames_published'] += 1
        if detection.ok:
            counts['frames_measured'] += 1
            reason = 'measured'
        else:
            counts['frames_estimated'] += 1
            reason = f'{detection.reason.value}: {detection.detail}'
        estimated = self._stats.estimated(None if detection.ok else detection.reason.value)
        switch = self._switch
        d.update(mode=switch.mode, source=switch.source, detection=reason,
                 search=detection.search, switches=switch.switches,
                 **self._stats.processing(elapsed_ms), waiting_for='')
        d.update(**estimated)
        if switch.last_switch_ns is not None and switch.source != previous \
                and previous is not None:
            t_s = ns_to_seconds(switch.last_switch_ns)
            d.update(last_switch_time_s=t_s,
                     last_switch=f'{previous} -> {switch.source} at {t_s:.9f} s')
            d.publish()
        d.set_level(DiagnosticStatus.OK,
                    switch.mode + ('' if detection.ok else f' ({reason})'))


def _one_encoding(left, right):
    """
    Return ((left, right), encoding) of two (pixels, encoding): both in the same encoding.

    The usual pair is of one encoding and passes as it is; otherwise both become rgb8
    copies.
    """
    (left, encoding), (right, right_encoding) = left, right
    if right_encoding == encoding:
        return (left, right), encoding
    return (np.ascontiguousarray(rgb_pixels(left, encoding)),
            np.ascontiguousarray(rgb_pixels(right, right_encoding))), 'rgb8'


def main(args=None):
    """Run the feature node (``ros2 run ibvs_vision feature_node``)."""
    run(FeatureNode, args=args, name='feature_node')


if __name__ == '__main__':
    main()
