"""
feature_node's typed configuration (:class:`FeatureConfig`), no ROS.

Each value is checked against its Param at construction, then the rules across them: the
detector's (:class:`.detector.DetectorConfig`: the Hough radii) and the camera pose's
(:func:`ibvs_common.shared_params.camera_pose_from`, a rule the node runs at start), so that
``ibvs run`` refuses a bad combination before any node starts, in the node's words.
"""

from dataclasses import dataclass

from ibvs_common import shared_params as shared
from ibvs_common.params import group_field, Param, param_field, ParamConfig, ParameterError

from . import stamp_offset
from .detector import config as detector

BLEND_TIME_S = Param(
    'blend_time_s', 0.2, 'time over which the published features move from the estimate '
    'to the measurement (and back) after a switch (section 2.3); 0: switch outright', 's',
    low=0.0, high=10.0)
HOLD_MODEL_ERROR = Param(
    'hold_model_error', False, 'while the markers are not seen, publish F(q_T) plus the '
    'model error the last measurement showed instead of F(q_T) alone (the paper)', '-')
DETECTION_BUDGET_SHARE = Param(
    'detection_budget_share', 0.5, 'share of the camera frame period the detector may spend '
    'on a stereo pair, in its estimated cost (detector.budget); a pair that needs more is '
    'not measured', '-', low=0.0, high=1.0, low_open=True)
JOINT_HISTORY_S = Param(
    'joint_history_s', 2.0, 'how long joint states are kept to match image stamps', 's',
    low=0.0, high=60.0, low_open=True)
STAMP_OFFSET_WINDOW_S = Param(
    'stamp_offset_window_s', 1.0, "the window of measured frames over which the camera's "
    'stamp offset (stamp - exposure) is estimated from the joint states (stamp_offset: the '
    'offset that best explains the image motion; each frame is then read and published at '
    'its estimated exposure); 0: the stamps are taken as the exposures. Free-running only '
    '(in lockstep the stamps are the exposures and name the frames); needs joint states at '
    'least 4 a frame and the window, the largest offset (0.2 s) and the speed step within '
    'joint_history_s', 's', low=0.0, high=10.0)
STAMP_OFFSET_INITIAL_S = Param(
    'stamp_offset_initial_s', 0.0, 'the stamp offset applied from the first frame and the '
    "estimate's start: what an earlier run on the same camera found (its stamp_offset_ms on "
    "/diagnostics, ibvs cell's status line); the estimate replaces it once the arm moves; "
    '0 in lockstep', 's', low=-0.2, high=0.2)
PUBLISH_DEBUG_IMAGES = Param(
    'publish_debug_images', False, 'publish the overlays on /ibvs/debug/{left,right}/image '
    'for every frame even when nobody subscribes (e.g. to record them)', '-')


@dataclass(frozen=True)
class FeatureConfig(ParamConfig):
    """The parameters of feature_node (each field: the parameter of its name)."""

    #: Rules between parameters, run at start and by ``ibvs run`` before any node starts.
    RULES = (shared.camera_pose_from,)

    blend_time_s: float = param_field(BLEND_TIME_S)
    hold_model_error: bool = param_field(HOLD_MODEL_ERROR)
    epipolar_tolerance_px: float = param_field(detector.EPIPOLAR_TOLERANCE_PX)
    hough_min_radius_px: int = param_field(detector.HOUGH_MIN_RADIUS_PX)
    hough_max_radius_px: int = param_field(detector.HOUGH_MAX_RADIUS_PX)
    hough_canny_high: float = param_field(detector.HOUGH_CANNY_HIGH)
    hough_votes: int = param_field(detector.HOUGH_VOTES)
    min_colour_score: float = param_field(detector.MIN_COLOUR_SCORE)
    roi_margin_px: int = param_field(detector.ROI_MARGIN_PX)
    detection_budget_share: float = param_field(DETECTION_BUDGET_SHARE)
    joint_history_s: float = param_field(JOINT_HISTORY_S)
    stamp_offset_window_s: float = param_field(STAMP_OFFSET_WINDOW_S)
    stamp_offset_initial_s: float = param_field(STAMP_OFFSET_INITIAL_S)
    command_interface: str = param_field(shared.COMMAND_INTERFACE)
    publish_debug_images: bool = param_field(PUBLISH_DEBUG_IMAGES)
    timing: shared.Timing = group_field(shared.Timing)
    camera_pose: tuple[float, ...] = param_field(shared.CAMERA_POSE)
    target: shared.Target = group_field(shared.Target)

    def __post_init__(self):
        """Check each value, then the detector's rules (:meth:`detector_config`)."""
        super().__post_init__()
        self.detector_config()
        if self.lockstep and self.stamp_offset_initial_s != 0.0:
            raise ParameterError(
                f"parameter 'stamp_offset_initial_s' = {self.stamp_offset_initial_s!r} is "
                "invalid in lockstep: a frame's stamp names it there (the joint controller "
                'waits for the q_feedback of that stamp); allowed: 0 (or command_interface '
                "'position')")
        reach_s = self.stamp_offset_window_s + stamp_offset.REACH_S
        if self.stamp_offset_window_s > 0.0 and reach_s > self.joint_history_s:
            raise ParameterError(
                f"parameter 'stamp_offset_window_s' = {self.stamp_offset_window_s!r} is "
                f'invalid with joint_history_s = {self.joint_history_s!r}: the estimate reads '
                f'joint states up to {reach_s:g} s back; allowed: at most '
                f'{self.joint_history_s - stamp_offset.REACH_S:g} (or a longer '
                'joint_history_s, or 0: no estimate)')

    def detector_config(self) -> detector.DetectorConfig:
        """Return the detector's tuning of these values (ParameterError if it refuses them)."""
        return detector.DetectorConfig.from_parameters(self.values())

    @property
    def lockstep(self) -> bool:
        """Return whether it runs in lockstep, by :func:`ibvs_common.shared_params.lockstep`."""
        return shared.lockstep(self.values())

    @property
    def estimates_stamp_offset(self) -> bool:
        """Return whether the stamp offset is estimated: free-running, with a window."""
        return not self.lockstep and self.stamp_offset_window_s > 0.0

    @property
    def budget_ms(self) -> float:
        """Return the detector's budget per stereo pair: its share of the camera period (ms)."""
        return self.detection_budget_share * 1e3 / self.timing.camera_rate_hz
