"""
The classes of bad input, as message builders for each message type of the graph.

Each builder returns a list of ``(name, make)``: ``make()`` returns the case's messages
when the case runs (stamps are those the rig expects next, so that only the fault is
wrong). Classes: NaN / inf, 1e308, wrong lengths, wrong / missing / repeated names,
negative stamps, ``nanosec`` >= 1e9, far-future stamps, a stamp a little ahead
(:data:`AHEAD_NS`: refused, and the next frame taken), bursts; for images wrong step, size
or encoding, and valid full-size images costly to search (noise, checkerboards, many
circles: :func:`contents`); for CameraInfo an impossible size or projection and absurd but
finite camera models (focal length, principal point, baseline); for poses a non-finite or
non-unit quaternion, a camera looking away; for trajectory commands what
joint_trajectory_controller refuses (:func:`command_trajectories`); for the feedforward
trajectory a valid one of :data:`HUGE_POINTS` points and one bad in its last
(:func:`huge_trajectories`). And two classes that are no message: a second publisher on a
topic the node reads or commands on (:func:`second_publishers`), which the node must name
on /diagnostics and clear when it went; and a /clock set back, as a restarted simulator
sets it, inputs then stamped from the earlier time on (:func:`clock_jumps`), which the node
must see and take.
"""

import copy
import math

from builtin_interfaces.msg import Duration
import cv2
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import Point32, PolygonStamped
from ibvs_common import contract
from ibvs_common.conversions import (feature_status_msg, FeatureStatus, image_msg, joint_state,
                                     joint_trajectory, ns_stamp, stamp_ns)
from ibvs_common.sim_time import clock_watch
import numpy as np
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo
from std_msgs.msg import Float64MultiArray, Header, Int8

from .harness import Case, stamp

NAMES = list(contract.JOINT_NAMES)
#: A stamp 2^31 - 1 s on: as far in the future as a builtin_interfaces/Time goes.
FAR_SEC = 2 ** 31 - 1
#: Messages in a burst.
BURST = 50
#: How far a stamp leads the next one in the 'stamp 0.4 s ahead' class: a node that took
#: such an image would refuse the eleven frames after it as stamped before it.
AHEAD_NS = 400_000_000
#: Points of the 'huge trajectory' class: a 6 s feedforward at 1 kHz.
HUGE_POINTS = 6000
#: The node of the second publisher (:func:`second_publishers`).
ROGUE = 'fuzz_rogue'
#: The topics whose second publisher would otherwise go unnoticed: every rig that reads
#: one, or commands on one, gets the class on it.
SECOND_PUBLISHER_TOPICS = (contract.JOINT_STATES, contract.FRAME_JOINT_STATES,
                           contract.Q_FEEDBACK, contract.FEATURES, contract.EFFORT_COMMANDS,
                           contract.POSITION_COMMANDS, contract.TRAJECTORY_COMMANDS)


def bad_stamps(t_ns):
    """Return (name, stamp) of the malformed and far-future stamps, ``t_ns`` the next one."""
    sec, nsec = divmod(t_ns, 1_000_000_000)
    return [('negative stamp', stamp(-5, nsec)),
            ('nanosec >= 1e9', stamp(sec, 4_000_000_000)),
            ('far-future stamp', stamp(FAR_SEC, 0)),
            ('future stamp, 1000 s ahead', stamp(sec + 1000, nsec))]


