"""
The camera's stamp offset, found online from the encoders (no ROS).

A camera driver stamps a frame at some moment of its own, not at the exposure: the ZED
wrapper stamps ``getTimestamp(sl::TIME_REFERENCE::IMAGE)``, the time the host received the
frame, one to two frame periods after the exposure at 30 fps (docs/real_cell.md). Every use
of a frame's stamp as its exposure, the joint angles the feature node estimates the
markers at and the feedback's prediction from the exposure (ibvs_control.prediction), is
then wrong by that constant delta = stamp - exposure.

The encoders say where the arm was at every moment, and the camera-and-robot model F
(eq. 30) where the markers were then: delta is the shift of the encoders' time line that
best explains the measured image motion. The model's own error (the calibration's and the
arm's: a real cell's joint offsets, the rehearsal's ``disturbance_deg``) is not constant
over a window of motion: it changes with the pose, to first order in proportion to the
image displacement, J_err J^+ (f - f_bar). Over a sliding window of measured frames
(t_i, s_i), with f_i = F(q(t_i - delta)), a bias b and a per-channel scale d of the
displacement unknown,

    s_i = f_i + b + d * (f_i - f_bar) + noise,                                       (S)

solved by Gauss-Newton in delta with b and d eliminated: linearised at delta_0,
r_i = s_i - f_i(delta_0) = b + d * (f_i - f_bar) - sdot_i (delta - delta_0), with sdot_i
the image speed F(q(t))' at t_i - delta_0 (central differences of the interpolated
encoders). With each channel's mean and its fit to that channel's displacement removed
(written ^; for motion along one direction in joint space the diagonal d is as general as
a full matrix),

    delta - delta_0 = -sum(r^_i . sdot^_i) / sum(|sdot^_i|^2),
    sd(delta) = sigma_r / sqrt(sum(|sdot^_i|^2)),

sigma_r the residuals' standard deviation after the fit (13 unknowns). A constant image
speed is indistinguishable from a bias (a shifted straight line is a line) and a speed in
proportion to the displacement from a scale, so delta is observable only through the image
motion's changes: a start, a stop, a turn. The window's excitation is the root mean square
of sdot^; below ``min_excitation_px_s`` (the tool still, or moving uniformly) the last
estimate is held and the state says so.

- :func:`fit_stamp_offset`: one fit of (S) over a window;
- :class:`StampOffsetEstimator`: the window, the fits every few frames, the held estimate
  and the offset applied to the stamps (moved towards the estimate by at most a quarter of
  a frame period a frame, so that corrected stamps stay in order).
"""

from collections import deque
from typing import Callable, Deque, NamedTuple, Optional, Sequence, Tuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: Half the central difference's span for the image speed (ns): one period of a 250 Hz
#: joint_state_broadcaster, between which the encoders are interpolated linearly.
SPEED_STEP_NS = 4_000_000
#: Gauss-Newton iterations of one fit, at most; it stops once a step is under STEP_TOL_NS.
ITERATIONS = 5
STEP_TOL_NS = 50_000
#: A frame's residual over this many times the median frame's is an outlier.
OUTLIER_FACTOR = 4.0
#: An estimate is applied only once its standard deviation is at most this (ns).
MAX_SD_NS = 2_000_000
#: Fewest frames of a fit: 13 unknowns (delta, b and d), 6 equations a frame.
MIN_FRAMES = 8
#: The largest |delta| looked for (ns): two frame periods of a ZED 2 at 15 fps, well past
#: the one to two at 30 fps a ZED wrapper's stamps lag by.
MAX_OFFSET_NS = 200_000_000
#: How far (s) before a window's oldest stamp the fits read joint states.
REACH_S = (MAX_OFFSET_NS + SPEED_STEP_NS) * 1e-9
#: The window's excitation (px/s) below which the estimate is held. The noise alone would
#: allow far less (0.3 px of it over a one-second window at 30 fps gives a standard
#: deviation of about 1 ms at 30 px/s), but what (S) does not model of the model's error
#: grows with the distance moved, the timing signal with the speed: in the rehearsal
#: (docs/real_cell.md) windows at 40-50 px/s were off by up to 40 ms, at 130 px/s and more
#: by at most 2 ms. The standard deviation given is the noise's share alone.
MIN_EXCITATION_PX_S = 100.0
#: Joint states must come at least this many times a camera period to estimate from:
#: between sparser ones the interpolated encoders cannot tell a few milliseconds (the
#: feature node estimates free-running only; lockstep's stamps are the exposures).
MIN_STATES_PER_FRAME = 4

JointsAt = Callable[[int], Optional[NDArray[np.float64]]]
#: F of many joint vectors: (m, 6) joint angles to (m, 6) features.
FeaturesOf = Callable[[NDArray[np.float64]], NDArray[np.float64]]


class OffsetFit(NamedTuple):
    """One fit of (S): the offset, its standard deviation, the window's excitation."""

    offset_ns: int
    sd_ns: float
    excitation_px_s: float
    frames: int


