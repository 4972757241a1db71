"""
Figures of one run, in the style of the paper's Figures 10-12, and more.

- ``pose_vs_time.png``: tool position (x, y, z) and tool axis a = z6 against time, with the
  targets (paper: blue response, red target);
- ``trajectory_3d.png``: the flange path with tool-axis arrows, start (circle), target (star)
  and the target axis (red arrow);
- ``image_plane.png``: both markers' paths in the left and right images, measured and
  estimated parts apart, targets and image borders;
- ``feature_timeline.png``: which frames were measured, blended or estimated.
"""

import matplotlib

matplotlib.use('Agg')

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

MODE_COLOURS = {'measured': 'tab:green', 'blending': 'tab:orange', 'estimated': 'tab:red'}


def pose_vs_time(run, path):
    """Plot position and tool axis against time with their targets (Figures 10-12)."""
    fig, axes = plt.subplots(2, 3, figsize=(13, 6.5), sharex=True)
    t = run.t - run.t[0]
    for i, name in enumerate('xyz'):
        ax = axes[0, i]
        ax.plot(t, run.position[:, i], color='tab:blue', label='tool')
        ax.axhline(run.target[i, 3], color='tab:red', ls='--', label='target')
        ax.set_ylabel(f'{name} [m]')
        ax.grid(alpha=0.3)
        ax = axes[1, i]
        ax.plot(t, run.rotation[:, i, 2], color='tab:blue', label='tool')
        ax.axhline(run.target[i, 2], color='tab:red', ls='--', label='target')
        ax.set_ylabel(f'a_{name} (tool axis z6)')
        ax.set_xlabel('sim time [s]')
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc='best')
    fig.suptitle(_title(run, 'tool pose against time'))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def trajectory_3d(run, path, arrows=12):
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


def image_plane(run, path, target_features=None):
    """Plot both markers' image paths in the left and right images."""
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8))
    width, height = 1280, 720
    if run.camera is not None:
        width, height = run.camera.intrinsics.width, run.camera.intrinsics.height
    modes = _modes_at(run, run.feature_t)
    for side, ax in enumerate(axes):
        ax.add_patch(plt.Rectangle((-0.5, -0.5), width, height, fill=False, color='grey'))
        for marker, style in ((0, 'o'), (1, 's')):
            u = run.features[:, 3 * marker + side] if len(run.features) else np.zeros(0)
            v = run.features[:, 3 * marker + 2] if len(run.features) else np.zeros(0)
            ax.plot(u, v, color='lightgrey', lw=0.8, zorder=1)
            for mode, colour in MODE_COLOURS.items():
                sel = np.array([m == mode for m in modes], dtype=bool)
                if sel.any():
                    ax.scatter(u[sel], v[sel], s=6, color=colour, marker=style, zorder=2,
                               label=f'marker {marker + 1} {mode}')
            if target_features is not None:
                ax.scatter(target_features[3 * marker + side], target_features[3 * marker + 2],
                           s=150, marker='*', color='black', zorder=3,
                           label=f'marker {marker + 1} target')
        ax.set_xlim(-0.05 * width, 1.05 * width)
        ax.set_ylim(1.05 * height, -0.05 * height)
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


def feature_timeline(run, path):
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


def _modes_at(run, times):
    """Return the mode of the feature status at each time (the latest at or before it)."""
    if not len(run.modes):
        return ['measured'] * len(times)
    idx = np.searchsorted(run.mode_t, times, side='right') - 1
    return [run.modes[max(i, 0)] for i in idx]


def _title(run, what):
    name = run.params.get('scenario_name') or f"scenario {run.params.get('scenario', '?')}"
    return f'{name}: {what}'


def write_all(run, out_dir, target_features=None):
    """Write every figure of a run into ``out_dir``; return their paths."""
    paths = {
        'pose_vs_time': out_dir / 'pose_vs_time.png',
        'trajectory_3d': out_dir / 'trajectory_3d.png',
        'image_plane': out_dir / 'image_plane.png',
        'feature_timeline': out_dir / 'feature_timeline.png',
    }
    pose_vs_time(run, paths['pose_vs_time'])
    trajectory_3d(run, paths['trajectory_3d'])
    image_plane(run, paths['image_plane'], target_features)
    feature_timeline(run, paths['feature_timeline'])
    return paths
