"""
The tool a cell needs, drawn with what the detector accepts: docs/tool.md's figure.

``python -m ibvs_analysis.tool_figure docs/tool.png`` (docs/tool.md). Every number comes from
the code that uses it: the tool (:data:`ibvs_model.tool.TOOL`; the fiducial points of the model,
:attr:`ibvs_model.robot.RobotParams.fiducials_E`) and the detector's defaults
(:class:`ibvs_vision.detector.config.DetectorConfig`; the colour scores of
:mod:`ibvs_vision.detector.colour`), gathered by :func:`facts`, which docs/tool.md's test
reads too.
"""

import argparse
from pathlib import Path
import sys
from typing import Any

from ibvs_model import default_camera, IRB4600
from ibvs_model.tool import TOOL
from ibvs_vision.detector.colour import MarkerColour, score_of
from ibvs_vision.detector.config import DetectorConfig
import numpy as np

#: The brightness factors the colour panel shows each marker colour at.
SHADES = (1.0, 0.5, 0.25, 0.12)


def passes(rgb: Any, design: Any, cfg: DetectorConfig) -> bool:
    """
    Return whether a marker seen as ``rgb`` passes the detector's colour tests.

    Its score s = C_d - max(others) (the dominant channel of the ``design`` colour) at least
    ``min_colour_score``, and its hue-selective score C_d - gamma max(others) at least half
    of it (ibvs_vision.detector: the disc's median, and its outline).
    """
    colour = MarkerColour.of(design)
    rgb = np.asarray(rgb, dtype=float)
    top = max(rgb[colour.others[0]], rgb[colour.others[1]])
    return bool(rgb[colour.d] - top >= cfg.min_colour_score
                and rgb[colour.d] - colour.gamma * top >= 0.5 * cfg.min_colour_score)


def facts(resolution: str = 'HD720') -> dict[str, Any]:
    """Return the numbers the figure and docs/tool.md give (mm, px, 0-255)."""
    cfg = DetectorConfig()
    fu = default_camera(resolution).intrinsics.fu
    radius_m = TOOL.marker_radius_m
    spacing_m = float(np.linalg.norm(np.subtract(*IRB4600.fiducials_E[::-1])))
    colours = []
    for rgb in TOOL.marker_rgb:
        colour = MarkerColour.of(rgb)
        colours.append({'rgb': tuple(int(c) for c in rgb), 'score': float(score_of(rgb)),
                        'gamma': float(colour.gamma), 'dominant': 'RGB'[colour.d],
                        # the least brightness (of 1 %, 2 %, ... 100 %) still accepted
                        'darkest': min(k / 100.0 for k in range(1, 101)
                                       if passes(np.asarray(rgb) * k / 100.0, rgb, cfg))})
    return {
        'radius_mm': round(radius_m * 1e3, 6),
        'spacing_mm': round(spacing_m * 1e3, 6),
        'gap_mm': round((spacing_m - 2.0 * radius_m) * 1e3, 6),
        'length_mm': round(TOOL.length_m * 1e3, 6),
        'shaft_diameter_mm': round(2.0 * TOOL.shaft_radius_m * 1e3, 6),
        'shaft_grey': TOOL.shaft_rgba[0],
        'colours': colours,
        'min_colour_score': cfg.min_colour_score,
        'radius_tolerance': cfg.radius_tolerance,
        'radius_range_mm': (round(radius_m * (1.0 - cfg.radius_tolerance) * 1e3, 6),
                            round(radius_m * (1.0 + cfg.radius_tolerance) * 1e3, 6)),
        'hough_px': (cfg.hough_min_radius_px, cfg.hough_max_radius_px),
        'resolution': resolution, 'fu_px': fu,
        'depth_range_m': (fu * radius_m / cfg.hough_max_radius_px,
                          fu * radius_m / cfg.hough_min_radius_px),
        'min_roundness': cfg.min_roundness,
        'rod_radius_mm': round(cfg.rod_radius_m * 1e3, 6),
        'epipolar_tolerance_px': cfg.epipolar_tolerance_px,
    }


