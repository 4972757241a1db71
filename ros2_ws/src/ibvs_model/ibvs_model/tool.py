"""
The tool a cell needs, as data: the screwdriver and its two spherical fiducials (no ROS).

One place for the numbers: the model (the fiducial points P1, P2 of eq. 8-9,
:attr:`.robot.RobotParams.fiducials_E`, through ``L_tool``), the simulator (the URDF's
shaft and spheres, their colours: :mod:`.urdf`, :mod:`.mass_model`), the detector
(ibvs_vision.detector: the marker radius and colours it looks for) and the viewers read
:data:`TOOL`, under the names :mod:`.scene` and :mod:`.mass_model` give them.
docs/tool.md draws it with the detector's tolerances (``python -m
ibvs_analysis.tool_figure docs/tool.png``).

The paper fixes the tool's length (L_tool, Table 2) and where the two circular fiducials
sit on it (section 3.1: P1 = [0, 0, 0]{E}, the flange centre; P2 = [0, 0, L_tool / 2]{E},
on the tool axis), not their size or colour. Spheres project to circles from every
viewpoint (discs do not); 25 mm of radius is about 8.5 px at the target (2.0 m from the
camera at HD720, f_u ~ 685 px), enough for the Hough transform. Two saturated colours,
each with its own dominant channel, tell marker 1 from marker 2; the robot (light grey)
and the shaft (dark grey) have neither hue.
"""

from dataclasses import dataclass


@dataclass(frozen=True)
class Tool:
    """
    The screwdriver {E} carries and its two spherical fiducials (module docstring).

    Lengths in metres, in {E} (z: the tool axis); marker colours 0-255 sRGB. Where the
    spheres sit is the model's rule (:attr:`.robot.RobotParams.fiducials_E`: P1 at the
    flange centre, P2 at ``length_m`` / 2 along z).
    """

    #: L_tool (paper Table 2): the shaft from the flange centre P1 along z to its tip.
    length_m: float = 0.127
    #: Radius of each sphere.
    marker_radius_m: float = 0.025
    #: Colours of marker 1 (centre P1) and marker 2 (centre P2): red and blue.
    marker_rgb: tuple = ((220, 30, 30), (30, 70, 220))
    #: Radius of the shaft (4 mm across), and its colour as a URDF material's rgba (0-1):
    #: dark grey.
    shaft_radius_m: float = 0.002
    shaft_rgba: tuple = (0.35, 0.35, 0.35, 1.0)


#: The tool of the paper's cell, simulated and to be built (docs/tool.md).
TOOL = Tool()
