"""
What ``ibvs cell``'s status line says, from the session's messages as they come (no ROS).

:class:`StatusBoard` takes plain values (the servo status, the frames a command used, each
DiagnosticStatus, the features) and words them once a second; :class:`PoseError` gives the
model's pose error of the tool from the newest /joint_states, as the analysis of a bag
defines it (:func:`.metrics.axis_angle_deg`). ``ibvs cell`` (ibvs_experiments.cell, its
module docstring, step 3) feeds both from its subscriptions.
"""

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
import math
import time
from typing import Any

import numpy as np

#: What the status line says of a holding code until /diagnostics says more (in the
#: sim-time rehearsal a stopped /clock ages nothing: only the code tells it).
HOLD_WORDS = {'HOLD_CLOCK_STOPPED': 'clock stopped',
              'HOLD_CLOCK_JUMPED_BACK': 'clock jumped back',
              'HOLD_SECOND_PUBLISHER': 'second publisher'}


class PoseError:
    """
    The model's pose error of the tool: the nominal kinematics of /joint_states vs the target.

    Called with the newest /joint_states as serialized bytes (the recorder's ``latest``),
    returns (position error m, tool-axis error deg) as the analysis defines them
    (:func:`.metrics.axis_angle_deg`), or (None, None) without a readable one.
    The encoders' view: on a cell the only one; at the taught pose it is the target's own
    (``ibvs teach``), so it goes to zero as the image error does.
    """

    def __init__(self, target: Any) -> None:
        """Keep the target T_E^O (4x4)."""
        self.target = target

    def __call__(self, raw: bytes | None) -> tuple[float | None, float | None]:
        """Return the errors of the joint state ``raw`` (class docstring)."""
        if raw is None:
            return None, None
        from ibvs_common.conversions import InputError, read_joints
        from ibvs_model import forward_kinematics
        from rclpy.serialization import deserialize_message
        from sensor_msgs.msg import JointState

        from .metrics import axis_angle_deg
        try:
            pose = forward_kinematics(read_joints(deserialize_message(raw, JointState)))
        except (InputError, ValueError):
            return None, None
        position = float(math.dist(pose[:3, 3], self.target[:3, 3]))
        return position, float(axis_angle_deg(pose[None, :3, :3], self.target[:3, :3])[0])