def joint_states(topic, next_ns, position, fields=('position',), scale=1.0, last_ns=None):
    """
    Bad JointStates on ``topic``; ``position`` (6,) a valid value; ``fields`` read.

    With ``last_ns`` (the stamp of the last state the node acted on), also that stamp
    again and one a millisecond before it: a duplicate and a stamp going back.
    """
    def msg(t_ns, names=NAMES, **values):
        full = {'position': position, 'velocity': np.zeros(6), 'effort': np.zeros(6)}
        full.update(values)
        return joint_state(t_ns, full['position'], full['velocity'], full['effort'], names)

    cases = []
    for field in fields:
        good = {'position': position, 'velocity': np.zeros(6), 'effort': np.zeros(6)}[field]
        for label, value in (('NaN', np.nan), ('inf', np.inf), ('1e308', 1e308),
                             ('-1e308', -1e308)):
            bad = np.array(good, dtype=float)
            bad[2] = value
            cases.append((f'{label} {field}', lambda f=field, b=bad: [msg(next_ns(), **{f: b})]))
        cases.append((f'wrong {field} length',
                      lambda f=field, g=good: [msg(next_ns(), **{f: np.r_[g, 0.0]})]))
        absurd = np.full(6, 1e6 * scale)
        cases.append((f'absurd finite {field} ({scale:g} x 1e6)',
                      lambda f=field, a=absurd: [msg(next_ns(), **{f: a})]))
    for other in ('position', 'velocity', 'effort'):
        if other not in fields:  # a field it does not read: a NaN is refused all the same
            bad = np.zeros(6)
            bad[4] = np.nan
            cases.append((f'NaN {other} (not read)',
                          lambda o=other, b=bad: [msg(next_ns(), **{o: b})]))
    nan = {fields[0]: np.full(6, np.nan)}
    cases += [
        ('no names', lambda: [msg(next_ns(), names=[])]),
        ('repeated names', lambda: [msg(next_ns(), names=[NAMES[0]] * 6)]),
        ('unknown name', lambda: [msg(next_ns(), names=NAMES[:5] + ['joint_7'])]),
        ('missing name', lambda: [joint_state(next_ns(), position[:5], np.zeros(5),
                                              np.zeros(5), NAMES[:5])]),
        (f'burst of {BURST} NaN', lambda: [msg(next_ns(), **nan) for _ in range(BURST)]),
        ('NaN with a far-future stamp', lambda: [_stamped(msg(0, **nan), stamp(FAR_SEC))]),
    ]
    for label in ('negative stamp', 'nanosec >= 1e9', 'far-future stamp',
                  'future stamp, 1000 s ahead'):
        cases.append((label, lambda lb=label: [
            _stamped(msg(0), dict(bad_stamps(next_ns()))[lb])]))
    cases.append((f'paced stream of {BURST} future stamps', lambda: [
        msg(next_ns() + (1000 + k) * 1_000_000_000) for k in range(BURST)]))
    cases.append(('stamp 0.4 s ahead', lambda: [msg(next_ns() + AHEAD_NS)]))
    if last_ns is not None:
        cases += [('duplicate of the last stamp', lambda: [msg(last_ns())]),
                  ('stamp going back 1 ms', lambda: [msg(last_ns() - 1_000_000)])]
    return [(name, topic, make) for name, make in cases]


def _stamped(msg, t):
    msg.header.stamp = t
    return msg


def headers(topic, next_ns, off_grid=True):
    """Bad std_msgs/Header (frame_lost): stamps only."""
    cases = [(name, lambda s=s: [Header(stamp=s, frame_id=contract.CAMERA_FRAME)])
             for name, s in bad_stamps(0)]
    if off_grid:
        cases.append(('off the frame grid', lambda: [Header(stamp=ns_stamp(next_ns() + 1))]))
    cases.append(('stamp 0.4 s ahead', lambda: [Header(stamp=ns_stamp(next_ns() + AHEAD_NS),
                                                       frame_id=contract.CAMERA_FRAME)]))
    cases.append((f'burst of {BURST} far-future', lambda: [
        Header(stamp=stamp(FAR_SEC - k)) for k in range(BURST)]))
    return [(name, topic, make) for name, make in cases]


def zero_camera_info(good):
    """Return an all-zero CameraInfo stamped as ``good``: no camera's frame."""
    msg = CameraInfo()
    msg.header = copy.deepcopy(good.header)
    return msg


def camera_info_stamps(topic, good):
    """Bad CameraInfo stamps, for a reader that takes only a frame's time from it."""
    return [(name, topic, lambda s=s: [_stamped(copy.deepcopy(good), s)])
            for name, s in bad_stamps(0)] + [
        ('all-zero CameraInfo, fresh stamp', topic, lambda: [zero_camera_info(good)])]


def clocks(topic=contract.CLOCK):
    """Bad /clock: negative time and nanosec >= 1e9."""
    return [('negative /clock', topic, lambda: [Clock(clock=stamp(-1, 0))]),
            ('/clock nanosec >= 1e9', topic, lambda: [Clock(clock=stamp(1, 2_000_000_000))])]


