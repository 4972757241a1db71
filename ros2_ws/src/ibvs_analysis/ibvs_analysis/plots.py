"""
Figures of one run, in the style of the paper's Figures 10-12, and more.

- ``pose_vs_time.png``: tool position (x, y, z) and tool axis a = z6 against time, with the
  targets (paper: blue response, red target), on a time axis that fits the transient, the
  whole run in an inset;
- ``trajectory_3d.png``: the flange path with tool-axis arrows, start (circle), target (star)
  and the target axis (red arrow);
- ``image_plane.png``: both markers' paths in the left and right images, measured and
  estimated parts apart, targets and image borders;
- ``feature_timeline.png``: which frames were measured, blended or estimated;
- ``error_vs_time.png``: position and tool-axis error norms on a log axis over the whole
  run (the sub-millimetre end), each with a linear inset from the time it first came within
  5 % of its start value (the overshoot);
- ``feature_error.png``: each marker's image error |p_I - p_bar| (px) against time, log
  axis, coloured by the frame's mode; p_bar is the target the controller used: the taught
  features in a taught run (``target_features_source: taught``), else F(q_target)
  (:func:`.results.target_features`);
- ``joints.png`` (with :func:`joints`): joint angles, speeds and torques against their
  limits.
"""

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use('Agg')

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import ArrayLike  # noqa: E402

if TYPE_CHECKING:
    from .analysis import RunData

MODE_COLOURS = {'measured': 'tab:green', 'blending': 'tab:orange', 'estimated': 'tab:red'}
#: Each marker's colour in the figures: P1 (flange) red, P2 (shaft) blue, as the spheres.
MARKER_COLOURS = ('tab:red', 'tab:blue')
#: The inset of error_vs_time.png shows this many seconds on a linear axis, from the time
#: the error is first within 5 % of its start value (the overshoot).
TRANSIENT_S = 0.4
#: The shortest time axis of pose_vs_time.png's transient (s).
TRANSIENT_MIN_S = 0.1


def transient_window(run: 'RunData') -> float:
    """
    Return the sim time (s from the start) that the transient of ``run`` fits in.

    Three times the 2 % settling time of the position error (the motion, its overshoot
    and the start of the correction), at least :data:`TRANSIENT_MIN_S`; the whole run when
    it never settles or the window would cover most of it.
    """
    t = run.t - run.t[0]
    error = np.linalg.norm(run.position - run.target[:3, 3], axis=1)
    from .metrics import _settle_time  # the rule of settling_time_2pct_s
    settle = _settle_time(t, error <= 0.02 * error[0])
    if settle is None:
        return float(t[-1])
    window = max(3.0 * settle, TRANSIENT_MIN_S)
    return float(t[-1]) if window >= 0.7 * t[-1] else window