def draw(path: Path) -> None:
    """Draw the tool and the detector's tolerances into ``path`` (PNG)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Rectangle

    f = facts()
    r, spacing, length = f['radius_mm'], f['spacing_mm'], f['length_mm']
    shaft = f['shaft_diameter_mm']
    fig, (ax, cx) = plt.subplots(1, 2, figsize=(13.0, 5.6),
                                 gridspec_kw={'width_ratios': [1.55, 1.0]})
    # -- the tool, to scale, in {E} (z: the tool axis, drawn to the right) ----------------
    ax.plot([0.0, 0.0], [-r - 8.0, r + 8.0], '--', color='0.45', linewidth=0.9, zorder=5)
    ax.text(-r - 3.0, 0.0, "the model's\nflange face:\n{E}, tool0", ha='right',
            va='center', fontsize=8, color='0.3')
    ax.add_patch(Rectangle((0.0, -shaft / 2.0), length, shaft,
                           facecolor=(f['shaft_grey'],) * 3, edgecolor='none', zorder=1))
    for k, centre in enumerate((0.0, spacing)):
        rgb = np.asarray(f['colours'][k]['rgb']) / 255.0
        ax.add_patch(Circle((centre, 0.0), r, facecolor=rgb, edgecolor='k', linewidth=0.6,
                            zorder=2))
        ax.plot(centre, 0.0, 'k+', markersize=8, zorder=3)
        ax.text(centre, -r - 4.0, f'marker {k + 1} (P{k + 1})', ha='center', va='top',
                fontsize=9)
    # {E}'s axes at P1
    ax.annotate('', xy=(22.0, 0.0), xytext=(0.0, 0.0),
                arrowprops={'arrowstyle': '->', 'color': 'k', 'lw': 1.2}, zorder=4)
    ax.text(22.0, -5.0, 'z', fontsize=9, zorder=4)

    def dimension(x0, x1, y, text, above=True):
        ax.annotate('', xy=(x1, y), xytext=(x0, y),
                    arrowprops={'arrowstyle': '<->', 'color': '0.2', 'lw': 0.8})
        ax.text(0.5 * (x0 + x1), y + (2.0 if above else -2.0), text, ha='center',
                va='bottom' if above else 'top', fontsize=9)

    dimension(0.0, spacing, r + 12.0, f'{spacing:g} mm between the centres (L_tool / 2)')
    dimension(0.0, length, r + 30.0, f'shaft {length:g} mm from P1 to the tip (L_tool)')
    dimension(spacing - r, spacing + r, -r - 18.0,
              f'sphere \u00d8 {2 * r:g} mm (radius {r:g} mm)', above=False)
    dimension(r, spacing - r, -r - 34.0, f"gap {f['gap_mm']:g} mm", above=False)
    ax.annotate(f'shaft \u00d8 {shaft:g} mm, dark grey', xy=(100.0, shaft / 2.0),
                xytext=(95.0, 16.0), fontsize=9,
                arrowprops={'arrowstyle': '-', 'color': '0.3', 'lw': 0.7})
    ax.text(-70.0, -r - 52.0,
            'P1, the centre of marker 1, is the origin of {E}: the model puts it at the\n'
            "flange centre (the paper's eq. 8); the simulated arm carries it on a thin\n"
            'quill. A real tool whose marker 1 sits in front of the flange needs the\n'
            "model's Lt lengthened by that distance (docs/tool.md).", fontsize=8, va='top',
            color='0.25')
    ax.set_xlim(-72.0, length + 12.0)
    ax.set_ylim(-r - 82.0, r + 46.0)
    ax.set_aspect('equal')
    ax.axis('off')
    ax.set_title('the tool, to scale (mm)', fontsize=11)
    # -- the colours, and how dark the detector still takes them --------------------------
    cx.set_xlim(0.0, len(SHADES) + 0.2)
    cx.set_ylim(-1.6, 2.2)
    cx.axis('off')
    cfg = DetectorConfig()
    for k, colour in enumerate(f['colours']):
        y = 1.0 - 1.25 * k
        cx.text(0.0, y + 0.62, f"marker {k + 1}: sRGB {colour['rgb']}, dominant "
                f"{colour['dominant']}, score {colour['score']:g}, gamma "
                f"{colour['gamma']:.2f}", fontsize=8.5)
        for j, shade in enumerate(SHADES):
            seen = np.asarray(colour['rgb']) * shade
            cx.add_patch(Rectangle((j + 0.05, y - 0.35), 0.85, 0.85,
                                   facecolor=seen / 255.0, edgecolor='k', linewidth=0.5))
            ok = passes(seen, colour['rgb'], cfg)
            cx.text(j + 0.475, y - 0.45, f"{shade:.0%}: {'accepted' if ok else 'too faint'}",
                    ha='center', va='top', fontsize=7.5)
    lo, hi = f['radius_range_mm']
    near, far = f['depth_range_m']
    cx.text(0.0, -1.05,
            f"accepted: C_d - max(others) >= {f['min_colour_score']:g} and "
            f"C_d - gamma max(others) >= {0.5 * f['min_colour_score']:g} (0-255), as imaged;\n"
            f"image radius {f['hough_px'][0]}-{f['hough_px'][1]} px ({near:.2f}-{far:.1f} m "
            f"at {f['resolution']}); radius within {f['radius_tolerance']:.0%} of the "
            f"disparity's ({lo:g}-{hi:g} mm);\nroundness >= {f['min_roundness']:g}; "
            f"both lenses' v within {f['epipolar_tolerance_px']:g} px",
            fontsize=7.5, va='top')
    cx.set_title("the colours at falling brightness, and the detector's tests", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=100, metadata={'Software': None})
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """``python -m ibvs_analysis.tool_figure PATH``: write the figure."""
    parser = argparse.ArgumentParser(prog='python -m ibvs_analysis.tool_figure',
                                     description=__doc__.strip().splitlines()[0])
    parser.add_argument('path', help='the PNG to write (docs/tool.png)')
    args = parser.parse_args(argv)
    path = Path(args.path)
    path.parent.mkdir(parents=True, exist_ok=True)
    draw(path)
    print(f'wrote {path}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