def fit_stamp_offset(stamps_ns: Sequence[int], features: ArrayLike, joints_at: JointsAt,
                     features_of: FeaturesOf, offset0_ns: int = 0,
                     max_offset_ns: int = MAX_OFFSET_NS,
                     outliers_out: bool = True) -> Optional[OffsetFit]:
    """
    Fit (S) over one window: the stamp offset that best explains the image motion.

    Parameters
    ----------
    stamps_ns : sequence of int
        The frames' stamps (ns), as the camera gave them.
    features : array_like, shape (n, 6)
        The features measured in each frame (px), eq. (2)-(3).
    joints_at : callable
        The encoder angles at a time (ns), or None where the joint states kept do not
        reach (the frame is then left out).
    features_of : callable
        The model F (eq. 30) of many joint vectors at once: (m, 6) joint angles to (m, 6)
        features (``CameraRobotModel.features_batch``).
    offset0_ns : int
        Where Gauss-Newton starts (the last estimate).
    max_offset_ns : int
        The largest |delta| looked for: a fit that leaves it is refused (None).
    outliers_out : bool
        Whether the frames whose residual is over :data:`OUTLIER_FACTOR` times the median
        frame's are left out and the rest fitted again (once).

    Returns
    -------
    OffsetFit or None
        None with fewer than :data:`MIN_FRAMES` frames the joint states reach or a fit
        beyond ``max_offset_ns``; without any image motion, ``offset0_ns`` with an infinite
        standard deviation and no excitation.

    """
    stamps = np.asarray(stamps_ns, dtype=np.int64)
    s = np.asarray(features, dtype=float).reshape(len(stamps), 6)
    offset = int(offset0_ns)
    speed = keep = None
    for _ in range(ITERATIONS):
        rows, qs = [], []
        for i, t in enumerate(stamps):
            if keep is not None and not keep[i]:
                continue
            q = joints_at(int(t) - offset)
            if q is None:
                continue
            rows.append(i)
            qs.append(q)
        if not rows:
            return None
        f = features_of(np.asarray(qs))
        if speed is None:  # the image speed, once, at the starting offset
            speed_rows, q_a, q_b = [], [], []
            for i in rows:
                t = int(stamps[i]) - offset
                a, b = joints_at(t - SPEED_STEP_NS), joints_at(t + SPEED_STEP_NS)
                if a is None or b is None:
                    continue
                speed_rows.append(i)
                q_a.append(a)
                q_b.append(b)
            if len(speed_rows) < MIN_FRAMES:
                return None
            keep = np.zeros(len(stamps), dtype=bool)
            keep[speed_rows] = True
            f = f[keep[rows]]
            rows = speed_rows
            both = features_of(np.vstack([q_a, q_b]))
            speed = (both[len(rows):] - both[:len(rows)]) * (0.5e9 / SPEED_STEP_NS)
            drift = _centred(f)
            speed_c = _residual(_centred(speed), drift)
            energy = float(np.sum(speed_c ** 2))
            if energy <= 0.0:  # no image motion at all: nothing to tell the offset by
                return OffsetFit(offset, float('inf'), 0.0, len(rows))
        if len(rows) != len(speed):  # a state gone from the history since: start again
            return None
        r = s[rows] - f
        r_c = _residual(_centred(r), drift)
        step = -float(np.sum(r_c * speed_c)) / energy
        offset += int(round(step * 1e9))
        if abs(offset) > max_offset_ns:
            return None
        if abs(step) * 1e9 < STEP_TOL_NS:
            break
    residual = r_c + speed_c * step
    dof = residual.size - 13
    sigma = float(np.sqrt(np.sum(residual ** 2) / dof)) if dof > 0 else float('inf')
    # A frame whose residual is far beyond the others' (a marker half hidden at the image's
    # edge, a blob taken for a marker) is left out and the window fitted again without it.
    norms = np.sqrt(np.sum(residual ** 2, axis=1))
    inliers = norms <= OUTLIER_FACTOR * float(np.median(norms))
    if outliers_out and not inliers.all() and inliers.sum() >= MIN_FRAMES:
        kept = np.asarray(rows)[inliers]
        return fit_stamp_offset(stamps[kept], s[kept], joints_at, features_of, offset,
                                max_offset_ns, outliers_out=False)
    return OffsetFit(offset, float(sigma / np.sqrt(energy) * 1e9),
                     float(np.sqrt(energy / len(rows))), len(rows))