def pose_vs_time(run: 'RunData', path: str | Path) -> None:
    """
    Plot position and tool axis against time with their targets (Figures 10-12).

    The time axis fits the transient (:func:`transient_window`); each panel's inset shows
    the whole run, with the window shaded.
    """
    fig, axes = plt.subplots(2, 3, figsize=(13, 6.5), sharex=True)
    t = run.t - run.t[0]
    window = transient_window(run)
    whole = window >= t[-1]
    for row, (values, target, label) in enumerate((
            (run.position, run.target[:3, 3], '{} [m]'),
            (run.rotation[:, :, 2], run.target[:3, 2], 'a_{} (tool axis z6)'))):
        for i, name in enumerate('xyz'):
            ax = axes[row, i]
            ax.plot(t, values[:, i], color='tab:blue', label='tool')
            ax.axhline(target[i], color='tab:red', ls='--', label='target')
            ax.set_ylabel(label.format(name))
            ax.set_xlim(0.0, window)
            ax.grid(alpha=0.3)
            if row == 1:
                ax.set_xlabel('sim time [s]')
            if not whole:
                inset = ax.inset_axes([0.58, 0.56, 0.4, 0.4])
                inset.plot(t, values[:, i], color='tab:blue', lw=0.8)
                inset.axhline(target[i], color='tab:red', ls='--', lw=0.8)
                inset.axvspan(0.0, window, color='0.85')
                inset.set_title(f'whole run, 0-{t[-1]:.2g} s', fontsize=7)
                inset.tick_params(labelsize=6)
    # One legend for the six panels, below them: inside a panel it covers a curve.
    fig.legend(*axes[0, 0].get_legend_handles_labels(), loc='lower center', ncol=2,
               frameon=False)
    what = ('tool pose against time' if whole else
            f'tool pose against time, the first {window:.3g} s (the transient; inset: the '
            'whole run)')
    fig.suptitle(_title(run, what))
    fig.tight_layout(rect=(0.0, 0.05, 1.0, 1.0))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def trajectory_3d(run: 'RunData', path: str | Path, arrows: int = 12) -> None:
    """Plot the 3D flange path with tool-axis arrows, start, target and target axis."""
    fig = plt.figure(figsize=(7.5, 6.5))
    ax = fig.add_subplot(projection='3d')
    p = run.position
    ax.plot(p[:, 0], p[:, 1], p[:, 2], color='tab:blue', lw=1.5, label='flange path')
    # Arrows equally spaced along the path (by arc length), not in time: the tool spends
    # most of the run at the target.
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
    idx = np.unique(np.searchsorted(arc, np.linspace(0.0, arc[-1], arrows)).clip(0, len(p) - 1))
    span = float(np.ptp(np.vstack([p, run.target[:3, 3]]), axis=0).max()) or 1.0
    length = 0.08 * span
    a = run.rotation[idx, :, 2]
    ax.quiver(p[idx, 0], p[idx, 1], p[idx, 2], a[:, 0], a[:, 1], a[:, 2], length=length,
              color='black', lw=0.8, label='tool axis')
    tgt = run.target[:3, 3]
    ax.quiver(*tgt, *run.target[:3, 2], length=length * 1.5, color='tab:red', lw=2,
              label='target axis')
    ax.scatter(*p[0], s=60, facecolors='none', edgecolors='tab:blue', label='start')
    ax.scatter(*tgt, s=120, marker='*', color='tab:red', label='target')
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.set_zlabel('z [m]')
    ax.set_box_aspect(np.ptp(np.vstack([p, tgt]), axis=0).clip(0.05))
    ax.legend(loc='upper left', fontsize=8)
    ax.set_title(_title(run, '3D trajectory'))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def image_plane(run: 'RunData', path: str | Path, target_features: ArrayLike | None = None
                ) -> None:
    """Plot both markers' image paths in the left and right images."""
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8))
    width, height = 1280, 720
    if run.camera is not None:
        width, height = run.camera.intrinsics.width, run.camera.intrinsics.height
    modes = _modes_at(run, run.feature_t)
    measured = np.array([m == 'measured' for m in modes], dtype=bool)
    for side, ax in enumerate(axes):
        ax.add_patch(plt.Rectangle((-0.5, -0.5), width, height, fill=False, color='grey',
                                   label='image border'))
        us, vs = [-0.5, width - 0.5], [-0.5, height - 0.5]
        for marker, colour in enumerate(MARKER_COLOURS):
            u = run.features[:, 3 * marker + side] if len(run.features) else np.zeros(0)
            v = run.features[:, 3 * marker + 2] if len(run.features) else np.zeros(0)
            us += list(u)
            vs += list(v)
            ax.plot(u, v, color=colour, lw=0.6, alpha=0.4, zorder=1)
            if measured.any():
                ax.scatter(u[measured], v[measured], s=8, color=colour, zorder=2,
                           label=f'marker {marker + 1} measured')
            if (~measured).any():
                ax.scatter(u[~measured], v[~measured], s=14, marker='x', color=colour,
                           zorder=2, label=f'marker {marker + 1} estimated / blended')
            if target_features is not None:
                ax.scatter(target_features[3 * marker + side], target_features[3 * marker + 2],
                           s=150, marker='*', color=colour, edgecolor='black', zorder=3,
                           label=f'marker {marker + 1} target')
        # Estimated features out of view are drawn too: the axes hold every point.
        pad_u, pad_v = 0.05 * (max(us) - min(us)), 0.05 * (max(vs) - min(vs))
        ax.set_xlim(min(us) - pad_u, max(us) + pad_u)
        ax.set_ylim(max(vs) + pad_v, min(vs) - pad_v)
        ax.set_aspect('equal')
        ax.set_xlabel('u [px]')
        ax.set_ylabel('v [px]')
        ax.set_title(('left' if side == 0 else 'right') + ' image')
        ax.grid(alpha=0.3)
    axes[1].legend(loc='center left', bbox_to_anchor=(1.02, 0.5), fontsize=8)
    fig.suptitle(_title(run, 'image-plane trajectories'))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def feature_timeline(run: 'RunData', path: str | Path) -> None:
    """Plot per frame whether features were measured, blended or estimated."""
    fig, ax = plt.subplots(figsize=(10, 2.2))
    levels = {'estimated': 0, 'blending': 1, 'measured': 2}
    t = np.asarray(run.mode_t) - (run.t[0] if len(run.t) else 0.0)
    for mode, colour in MODE_COLOURS.items():
        sel = np.array([m == mode for m in run.modes], dtype=bool)
        if sel.any():
            ax.scatter(t[sel], np.full(sel.sum(), levels[mode]), color=colour, s=12, label=mode)
    ax.set_yticks(list(levels.values()), list(levels.keys()))
    ax.set_ylim(-0.5, 2.5)
    ax.set_xlabel('sim time [s]')
    ax.grid(alpha=0.3)
    ax.set_title(_title(run, 'feature source per stereo frame'))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def error_vs_time(run: 'RunData', path: str | Path) -> None:
    """Plot the position and tool-axis error norms, log axis, with the transient inset."""
    from .metrics import axis_angle_deg
    t = run.t - run.t[0]
    errors = (np.linalg.norm(run.position - run.target[:3, 3], axis=1) * 1e3,
              axis_angle_deg(run.rotation, run.target[:3, :3]))
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8))
    for ax, error, what, unit in zip(axes, errors, ('position error', 'tool-axis error'),
                                     ('mm', 'deg')):
        floor = max(float(np.min(error[error > 0])) if np.any(error > 0) else 1e-6, 1e-6)
        ax.semilogy(t, np.maximum(error, floor), color='tab:blue')
        ax.set_xlabel('sim time [s]')
        ax.set_ylabel(f'{what} [{unit}] (log)')
        ax.grid(alpha=0.3, which='both')
        # The approach (metres, in the first tenth of a second) hides the overshoot on a
        # linear axis: the inset starts once the error is within 5 % of its start value.
        near = np.flatnonzero(error <= 0.05 * error[0])
        start = t[near[0]] if len(near) else t[0]
        window = (t >= start) & (t <= start + TRANSIENT_S)
        peak = int(np.argmax(np.where(t >= start, error, -np.inf)))
        ax.set_title(f'{what}: final {error[-1]:.3g} {unit}; largest after first within '
                     f'5 %: {error[peak]:.3g} {unit} at {t[peak]:.3f} s', fontsize=9)
        inset = ax.inset_axes([0.5, 0.5, 0.47, 0.42])
        inset.plot(t[window], error[window], color='tab:blue')
        inset.set_title(f'{start:.3f}-{start + TRANSIENT_S:.3f} s, linear [{unit}]',
                        fontsize=8)
        inset.tick_params(labelsize=7)
        inset.grid(alpha=0.3)
    fig.suptitle(_title(run, 'error norms against time'))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def feature_error(run: 'RunData', path: str | Path, target_features: ArrayLike | None) -> None:
    """Plot each marker's image error |p_I - p_bar| (px, both images) against time."""
    fig, ax = plt.subplots(figsize=(10, 4))
    t = np.asarray(run.feature_t) - (run.t[0] if len(run.t) else 0.0)
    modes = _modes_at(run, run.feature_t)
    for marker, colour in enumerate(MARKER_COLOURS):
        cols = slice(3 * marker, 3 * marker + 3)
        error = np.linalg.norm(run.features[:, cols] - target_features[cols], axis=1) \
            if len(run.features) else np.zeros(0)
        ax.semilogy(t, np.maximum(error, 1e-4), color=colour, lw=1,
                    label=f'marker {marker + 1}')
        for mode, mode_colour in MODE_COLOURS.items():
            sel = np.array([m == mode for m in modes], dtype=bool)
            if sel.any() and mode != 'measured':
                ax.scatter(t[sel], np.maximum(error[sel], 1e-4), s=10, color=mode_colour,
                           zorder=3, label=f'{mode} (marker {marker + 1})')
    ax.set_xlabel('sim time [s]')
    ax.set_ylabel('|p_I - p_bar| over (u_l, u_r, v) [px] (log)')
    ax.grid(alpha=0.3, which='both')
    ax.legend(fontsize=8, loc='upper right')
    ax.set_title(_title(run, 'feature error against time'))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def joints(series: Sequence[ArrayLike], limits: Sequence[ArrayLike], path: str | Path,
           title: str = '') -> None:
    """
    Plot joint angles, speeds and torques against time with their limits.

    ``series``: (t, q, qd, tau_t, tau) of :func:`.analysis.load_joints`: t (N,) with q, qd
    (N, 6) (the joint states), tau_t (M,) with tau (M, 6) (the torques); ``limits``:
    (q_min, q_max, qd_max, tau_max), six values each.
    """
    t, q, qd, tau_t, tau = series
    q_min, q_max, qd_max, tau_max = (np.asarray(v, dtype=float) for v in limits)
    fig, axes = plt.subplots(3, 6, figsize=(16, 7.5), sharex=True)
    for i in range(6):
        for row, (values, low, high, label) in enumerate((
                (np.degrees(q[:, i]), np.degrees(q_min[i]), np.degrees(q_max[i]), 'q [deg]'),
                (np.degrees(qd[:, i]), -np.degrees(qd_max[i]), np.degrees(qd_max[i]),
                 'qdot [deg/s]'),
                (tau[:, i] if len(tau) else np.zeros(0), -tau_max[i], tau_max[i],
                 'torque [N m]'))):
            ax = axes[row, i]
            ax.plot(t if row < 2 else tau_t, values, color='tab:blue', lw=0.8)
            for limit in (low, high):
                ax.axhline(limit, color='tab:red', ls='--', lw=0.8)
            ax.grid(alpha=0.3)
            if row and len(values):
                # Spikes of many times the limit would flatten the rest: the axis shows
                # three times the limit, the peak is written.
                peak = float(np.max(np.abs(values)))
                ax.set_ylim(3.0 * low, 3.0 * high)
                ax.text(0.98, 0.95, f'peak {peak:.3g}', transform=ax.transAxes, ha='right',
                        va='top', fontsize=7, color='tab:red' if peak > high else 'black')
            if i == 0:
                ax.set_ylabel(label)
            if row == 0:
                ax.set_title(f'joint {i + 1}')
            if row == 2:
                ax.set_xlabel('sim time [s]')
    fig.suptitle((title + ': ' if title else '') + 'joints against their limits (red)')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def _modes_at(run, times):
    """Return the mode of the feature status at each time (the latest at or before it)."""
    if not len(run.modes):
        return ['measured'] * len(times)
    idx = np.searchsorted(run.mode_t, times, side='right') - 1
    return [run.modes[max(i, 0)] for i in idx]


def title_of(run: 'RunData') -> str:
    """Return the run's name for figure titles: the scenario's name or number."""
    return run.params.get('scenario_name') or f"scenario {run.params.get('scenario', '?')}"


def _title(run, what):
    return f'{title_of(run)}: {what}'


def write_all(run: 'RunData', out_dir: Path, target_features: ArrayLike | None = None
              ) -> dict[str, Path]:
    """Write every figure of a run into ``out_dir``; return their paths."""
    paths = {
        'pose_vs_time': out_dir / 'pose_vs_time.png',
        'trajectory_3d': out_dir / 'trajectory_3d.png',
        'image_plane': out_dir / 'image_plane.png',
        'feature_timeline': out_dir / 'feature_timeline.png',
        'error_vs_time': out_dir / 'error_vs_time.png',
    }
    pose_vs_time(run, paths['pose_vs_time'])
    trajectory_3d(run, paths['trajectory_3d'])
    image_plane(run, paths['image_plane'], target_features)
    feature_timeline(run, paths['feature_timeline'])
    error_vs_time(run, paths['error_vs_time'])
    if target_features is not None and len(run.features):
        paths['feature_error'] = out_dir / 'feature_error.png'
        feature_error(run, paths['feature_error'], target_features)
    return paths