def trajectories(topic, next_ns, rows):
    """Bad JointTrajectory: values, names, sample times, stamps."""
    def traj(t_ns=0, values=rows, names=NAMES):
        return joint_trajectory(t_ns, 1_000_000, values, names)

    def nan():
        values = np.array(rows, dtype=float)
        values[1, 3] = np.nan
        return [traj(values=values)]

    def huge():
        values = np.array(rows, dtype=float)
        values[:, 0] = 1e308
        return [traj(values=values)]

    def times():
        msg = traj()
        msg.points[1].time_from_start.nanosec = 7
        return [msg]

    def ragged():
        msg = traj()
        msg.points[1].positions = [0.0] * 5
        return [msg]

    def empty():
        msg = traj()
        msg.points = []
        return [msg]

    cases = [('NaN position', nan), ('1e308 positions', huge), ('wrong sample times', times),
             ('ragged points', ragged), ('empty', empty),
             ('wrong names', lambda: [traj(names=NAMES[:5] + ['joint_7'])])]
    for name, s in bad_stamps(0):
        cases.append((name, lambda s=s: [_stamped(traj(), s)]))
    return [(name, topic, make) for name, make in cases]


def polygons(topic, next_ns, features, last_ns=None):
    """Bad features (PolygonStamped): values, point count, stamps (``last_ns``: joint_states)."""
    def msg(t_ns, values=features, points=2):
        out = PolygonStamped()
        out.header.stamp = ns_stamp(t_ns)
        p = np.asarray(values, dtype=float).reshape(2, 3)
        out.polygon.points = [Point32(x=float(r[0]), y=float(r[1]), z=float(r[2]))
                              for r in p][:points]
        if points > 2:
            out.polygon.points = out.polygon.points + [Point32()] * (points - 2)
        return out

    cases = [('NaN features', lambda: [msg(next_ns(), np.r_[np.nan, features[1:]])]),
             ('inf features', lambda: [msg(next_ns(), np.r_[np.inf, features[1:]])]),
             ('one point', lambda: [msg(next_ns(), points=1)]),
             ('three points', lambda: [msg(next_ns(), points=3)])]
    for name, s in bad_stamps(0):
        cases.append((name, lambda s=s: [_stamped(msg(0), s)]))
    cases.append((f'burst of {BURST} far-future', lambda: [
        _stamped(msg(0), stamp(FAR_SEC - k)) for k in range(BURST)]))
    cases.append(('stamp 0.4 s ahead', lambda: [msg(next_ns() + AHEAD_NS)]))
    if last_ns is not None:
        cases += [('duplicate of the last stamp', lambda: [msg(last_ns())]),
                  ('stamp going back 1 ms', lambda: [msg(last_ns() - 1_000_000)])]
    return [(name, topic, make) for name, make in cases]


def status(t_ns, mode):
    """Return a /ibvs/feature_status of the frame stamped ``t_ns`` in ``mode``."""
    return feature_status_msg(FeatureStatus(mode, mode, mode, 0.0, 'full'), t_ns,
                              name='features')


def statuses(topic, next_ns, last_ns=None):
    """Bad /ibvs/feature_status: stamps (of a measured frame), no status, an unknown mode."""
    cases = [('no status', topic, lambda: [DiagnosticArray(header=Header(
        stamp=ns_stamp(next_ns())))]),
             ('unknown mode', topic, lambda: [status(next_ns(), 'guessed')])]
    for name, s in bad_stamps(0):
        cases.append((name, topic, lambda s=s: [_stamped(status(0, 'measured'), s)]))
    cases.append(('stamp 0.4 s ahead', topic,
                  lambda: [status(next_ns() + AHEAD_NS, 'measured')]))
    if last_ns is not None:
        cases += [('duplicate of the last stamp', topic,
                   lambda: [status(last_ns(), 'measured')]),
                  ('stamp going back 1 ms', topic,
                   lambda: [status(last_ns() - 1_000_000, 'measured')])]
    return cases


def feedback_statuses(topic=contract.FEEDBACK_STATUS):
    """Bad /ibvs/feedback_status: codes the feedback node never reports (a hold's, unknown)."""
    return [(f'feedback status {code}', topic, lambda code=code: [Int8(data=code)])
            for code in (12, 99, -128)]


