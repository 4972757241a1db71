"""
viz_node: what a viewer (RViz, Foxglove) needs that a cell does not publish.

The tool's, the target's and (once known) the camera's frames on /tf_static, and the shapes
no URDF of the cell has on /ibvs/markers: the tool, the ZED 2's body, each lens's field of
view, the target, the tool's path, the markers estimated by the model and those measured.
The arm's frames are robot_state_publisher's (ibvs_sim.robot_state_node in simulation).

/ibvs/markers at most ``marker_rate_hz`` of sim time. Its topics and parameters:
docs/nodes.md (generated from what it opens and :data:`PARAMS`).
The frames it adds for the images, and what it rejects: docs/nodes.md.
"""

from collections import deque, OrderedDict

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point, PolygonStamped
from ibvs_common import contract
from ibvs_common.conversions import (check_features_in_image, ignored_joints, InputError,
                                     matrix_poses, position_bounds, read_feature_status,
                                     read_features, read_joints, transforms_msg)
from ibvs_common.diagnostics import Diagnostics
from ibvs_common.kit import (config, forget_on_back, Inputs, publisher, StereoCameraInput,
                             subscription, WaitReporter)
from ibvs_common.node_main import run
from ibvs_common.sim_time import node_time_ns
from ibvs_common.timing import period_ns
from ibvs_model import abb_urdf, IRB4600
from ibvs_model.abb_urdf import rpy_matrix
from ibvs_model.robot import fiducial_points, forward_kinematics
from ibvs_model.scene import MARKER_RADIUS_M, MARKER_RGB
import numpy as np
from rclpy.node import Node
from rclpy.time import Time
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from . import scene
from .node_params import VizConfig

#: The node's typed configuration, built by ``ibvs run`` before any node starts.
CONFIG = VizConfig
PARAMS = CONFIG.params()
RULES = CONFIG.RULES
#: Marker namespaces, one per thing drawn.
NS_FRUSTUM, NS_TARGET, NS_PATH = 'field_of_view', 'target', 'tool_path'
NS_MEASURED, NS_ESTIMATED = 'markers_measured', 'markers_estimated'
NS_TOOL, NS_CAMERA = 'tool', 'camera_body'
#: Feature frames kept while their /ibvs/feature_status is awaited.
_PENDING_FEATURES = 8


def _rgba(rgb, alpha=1.0):
    return ColorRGBA(r=rgb[0], g=rgb[1], b=rgb[2], a=alpha)


MARKER_COLOURS = [_rgba([c / 255.0 for c in rgb]) for rgb in MARKER_RGB]


def _points(array):
    return [Point(x=float(p[0]), y=float(p[1]), z=float(p[2])) for p in array]


