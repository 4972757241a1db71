"""The tool as data: one source for the model, the simulator and the detector; its page."""

from pathlib import Path

from ibvs_analysis import tool_figure
from ibvs_model import IRB4600, RobotParams
from ibvs_model.mass_model import tool_shapes
from ibvs_model.tool import TOOL, Tool
from ibvs_model.urdf import robot_urdf
from ibvs_vision.detector.config import DetectorConfig
import numpy as np
import pytest

PAGE = Path(__file__).resolve().parents[4] / 'docs' / 'tool.md'


def test_the_model_the_simulator_and_the_detector_read_the_tools_numbers():
    assert RobotParams().L_tool == TOOL.length_m
    np.testing.assert_allclose(IRB4600.fiducials_E,
                               [[0.0, 0.0, 0.0], [0.0, 0.0, TOOL.length_m / 2.0]])
    cfg = DetectorConfig()
    assert cfg.marker_radius_m == TOOL.marker_radius_m
    assert tuple(map(tuple, cfg.marker_rgb)) == TOOL.marker_rgb
    shapes = tool_shapes(IRB4600)
    assert shapes['screwdriver'][0].size == (TOOL.shaft_radius_m, TOOL.length_m)
    assert [s[0].size for k, s in shapes.items() if k != 'screwdriver'] == \
        [(TOOL.marker_radius_m,)] * 2
    urdf = robot_urdf()
    for rgb in TOOL.marker_rgb:  # the simulator's materials
        assert ' '.join(repr(c / 255.0) for c in rgb) + ' 1.0' in urdf
    assert ' '.join(repr(c) for c in TOOL.shaft_rgba) in urdf
    scale = repr(TOOL.marker_radius_m)
    assert f'scale="{scale} {scale} {scale}"' in urdf


def test_the_facts_are_the_tools_and_the_detectors():
    f = tool_figure.facts()
    assert (f['radius_mm'], f['spacing_mm'], f['gap_mm'], f['length_mm'],
            f['shaft_diameter_mm']) == (25.0, 63.5, 13.5, 127.0, 4.0)
    assert [c['rgb'] for c in f['colours']] == list(TOOL.marker_rgb)
    assert [c['dominant'] for c in f['colours']] == ['R', 'B']
    assert f['radius_range_mm'] == (17.5, 32.5) and f['hough_px'] == (2, 40)
    # the darkest brightness accepted: a darker one fails, it passes
    for c in f['colours']:
        design = np.asarray(c['rgb'])
        assert tool_figure.passes(design * c['darkest'], design, DetectorConfig())
        assert not tool_figure.passes(design * (c['darkest'] - 0.01), design, DetectorConfig())
    # a hue next to the design's fails the hue-selective test: orange is not marker 1's red
    assert not tool_figure.passes((255, 128, 0), TOOL.marker_rgb[0], DetectorConfig())


def test_the_page_states_the_numbers_the_code_uses():
    text = PAGE.read_text()
    f = tool_figure.facts()
    lo, hi = f['radius_range_mm']
    near, far = f['depth_range_m']
    for words in (f"radius {f['radius_mm']:g} mm", f"{f['spacing_mm']:g} mm between the centres",
                  f"{f['gap_mm']:g} mm between the spheres",
                  f"\u00d8 {f['shaft_diameter_mm']:g} mm",
                  f"{f['length_mm']:g} mm (L_tool)", f'{lo:g}-{hi:g} mm',
                  f"image radius {f['hough_px'][0]}-{f['hough_px'][1]} px",
                  f'{near:.2f}-{far:.1f} m', f">= {f['min_colour_score']:g}",
                  f"within {f['radius_tolerance'] * 100:g} %", f"within {f['min_roundness']:g}",
                  f"{f['rod_radius_mm']:g} mm of radius",
                  f"within {f['epipolar_tolerance_px']:g} px", 'tool.png',
                  'python -m ibvs_analysis.tool_figure docs/tool.png'):
        assert words in text, words
    for c in f['colours']:
        assert f"sRGB {c['rgb']}" in text
        assert f"{c['gamma']:.2f} max" in text
        assert f"{c['darkest'] * 100:g} % of" in text


def test_the_figure_is_drawn_by_its_command(tmp_path, capsys):
    path = tmp_path / 'tool.png'
    assert tool_figure.main([str(path)]) == 0
    assert path.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert f'wrote {path}' in capsys.readouterr().out


def test_a_tool_is_frozen():
    with pytest.raises(AttributeError):
        TOOL.marker_radius_m = 0.03
    assert Tool() == TOOL