def arrays(topic, good, beyond):
    """
    Bad Float64MultiArray position commands: values, lengths, a joint beyond its travel.

    ``good`` (6,) is a valid command, ``beyond`` (6,) one with a joint past its range.
    """
    def msg(values):
        return Float64MultiArray(data=[float(v) for v in values])

    cases = []
    for label, value in (('NaN', np.nan), ('inf', np.inf), ('1e308', 1e308),
                         ('-1e308', -1e308)):
        bad = np.array(good, dtype=float)
        bad[2] = value
        cases.append((f'{label} value', lambda b=bad: [msg(b)]))
    cases += [('5 values', lambda: [msg(good[:5])]),
              ('7 values', lambda: [msg(np.r_[good, 0.0])]),
              ('no values', lambda: [msg([])]),
              ('a joint beyond its travel', lambda: [msg(beyond)]),
              (f'burst of {BURST} NaN', lambda: [msg(np.full(6, np.nan))] * BURST)]
    return [(name, topic, make) for name, make in cases]


def command_trajectories(topic, good, beyond, past_ns):
    """
    Bad JointTrajectory position commands beyond :func:`trajectories`.

    Names, travel, and what joint_trajectory_controller refuses
    (:func:`ibvs_common.conversions.read_command_trajectory`): a point out of range before
    a good last one, a stamp whose end lies beyond the command timeout in the past
    (``past_ns()`` returns such a stamp), negative or non-increasing times, NaN velocities,
    an inf acceleration, effort fields.
    """
    def traj(values=good, names=NAMES):
        return joint_trajectory(0, 1_000_000, np.atleast_2d(values), names)

    def with_point(change, rows=3):
        def make():
            msg = traj(np.tile(good, (rows, 1)))
            change(msg)
            return [msg]
        return make

    def times(*ns):
        def change(msg):
            for point, t in zip(msg.points, ns):
                point.time_from_start = Duration(sec=t // 10 ** 9, nanosec=t % 10 ** 9)
        return change

    def field(k, name, values):
        def change(msg):
            setattr(msg.points[k], name, values)
        return change

    def past():
        msg = traj(np.tile(good, (2, 1)))
        msg.header.stamp = ns_stamp(past_ns())
        return [msg]

    def long_last():
        msg = traj(np.tile(good, (3, 1)))
        msg.points[-1].positions = list(good) + [0.0]
        return [msg]

    nan_last = np.tile(good, (3, 1))
    nan_last[-1, 4] = np.nan
    cases = [('repeated names', lambda: [traj(names=[NAMES[0]] * 6)]),
             ('missing name', lambda: [traj(good[:5], NAMES[:5])]),
             ('NaN in the last point', lambda: [traj(nan_last)]),
             ('a joint beyond its travel', lambda: [traj(beyond)]),
             ('last point 7 positions', long_last),
             ('first point beyond the travel, the last good',
              lambda: [traj(np.vstack([beyond, good]))]),
             ('stamp in the past beyond the command timeout', past),
             ('negative time_from_start', with_point(times(-10 ** 9), rows=1)),
             ('times not increasing', with_point(times(0, 2_000_000, 1_000_000))),
             ('times repeated', with_point(times(0, 1_000_000, 1_000_000))),
             ('NaN velocities', with_point(field(2, 'velocities', [math.nan] * 6))),
             ('inf acceleration', with_point(field(0, 'accelerations', [0.0] * 5 + [math.inf]))),
             ('velocities of 5 joints', with_point(field(1, 'velocities', [0.0] * 5))),
             ('effort fields', with_point(field(2, 'effort', [0.0] * 6)))]
    return [(name, topic, make) for name, make in cases]


def camera_infos(topic, good):
    """
    Bad CameraInfo: impossible sizes and projections, absurd but finite camera models.

    The absurd models (f_u = 1e308 with the right P[3] = -1e308, which makes b = 1 m and
    features of inf; P[3] = -1e300 alone) and the others of
    :func:`ibvs_common.conversions.check_camera_info` and ``intrinsics_from_infos``: a
    field of view of 179 deg, a principal point off the image, a lens of another size than
    its pair, and for the right lens baselines of 1 mm and 10 m and a positive P[3], for the
    left one a P[3] (the right's CameraInfo on the left topic); an all-zero CameraInfo, a
    P with a skew or another third row than a rectified pinhole's, and a right lens whose
    c_u is far from its pair's.
    """
    def info(**changes):
        msg = CameraInfo()
        msg.header, msg.width, msg.height = good.header, good.width, good.height
        msg.k, msg.p, msg.d, msg.r = good.k, good.p, good.d, good.r
        msg.distortion_model = good.distortion_model
        for key, value in changes.items():
            setattr(msg, key, value)
        return msg

    p_nan = list(good.p)
    p_nan[0] = float('nan')
    p_neg = list(good.p)
    p_neg[0] = -p_neg[0]

    def p_with(**changes):
        p = list(good.p)
        for index, value in changes.items():
            p[int(index[1:])] = float(value)
        return p

    right = 'right' in topic
    f = good.p[0]
    wide = (good.width / 2.0) / math.tan(math.radians(179.0) / 2.0)
    huge = p_with(p0=1e308, p5=1e308, **({'p3': -1e308} if right else {}))
    cases = [('100000 x 100000', lambda: [info(width=100000, height=100000)]),
             ('0 x 0', lambda: [info(width=0, height=0)]),
             ('NaN in P', lambda: [info(p=p_nan)]),
             ('negative focal length', lambda: [info(p=p_neg)]),
             ('focal length 1e308' + (', P[3] -1e308' if right else ''),
              lambda: [info(p=huge)]),
             ('P[3] -1e300', lambda: [info(p=p_with(p3=-1e300))]),
             ('focal length 1e-300', lambda: [info(p=p_with(p0=1e-300))]),
             ('field of view 179 deg', lambda: [info(p=p_with(p0=wide))]),
             ('principal point 1e6 px', lambda: [info(p=p_with(p2=1e6))]),
             ('principal point -50 px', lambda: [info(p=p_with(p6=-50.0))]),
             ('another size than its pair', lambda: [info(width=good.width + 2)]),
             ('all-zero CameraInfo, fresh stamp', lambda: [zero_camera_info(good)]),
             ('skew in P', lambda: [info(p=p_with(p1=5.0))]),
             ('third row of P not 0 0 1 0', lambda: [info(p=p_with(p8=0.1, p10=2.0))])]
    if right:
        cases += [('c_u 20 % of the width off its pair',
                   lambda: [info(p=p_with(p2=good.p[2] - 0.2 * good.width))])]
    if right:
        cases += [('baseline 1 mm', lambda: [info(p=p_with(p3=-f * 0.001))]),
                  ('baseline 10 m', lambda: [info(p=p_with(p3=-f * 10.0))]),
                  ('positive P[3]', lambda: [info(p=p_with(p3=f * 0.12))])]
    else:
        cases += [('left lens with a baseline', lambda: [info(p=p_with(p3=-f * 0.12))])]
    return [(name, topic, make) for name, make in cases]


def poses(topic, good_tf):
    """Bad /stereo/pose: non-finite, non-unit quaternion, a camera looking away."""
    from ibvs_common.conversions import pose_stamped

    def msg(changes):
        out = pose_stamped(good_tf, 0)
        for (part, key), value in changes.items():
            setattr(getattr(out.pose, part), key, value)
        return out

    away = np.array(good_tf, dtype=float)
    away[:3, 1:3] *= -1.0  # turned half a turn about its x axis: z points away
    cases = [('NaN position', lambda: [msg({('position', 'x'): float('nan')})]),
             ('quaternion not normalised', lambda: [msg({('orientation', 'w'): 5.0})]),
             ('1e308 position', lambda: [msg({('position', 'z'): 1e308})]),
             ('camera looking away', lambda: [pose_stamped(away, 0)])]
    return [(name, topic, make) for name, make in cases]


def images(topic, frame, image):
    """
    Bad images, each sent as a whole frame: ``frame(left=..., right=...)`` returns it.

    ``image(t_ns)`` is a valid image message stamped ``t_ns``.
    """
    def variant(change):
        def make():
            return frame(**{_side(topic): change})
        return make

    def bad_step(msg):
        msg.step = msg.width  # shorter than a row
        return msg

    def bad_size(msg):
        msg.data = bytes(msg.data)[:-7]
        return msg

    def bad_encoding(msg):
        msg.encoding = '16UC1'
        return msg

    def empty(msg):
        msg.width = msg.height = msg.step = 0
        msg.data = b''
        return msg

    def small(msg):
        array = np.zeros((msg.height // 2, msg.width // 2, 3), dtype=np.uint8)
        return image_msg(array, msg.header.stamp)

    cases = [('step shorter than a row', variant(bad_step)),
             ('data length', variant(bad_size)),
             ('encoding 16UC1', variant(bad_encoding)),
             ('empty', variant(empty)),
             ('size disagrees with camera_info', variant(small))]
    for name, s in bad_stamps(0):
        cases.append((name, variant(lambda msg, s=s: _stamped(msg, s))))
    cases.append(('stamp 0.4 s ahead', variant(lambda msg: _stamped(
        msg, ns_stamp(stamp_ns(msg.header.stamp) + AHEAD_NS)))))
    return [(name, topic, make) for name, make in cases]


def _side(topic):
    return 'left' if 'left' in topic else 'right'


#: Seed of the full-size image contents: the same pixels in every run.
CONTENT_SEED = 39


def content_images(width, height):
    """
    Return (name, (left, right) RGB arrays) of valid full-size images costly to search.

    What a real cell can show (a lens cap off in a textured scene, a flash, sensor noise at
    ``image_noise_stddev`` 0.5, a patterned background, confetti of the markers' colours)
    and what costs a circle search most: uniform noise, Gaussian noise on grey, a black and
    white and a red and blue checkerboard, and 600 discs of the markers' colours and sizes,
    the right image the left shifted 24 px (a disparity every disc could pair with).
    """
    from ibvs_model.scene import MARKER_RGB
    rng = np.random.default_rng(CONTENT_SEED)
    shape = (height, width, 3)
    noise = rng.integers(0, 256, shape, dtype=np.uint8)
    grey = np.clip(128.0 + rng.normal(0.0, 0.5 * 255.0, shape), 0, 255).astype(np.uint8)
    rows, cols = np.indices((height, width)) // 16
    board = ((rows + cols) % 2 == 1)
    black_white = np.repeat(board[:, :, None] * 255, 3, axis=2).astype(np.uint8)
    red_blue = np.where(board[:, :, None], MARKER_RGB[0], MARKER_RGB[1]).astype(np.uint8)
    discs = np.full(shape, 235, dtype=np.uint8)
    for k in range(600):
        centre = (int(rng.integers(0, width)), int(rng.integers(0, height)))
        cv2.circle(discs, centre, int(rng.integers(4, 40)), MARKER_RGB[k % 2], -1,
                   cv2.LINE_AA)

    def shifted(image):
        return np.ascontiguousarray(np.roll(image, -24, axis=1))

    return [('uniform noise', (noise, shifted(noise))),
            ('Gaussian noise 0.5 on grey', (grey, shifted(grey))),
            ('checkerboard 16 px', (black_white, shifted(black_white))),
            ('red and blue checkerboard 16 px', (red_blue, shifted(red_blue))),
            ('600 discs of the marker colours', (discs, shifted(discs)))]


def contents(topic, frame, answered, width, height):
    """
    Return cases of valid full-size stereo frames costly to search, each a whole frame.

    ``frame(left=..., right=...)`` returns the next frame's messages (each change replaces
    that image); ``answered(messages)`` returns the predicate that the node answered the
    frame (published it, or dropped it with a count). Nothing is to be rejected: the
    checks are survival, the answer and the node acting on the next frame.
    """
    from .harness import Case

    def replace(array):
        return lambda msg: image_msg(array, msg.header.stamp, msg.encoding,
                                     msg.header.frame_id)

    cases = []
    for name, pair in content_images(width, height):
        label = f'{name} {width} x {height}'

        def case(label=label, pair=pair):
            messages = frame(left=replace(pair[0]), right=replace(pair[1]))
            return Case(label, topic, messages, counted=0, answered=answered(messages))
        cases.append((label, topic, case))
    return cases


class Newcomer:
    """
    A second publisher on ``topic`` (node :data:`ROGUE`), and the check of what became of it.

    Called (the case's ``answered``) until true: once the node has taken the topic's own
    publishers as the expected ones (it learns them at its first looks), the second
    publisher comes; it is true once the node named it on /diagnostics
    (``second_publishers``, a WARN status, ``second_publishers_seen`` one more) and then,
    after it left, said it is gone.
    """

    def __init__(self, rig, topic, msg_type):
        """Take the rig; nothing comes yet."""
        self.rig, self.topic, self.msg_type = rig, topic, msg_type
        self.words = f'second publisher on {topic}: /{ROGUE}'
        self.rogue = None
        self.named = False

    def __call__(self):
        """Return whether it was named, and is gone and said so (class docstring)."""
        diag = self.rig.diagnostics
        said = diag.values.get('second_publishers', 'none')
        if self.rogue is None:
            expected = diag.publishers.expected.get(self.topic)
            if expected is not None and expected.settled:
                self.seen = diag.values.get('second_publishers_seen', 0)
                self.rogue = Node(ROGUE, context=self.rig.driver.context)
                self.rogue.create_publisher(self.msg_type, self.topic, contract.RELIABLE)
            return False
        if not self.named:
            status = diag.status()
            if (self.words in said and self.words in status.message
                    and status.level >= DiagnosticStatus.WARN
                    and diag.values['second_publishers_seen'] == self.seen + 1):
                self.named = True
                self.rogue.destroy_node()
            return False
        return self.topic not in said


def second_publishers(rig):
    """
    Return a 'second publisher' case for each :data:`SECOND_PUBLISHER_TOPICS` of ``rig``.

    The topics the node reads (its subscriptions) and those it commands on (the watch's
    commands: none but its own publisher expected), each with its own message type.
    """
    types = {t: p.msg_type for t, p in rig.pubs.items()}
    watch = rig.diagnostics.publishers
    types.update((p.topic_name, p.msg_type) for p in rig.node.publishers
                 if p.topic_name in watch.expected and watch.expected[p.topic_name].count == 0)
    specs = []
    for topic in SECOND_PUBLISHER_TOPICS:
        if topic in types:
            def make(topic=topic):
                return Case('second publisher', topic, [], counted=0,
                            answered=Newcomer(rig, topic, types[topic]))
            specs.append(('second publisher', topic, make))
    return specs


def huge_trajectories(topic, rows, taken):
    """
    Return a valid feedforward trajectory of :data:`HUGE_POINTS` points, and one bad in its last.

    ``rows`` (n, 6): the trajectory the rig holds, its last row repeated to the length;
    ``taken(n)`` returns whether the node now holds a trajectory of ``n`` points. The valid
    one must be taken (nothing to reject) and the node act on its next input; the other
    rejected, its points all read.
    """
    rows = np.asarray(rows, dtype=float)
    long = np.vstack([rows, np.tile(rows[-1], (HUGE_POINTS - len(rows), 1))])
    bad = long.copy()
    bad[-1, 2] = np.nan

    def valid():
        return Case(f'valid trajectory of {HUGE_POINTS} points', topic,
                    [(topic, joint_trajectory(0, 1_000_000, long))], counted=0,
                    answered=lambda: taken(HUGE_POINTS))

    return [(f'valid trajectory of {HUGE_POINTS} points', topic, valid),
            (f'{HUGE_POINTS} points, NaN in the last', topic,
             lambda: [joint_trajectory(0, 1_000_000, bad)])]


class Rewound:
    """
    The check of a /clock set back (:func:`clock_jumps`): seen by the node, the rig rewound.

    Called (the case's ``answered``) once the jump is delivered: the rig's inputs go on from
    ``back_ns`` (the rig's ``rewind``: a restarted simulator's time line), and it is true
    once the node's clock watch (:func:`ibvs_common.sim_time.clock_watch`) counted one jump
    back more. That the node takes the inputs of the earlier time is the harness's check
    that it acts on the next valid input.
    """

    def __init__(self, rig, back_ns):
        """Take the rig and the time set back to; note the jumps the node has seen."""
        self.rig, self.back_ns = rig, back_ns
        self.before = clock_watch(rig.node).jumps_back
        self.rewound = False

    def __call__(self):
        """Rewind the rig (once); return whether the node saw the jump."""
        if not self.rewound:
            self.rig.rewind(self.back_ns)
            self.rewound = True
        return clock_watch(self.rig.node).jumps_back == self.before + 1


def clock_jumps(rig):
    """
    Return the 'clock set back' case of a rig that reads /clock and can rewind its inputs.

    A /clock at the rig's time (the stamp of its last valid input, ``rig.now_ns()``), then
    one at 1 ms, as a simulator restarted under a running graph starts it again: the node
    must see the jump (:class:`Rewound`) and take the inputs stamped from then on, which
    its stamp orders of the old time line would refuse as gone back. Nothing is rejected.
    """
    if contract.CLOCK not in rig.pubs or not hasattr(rig, 'rewind'):
        return []

    def make():
        now, back = max(rig.now_ns(), 2_000_000), 1_000_000
        return Case('clock set back, then inputs from the earlier time', contract.CLOCK,
                    [(contract.CLOCK, Clock(clock=ns_stamp(now))),
                     (contract.CLOCK, Clock(clock=ns_stamp(back)))], counted=0,
                    answered=Rewound(rig, back))
    return [('clock set back, then inputs from the earlier time', contract.CLOCK, make)]