def _centred(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return the columns of ``x`` less their means."""
    return x - x.mean(axis=0)


def _residual(x: NDArray[np.float64], drift: NDArray[np.float64]) -> NDArray[np.float64]:
    """Return each column of ``x`` less its least-squares fit to the same column of ``drift``."""
    norm = np.sum(drift ** 2, axis=0)
    scale = np.divide(np.sum(x * drift, axis=0), norm, out=np.zeros(x.shape[1]),
                      where=norm > 0.0)
    return x - drift * scale


class OffsetState(NamedTuple):
    """What the estimator says: the estimate, the offset applied, and why it is so."""

    estimate_ns: Optional[int]
    sd_ns: Optional[float]
    applied_ns: int
    state: str
    excitation_px_s: float


class StampOffsetEstimator:
    """
    The window of measured frames, a fit every ``update_frames``, the estimate held and applied.

    Parameters
    ----------
    window_ns : int
        How far back (ns) from the newest frame the window reaches.
    camera_period_ns : int
        The camera's frame period (ns): the applied offset moves by at most a quarter of it
        a frame.
    min_excitation_px_s : float
        The window's excitation (module docstring) below which the estimate is held.
    max_offset_ns : int
        The largest |delta| looked for.
    update_frames : int
        Measured frames between two fits.
    initial_ns : int
        The offset applied until an estimate replaces it, and the first fit's start (what
        an earlier run found).

    """

    def __init__(self, window_ns: int, camera_period_ns: int,
                 min_excitation_px_s: float = MIN_EXCITATION_PX_S,
                 max_offset_ns: int = MAX_OFFSET_NS, update_frames: int = 10,
                 initial_ns: int = 0) -> None:
        """Create the estimator with nothing seen (see the class docstring)."""
        self.window_ns = window_ns
        self.camera_period_ns = camera_period_ns
        self.min_excitation_px_s = min_excitation_px_s
        self.max_offset_ns = max_offset_ns
        self.update_frames = update_frames
        self._frames: Deque[Tuple[int, NDArray[np.float64]]] = deque()
        self._since_fit = 0
        self.estimate_ns: Optional[int] = None
        self.sd_ns: Optional[float] = None
        self.initial_ns = self.applied_ns = initial_ns
        self.fits = 0
        self.state = 'no measured frames yet'
        self.excitation_px_s = 0.0

    def forget(self) -> None:
        """Forget the window (the clock jumped back); the estimate and the offset are kept."""
        self._frames.clear()
        self._since_fit = 0

    def offer(self, t_ns: int, features: ArrayLike) -> None:
        """Keep the measured features of the frame stamped ``t_ns`` (px)."""
        self._frames.append((t_ns, np.asarray(features, dtype=float)))
        while self._frames and self._frames[0][0] < t_ns - self.window_ns:
            self._frames.popleft()
        self._since_fit += 1

    def due(self) -> bool:
        """Say whether a fit is due: ``update_frames`` measured frames since the last."""
        return self._since_fit >= self.update_frames and len(self._frames) >= MIN_FRAMES

    def update(self, joints_at: JointsAt, features_of: FeaturesOf,
               states_per_frame: Optional[float]) -> OffsetState:
        """
        Fit the window if due, keep what the fit says, and return the state.

        ``states_per_frame``: how many joint states come a camera period (None before two):
        below :data:`MIN_STATES_PER_FRAME` nothing is estimated and the offset stays the
        initial one.
        """
        if not self.due():
            return self.current()
        self._since_fit = 0
        if states_per_frame is None or states_per_frame < MIN_STATES_PER_FRAME:
            rate = 'none yet' if states_per_frame is None else f'{states_per_frame:.1f}'
            self.state = (f'not estimated: joint states a frame {rate} (at least '
                          f'{MIN_STATES_PER_FRAME} needed)')
            return self.current()
        stamps, features = zip(*self._frames)
        fit = fit_stamp_offset(stamps, np.asarray(features), joints_at, features_of,
                               self.initial_ns if self.estimate_ns is None
                               else self.estimate_ns, self.max_offset_ns)
        if fit is None:
            self.state = ('holding: the window does not fit' if self.estimate_ns is not None
                          else 'waiting: the window does not fit yet')
            return self.current()
        self.excitation_px_s = fit.excitation_px_s
        if fit.excitation_px_s < self.min_excitation_px_s:
            self.state = ('holding: the tool is still' if self.estimate_ns is not None
                          else 'waiting for the tool to move')
            return self.current()
        self.fits += 1
        self.estimate_ns, self.sd_ns = fit.offset_ns, fit.sd_ns
        self.state = 'estimating' if fit.sd_ns <= MAX_SD_NS else \
            'estimating (not applied: uncertain)'
        return self.current()

    def current(self) -> OffsetState:
        """Return the estimate, its standard deviation, the applied offset and the state."""
        return OffsetState(self.estimate_ns, self.sd_ns, self.applied_ns, self.state,
                           self.excitation_px_s)

    def advance(self) -> int:
        """
        Move the applied offset towards a certain estimate by at most a quarter period; return it.

        Called once a frame: two successive corrected stamps t - applied stay at least three
        quarters of a frame period apart, and in order.
        """
        if self.estimate_ns is not None and self.sd_ns is not None \
                and self.sd_ns <= MAX_SD_NS:
            limit = self.camera_period_ns // 4
            self.applied_ns += int(np.clip(self.estimate_ns - self.applied_ns, -limit, limit))
        return self.applied_ns
