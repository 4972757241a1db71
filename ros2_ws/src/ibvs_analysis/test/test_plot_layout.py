"""The figures' legends cover no curve: pose_vs_time.png's is outside its panels."""

from types import SimpleNamespace

from ibvs_analysis import plots
import matplotlib.pyplot as plt
import numpy as np


def test_pose_vs_time_legend_lies_outside_every_panel(tmp_path, monkeypatch):
    t = np.linspace(0.0, 1.0, 501)
    start, goal = np.array([1.0, 0.2, 1.0]), np.array([-1.0, 0.2, 0.3])
    y = 1.0 - np.exp(-t / 0.05)
    target = np.eye(4)
    target[:3, 3] = goal
    run = SimpleNamespace(t=t, position=start + np.outer(y, goal - start),
                          rotation=np.repeat(np.eye(3)[None], t.size, axis=0), target=target,
                          params={'scenario_name': 'layout'})
    figures = []
    monkeypatch.setattr(plots.plt, 'close', figures.append)  # keep the figure to read
    plots.pose_vs_time(run, tmp_path / 'pose_vs_time.png')
    (fig,) = figures
    assert (tmp_path / 'pose_vs_time.png').stat().st_size > 0
    renderer = fig.canvas.get_renderer()
    (legend,) = fig.legends
    assert [text.get_text() for text in legend.get_texts()] == ['tool', 'target']
    box = legend.get_window_extent(renderer)
    panels = [ax for ax in fig.axes if ax.get_label() != 'inset_axes']
    assert len(panels) >= 6
    for ax in panels:
        assert ax.get_legend() is None
        assert not box.overlaps(ax.get_window_extent(renderer)), ax.get_ylabel()
    monkeypatch.undo()
    plt.close(fig)