@dataclass
class StatusBoard:
    """
    What the status line says (ibvs_experiments.cell, step 3), from the messages as they come.

    Fed with plain values (:meth:`servo`, :meth:`frame_used`, :meth:`diagnostics`), so
    that it needs no ROS; ``clock`` is the wall clock of ages.
    """

    clock: Callable[[], float] = time.monotonic
    code: int | None = None
    frames: set = field(default_factory=set)
    last_error: str = ''
    last_error_at: float | None = None
    #: The joint controller's /diagnostics message (why it waits or holds).
    detail: str = ''
    #: Each node's second publishers, in its words (``second_publishers``), while any.
    newcomers: dict = field(default_factory=dict)
    #: Whether something the operator must see at once came since :meth:`take_news`: a
    #: new servo status, a second publisher that came or went.
    news: bool = False
    #: A dry run (the joint controller's ``dry_run``): the line says so first.
    dry_run: bool = False
    #: The newest features the loop used (/ibvs/features) and the taught target's
    #: (/ibvs/target_features), px (6,): the image error |s - s*| of the status line.
    features_px: Any = None
    target_px: Any = None
    #: The feedback node's own error norm (its /diagnostics ``image_error_norm_px``: the
    #: error it integrates, predicted to the rest pose), shown without a taught target.
    feedback_error_px: float | None = None
    #: The model's pose error (:class:`PoseError`): position (m), tool axis (deg).
    position_error_m: float | None = None
    axis_error_deg: float | None = None
    #: The camera's stamp offset the feature node estimated (its /diagnostics
    #: ``stamp_offset_ms`` and ``stamp_offset_sd_ms``, ibvs_vision.stamp_offset), and the
    #: estimate's state when it holds or waits: shown once there is an estimate.
    stamp_offset_ms: float | None = None
    stamp_offset_sd_ms: float | None = None
    stamp_offset_state: str = ''
    _rejected: dict = field(default_factory=dict)

    def __post_init__(self):
        """Start the session's clock."""
        self.started = self.clock()

    def servo(self, code: int) -> None:
        """Take a /ibvs/servo_status code."""
        self.news = self.news or int(code) != self.code
        self.code = int(code)

    def take(self, attr: str, msg: Any) -> None:
        """Take a features message as ``attr`` (:attr:`features_px`, :attr:`target_px`)."""
        from ibvs_common.conversions import InputError, read_features
        try:
            setattr(self, attr, read_features(msg))
        except InputError:
            pass  # the nodes reject and count it: the last error says so

    def take_news(self) -> bool:
        """Return whether there is news (:attr:`news`), and clear it."""
        news, self.news = self.news, False
        return news

    def image_error(self) -> tuple[float | None, str]:
        """
        Return the image error (px) and its words: |s - s*| of the features the loop used.

        s* is the taught target's (/ibvs/target_features); without one (a model target) the
        feedback node's own error norm, said so; (None, '') before either.
        """
        if self.features_px is not None and self.target_px is not None:
            from ibvs_control.controllers import feature_error
            return float(np.linalg.norm(feature_error(self.features_px, self.target_px))), ''
        if self.feedback_error_px is not None:
            return self.feedback_error_px, " (the feedback's)"
        return None, ''

    def pose_error(self, position_m: float | None, axis_deg: float | None) -> None:
        """Take the model's pose error (:class:`PoseError`; None: none known yet)."""
        if position_m is not None:
            self.position_error_m, self.axis_error_deg = position_m, axis_deg

    def frame_used(self, frame_stamp_ns: int) -> None:
        """Take a /ibvs/frame_latency: the frame of that stamp was used by a command."""
        self.frames.add(int(frame_stamp_ns))

    def diagnostics(self, name: str, level: int, message: str,
                    values: Mapping[str, str]) -> None:
        """
        Take one DiagnosticStatus (``name`` '<node>: <what>', level 0 OK, 1 WARN, 2 ERROR).

        A WARN or ERROR is the last error; so is a rejected input (a ``rejected[...]``
        count that grew, ibvs_common.diagnostics).
        """
        node = name.partition(': ')[0]
        if node == 'joint_controller_node' and 'servo_status' in values:
            self.detail = message
        if node == 'adaptive_feedback_node' and 'image_error_norm_px' in values:
            try:
                self.feedback_error_px = float(values['image_error_norm_px'])
            except ValueError:
                pass
        if node == 'feature_node' and 'stamp_offset_state' in values:
            self.stamp_offset_state = values['stamp_offset_state']
            try:
                self.stamp_offset_ms = float(values.get('stamp_offset_ms', ''))
                self.stamp_offset_sd_ms = float(values.get('stamp_offset_sd_ms', ''))
            except ValueError:
                pass  # 'none': no estimate yet
        if 'second_publishers' in values:
            words = values['second_publishers']
            words = '' if words == 'none' else words
            if words != self.newcomers.get(node, ''):
                self.news = True
            if words:
                self.newcomers[node] = words
            else:
                self.newcomers.pop(node, None)
        for key, count in values.items():
            if not key.startswith('rejected['):
                continue
            try:
                count = int(count)
            except ValueError:
                continue
            if count > self._rejected.get((node, key), 0):
                self._error(f'{node} {key[len("rejected["):-1]} ({count} so far)')
            self._rejected[(node, key)] = count
        if level >= 1 and message:
            self._error(f'{node}: {message}')

    def _error(self, text):
        self.last_error, self.last_error_at = text, self.clock()

    def line(self) -> str:
        """Return the status line now."""
        from ibvs_common.servo_codes import ServoStatus
        now = self.clock()
        if self.code is None:
            servo = 'servo: no status yet'
        else:
            try:
                name = ServoStatus(self.code).name
                servo = f'servo {self.code} {name}'
            except ValueError:
                name, servo = None, f'servo {self.code} (unknown code)'
            words = HOLD_WORDS.get(name)
            if name == 'HOLD_SECOND_PUBLISHER' and self.newcomers:
                servo += f' ({words})'  # who: named next
            elif words is not None and not self.detail.startswith(words):
                servo += f' ({words})'  # the code comes at once, /diagnostics once a second
            elif self.detail and self.detail != 'ok':
                servo += f' ({self.detail})'
        error = (f'{self.last_error} ({now - self.last_error_at:.0f} s ago)'
                 if self.last_error_at is not None else 'none')
        seen = {}  # each topic's words once, naming who saw them
        for node, words in sorted(self.newcomers.items()):
            for item in words.split('; '):
                seen.setdefault(item, []).append(node)
        second = ''.join(f' | {words} (seen by {", ".join(nodes)})'
                         for words, nodes in seen.items())
        errors = ''
        image, whose = self.image_error()
        if image is not None:
            errors += f' | image error {image:.3f} px{whose}'
        if self.position_error_m is not None:
            errors += (f' | pose error {self.position_error_m * 1e3:.3f} mm, '
                       f'{self.axis_error_deg:.3f} deg')
        if self.stamp_offset_ms is not None:
            held = '' if self.stamp_offset_state == 'estimating' else \
                f' ({self.stamp_offset_state})'
            errors += (f' | stamp offset {self.stamp_offset_ms:.1f} +- '
                       f'{self.stamp_offset_sd_ms:.1f} ms{held}')
        dry = 'DRY RUN | ' if self.dry_run else ''
        return (f'[{now - self.started:6.0f} s] {dry}{servo}{second}{errors} | frames used '
                f'{len(self.frames)} | last error: {error}')
