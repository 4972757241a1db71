"""
What the camera sees of the tool: fiducial size and colours, shared by simulator and detector.

The paper specifies two circular fiducials (section 2.2) but not their size or colour.
Spheres project to circles from every viewpoint (discs do not). A radius of 25 mm is
about 8.5 px at the target (2.0 m from the camera at HD720, f_u ~ 685 px), enough for the
Hough transform. Two saturated, distinct colours tell marker 1 (P1, flange centre) from
marker 2 (P2, L_tool / 2 along the tool); the robot and the scene avoid both hues.
"""

#: Radius of each spherical fiducial, m.
MARKER_RADIUS_M = 0.025

#: RGB colours (0-255) of marker 1 (P1) and marker 2 (P2): red and blue.
MARKER_RGB = ((220, 30, 30), (30, 70, 220))