class VizNode(Node):
    """Publish what a viewer needs that a cell does not publish (module docstring)."""

    def __init__(self, **kwargs):
        """Declare and check the parameters, then create the publishers and subscriptions."""
        super().__init__('viz_node', **kwargs)
        self.config = c = config(self, VizConfig)
        self._params = c.plant.robot
        self._d_q = c.plant.d_q
        self._target = c.target.pose
        self._marker_period_ns = period_ns(c.marker_rate_hz)
        self._camera = None
        self._path = deque(maxlen=self.config.tool_path_points)  # Points, oldest first
        self._last_markers_ns = None
        self._last_joint_ns = None
        self._features = OrderedDict()
        #: The markers triangulated from the newest measured /ibvs/features (2, 3), or None
        #: when the newest frame was not measured.
        self.measured = None
        self._estimated = None

        self._diag = Diagnostics(self, 'tool, camera and target frames, markers')
        self._inputs = Inputs(self._diag, self.now_ns, c.timing.frame_lead_ns)
        forget_on_back(self, self._inputs, self)
        self._diag.update(waiting_for='camera_info, /stereo/pose', joint_states_taken=0,
                          markers_published=0)
        self._diag.log_progress(lambda: None if not self._diag.values['joint_states_taken']
                                else (f"{self._diag.values['joint_states_taken']} joint states "
                                      f'(last at {self._last_joint_ns * 1e-9:.3f} s), '
                                      f"{self._diag.values['markers_published']} /ibvs/markers"))
        self._static_pub = publisher(self, TFMessage, contract.TF_STATIC, contract.LATCHED)
        self._markers_pub = publisher(self, MarkerArray, contract.MARKERS, 10)
        self.camera_input = StereoCameraInput(self, self._diag, c.values(), self._on_camera)
        self._joints_topic = subscription(self, JointState, contract.JOINT_STATES,
                                          self._on_joints, contract.RELIABLE).topic_name
        subscription(self, PolygonStamped, contract.FEATURES, self._on_features,
                     contract.RELIABLE)
        subscription(self, DiagnosticArray, contract.FEATURE_STATUS, self._on_status,
                     contract.RELIABLE)
        self._publish_static()
        self.waiting = WaitReporter(self, self._waiting)

    # --- camera and static frames ----------------------------------------------------------

    def _on_camera(self, camera, source):
        """Publish the frames a new camera fixes (a camera that failed: counted already)."""
        if camera is None:
            return
        self._camera = camera
        self._publish_static()
        self._diag.update(waiting_for='')
        self.get_logger().info('camera known: its frames published on /tf_static')

    def _publish_static(self):
        """Publish every fixed frame of this node in one /tf_static message (module doc)."""
        static = [(contract.BASE_FRAME, scene.TARGET_FRAME, self._target)]
        if self.config.tool_frames_tf:
            static += scene.tool_transforms(self._params)
        stamp = Time().to_msg()
        if self._camera is not None:
            static += scene.camera_transforms(self._camera.pose_C_O,
                                              self._camera.intrinsics.baseline)
            if self.config.image_frames_tf:
                static += self._image_frames(static)
            stamp = self.camera_input.pose.header.stamp
        self._static_pub.publish(transforms_msg(static, stamp))

    def _image_frames(self, static):
        """Return (our lens frame, the image's frame, identity) where the images name others."""
        ours = {frame for parent, child, _ in static for frame in (parent, child)}
        ours.update(abb_urdf.link_poses(np.zeros(6)))  # the arm's, a cell's URDF's
        ours.update(scene.TOOL_FRAMES)
        out = []
        for side, lens in zip(('left', 'right'), scene.LENS_FRAMES):
            frame = self.camera_input.infos[side].header.frame_id
            if not frame or frame == lens:
                continue
            if frame in ours or frame in (f for _, f, _ in out) or frame.startswith('/'):
                self._diag.reject(self.camera_input.topics[side], 'frame_id not publishable',
                                  f"'{frame}' is a frame of the cell's tree, the other "
                                  "lens's, or not a tf2 name: not placed at the lens")
                continue
            out.append((lens, frame, np.eye(4)))
        return out

    def _waiting(self):
        """Return the wait reporter's line while the camera is not known."""
        if self._camera is None:
            return f'waiting for {", ".join(self.camera_input.missing())} to describe the camera'
        return None

    def forget(self) -> None:
        """
        Forget the stamps of the old time line (the clock jumped back: :func:`forget_on_back`).

        The features waiting for their status, and the time of the last markers, which
        would hold every marker back until sim time passed it again.
        """
        self._features.clear()
        self._last_markers_ns = None

    # --- features ---------------------------------------------------------------------------

    def now_ns(self):
        """Return the newest time the node knows: its clock and its last joint state."""
        return node_time_ns(self, self._last_joint_ns)

    def _on_features(self, msg):
        # In order: a second message of one stamp would replace the first.
        got = self._inputs.read(contract.FEATURES, msg, read_features)
        if got is None:
            return
        t_ns, features = got
        self._features[t_ns] = features
        while len(self._features) > _PENDING_FEATURES:
            self._features.popitem(last=False)

    def _on_status(self, msg):
        got = self._inputs.read(contract.FEATURE_STATUS, msg, read_feature_status)
        if got is None:
            return
        t_ns, mode = got[0], got[1].mode
        features = self._features.pop(t_ns, None)
        if features is None or self._camera is None:
            return
        self.measured = None
        if mode == contract.FEATURE_MEASURED:
            try:
                check_features_in_image(features, self._camera.intrinsics)
                self.measured = self._camera.triangulate(features.reshape(2, 3))
            except InputError as exc:
                self._diag.reject(contract.FEATURES, exc.reason, exc.detail)
            except ValueError as exc:
                self._diag.reject(contract.FEATURES, 'cannot triangulate', str(exc))

    # --- joint states -----------------------------------------------------------------------

    def _on_joints(self, msg):
        topic = self._joints_topic  # in order: a duplicate would draw the same /tf again
        got = self._inputs.read(topic, msg, lambda m: read_joints(m, bound=position_bounds()))
        if got is None:
            return
        t_ns, q = got
        self._diag.note_ignored(topic, ignored_joints(msg))
        self._last_joint_ns = t_ns
        self._diag.values['joint_states_taken'] += 1
        # ABB's tool0 is the flange {E} of eq. (7): the true arm's, where the camera sees it.
        tool = forward_kinematics(q + self._d_q, self._params)
        # One Point a joint state (250 Hz on a cell), not a copy of the whole path
        self._path.append(Point(x=float(tool[0, 3]), y=float(tool[1, 3]), z=float(tool[2, 3])))
        self._estimated = fiducial_points(q, IRB4600)
        if self._camera is not None and (self._last_markers_ns is None or
                                         t_ns - self._last_markers_ns >= self._marker_period_ns):
            self._last_markers_ns = t_ns
            self._markers_pub.publish(self.markers(msg.header.stamp))
            self._diag.values['markers_published'] += 1

    # --- markers ----------------------------------------------------------------------------

    def _marker(self, ns, marker_id, kind, stamp, frame=contract.BASE_FRAME):
        m = Marker()
        m.header.stamp = stamp
        m.header.frame_id = frame
        m.ns, m.id, m.type, m.action = ns, marker_id, kind, Marker.ADD
        m.pose.orientation.w = 1.0
        return m

    def markers(self, stamp):
        """Return the MarkerArray of the current state (module docstring lists it)."""
        out = MarkerArray()
        kinds = {'cylinder': Marker.CYLINDER, 'sphere': Marker.SPHERE}
        for i, (frame, solid) in enumerate(scene.tool_solids(self._params)):
            m = self._marker(NS_TOOL, i, kinds[solid.kind], stamp, frame)
            m.pose = matrix_poses([scene.translation(solid.xyz) @ rpy_matrix(solid.rpy)])[0]
            if solid.kind == 'cylinder':
                m.scale.x = m.scale.y = 2.0 * solid.size[0]
                m.scale.z = solid.size[1]
                m.color = _rgba((0.35, 0.35, 0.35))
            else:
                m.scale.x = m.scale.y = m.scale.z = 2.0 * solid.size[0]
                m.color = MARKER_COLOURS[int(frame[-1]) - 1]
            out.markers.append(m)
        body = self._marker(NS_CAMERA, 0, Marker.CUBE, stamp, contract.CAMERA_FRAME)
        body.scale.x, body.scale.y, body.scale.z = scene.ZED2_BODY_SIZE_M
        body.color = _rgba((0.1, 0.1, 0.1))
        out.markers.append(body)
        lines = scene.frustum_lines(self._camera.intrinsics, self.config.frustum_depth_m)
        for i, frame in enumerate(scene.LENS_FRAMES):
            m = self._marker(NS_FRUSTUM, i, Marker.LINE_LIST, stamp, frame)
            m.scale.x = 0.005
            m.color = _rgba((0.2, 0.6, 1.0) if i == 0 else (1.0, 0.6, 0.2), 0.8)
            m.points = _points(lines)
            out.markers.append(m)
        arrow = self._marker(NS_TARGET, 0, Marker.ARROW, stamp)
        axis = self._target[:3, 2]
        tip = self._target[:3, 3]
        arrow.points = _points([tip - 0.15 * axis, tip])
        arrow.scale.x, arrow.scale.y, arrow.scale.z = 0.01, 0.02, 0.03
        arrow.color = _rgba((0.1, 0.8, 0.1), 0.9)
        out.markers.append(arrow)
        goal = self._marker(NS_TARGET, 1, Marker.SPHERE_LIST, stamp)
        goal.points = _points(self._params.fiducials_E @ self._target[:3, :3].T + tip)
        goal.scale.x = goal.scale.y = goal.scale.z = 2.0 * MARKER_RADIUS_M
        goal.colors = [_rgba((0.1, 0.8, 0.1), 0.5)] * 2
        out.markers.append(goal)
        path = self._marker(NS_PATH, 0, Marker.LINE_STRIP, stamp)
        path.points = list(self._path)
        path.scale.x = 0.003
        path.color = _rgba((0.9, 0.9, 0.2), 1.0)
        out.markers.append(path)
        for ns, points, scale, alpha in ((NS_ESTIMATED, self._estimated, 2.6, 0.35),
                                         (NS_MEASURED, self.measured, 2.0, 1.0)):
            m = self._marker(ns, 0, Marker.SPHERE_LIST, stamp)
            if points is None:
                m.action = Marker.DELETE
            else:
                m.points = _points(points)
                m.scale.x = m.scale.y = m.scale.z = scale * MARKER_RADIUS_M
                m.colors = [ColorRGBA(r=c.r, g=c.g, b=c.b, a=alpha) for c in MARKER_COLOURS]
            out.markers.append(m)
        return out


def main(args=None):
    """Run the viz node (``ros2 run ibvs_viz viz_node``)."""
    run(VizNode, args=args, name='viz_node')


if __name__ == '__main__':
    main()
