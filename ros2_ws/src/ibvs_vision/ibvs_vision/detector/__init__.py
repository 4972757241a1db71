"""
Hough detector of the two spherical fiducials in a rectified stereo pair (section 2.2, eq. 2-3).

Per image and per marker colour (:data:`ibvs_model.scene.MARKER_RGB`: marker 1 red,
marker 2 blue):

1. **Colour channels.** s = C_d - max(other two channels), C_d the marker's dominant
   channel (red: R - max(G, B)); grey, white and black give s ~ 0. The hue-selective
   s_sel = C_d - gamma max(others), gamma = clip(C_d / (2 max(others)), 1, 3) of the
   marker colour, is also 0 for nearby hues (orange for red). Both scale with brightness.
2. **Hough transform** (section 2.2, Figure 2): ``cv2.HoughCircles`` (HOUGH_GRADIENT) on
   s_sel gives circle candidates (centre on a 0.5 px grid, radius). It runs on the whole
   image, restricted to the 8 x 8 blocks where the marker's hue is present (grown by the
   largest radius), which finds the same circles in a fraction of the time.
3. **Sub-pixel refinement.** Around each circle, the outer contour of the marker-hue pixels
   (s_sel above half of ``min_colour_score``) is the object, holes (highlights) filled. Its
   interior pixels count 1; each rim pixel p is unmixed as p = x * m + y * b (m the marker
   colour at any brightness, b the mean background colour just outside), so that its
   coverage 1 - y does not depend on the shading of the sphere. The centre is the area
   centroid of the coverage (image moments): the centre of the silhouette, free of the
   Hough grid. A candidate is rejected if it touches the image border, is too faint, or
   if its second moments or outline are not those of a disc (partly occluded), after
   taking out the radial stretch 1 / cos(theta) of a sphere seen off-axis. A thin rod in
   front of the marker (the tool's shaft, link 6's quill) cuts a notch into the outline;
   the notch is filled from the point-symmetric side of the ellipse before the centroid is
   taken (:func:`.coverage.symmetric_centre`; at the target pose this takes the vertical bias
   from 0.07-0.09 px to under 0.01 px, and the implied tool-axis error from 0.16 to 0.06 deg).
   Once both markers are paired, each centre is taken again without a band about the
   line through both markers in its image (:func:`.refine.axis_band_centre`): the rods
   lie on the tool axis, so they spoil a marker's outline at two opposite ends, a notch
   where a rod is in front, a darker background where a rod or the other marker is
   behind, and filling a notch from the opposite end copies that end's error. The band
   (the rods' image radius plus ``axis_band_px``) is point-symmetric about the centre, so
   what is left still has its centroid at the ellipse's centre (what it removes from
   marker 1's vertical bias and scenario 1's final error: docs/design.md §7).
4. **Stereo pairing** by the epipolar constraint of a rectified pair: same v within a
   tolerance, positive disparity u_l - u_r (ROS signs, docs/design.md §5: the left lens at
   x = -b/2 of {C}), and radii that agree with each other and with the depth given by the
   disparity (a sphere of radius R at depth Z = f_u b / d has an image radius
   f_u R / Z = R d / b).
5. **Perspective correction.** A sphere projects to an ellipse whose centre is not the
   projection of the sphere's centre: with the silhouette cone of a sphere of radius R
   at depth Z, the ellipse centre is c + (p - c) / (1 - (R / Z)^2) for the principal
   point c and the centre projection p (exact for a pinhole, derived from the cone's
   conic). At HD720 this is up to 0.2 px at the image edge for a marker 2 m away, so it
   is undone with Z from the disparity (intrinsics needed; skipped without them).

The result is p_I = [u_l1, u_r1, v1, u_l2, u_r2, v2] (eq. 2-3, 21-22), v the mean of the
left and right v, or a :class:`Reason` why not. Pure numpy/OpenCV, no ROS.

Every step is paid for, before it runs, from the pair's budget of estimated cost
(:mod:`.budget`): the search stops at the first step the rest cannot pay for, and the pair
gives Reason.OVER_BUDGET, so that no image, however noisy or crowded, holds the caller for
longer than it allows.

Modules: :mod:`.config` (tuning, reasons), :mod:`.colour` (step 1), :mod:`.stereo`
(steps 2 and 4, :class:`StereoDetector`), :mod:`.refine` (steps 3 and 5), :mod:`.coverage`
(step 3's coverage and notch-filled centre), :mod:`.budget` (the cost model).
"""

from .colour import colour_scores, ENCODINGS
from .config import DetectorConfig, MARKER_NAMES, Reason
from .refine import Blob, centre_to_silhouette, silhouette_to_centre
from .stereo import ImageDetections, StereoDetection, StereoDetector

__all__ = ['Blob', 'centre_to_silhouette', 'colour_scores', 'DetectorConfig', 'ENCODINGS',
           'ImageDetections', 'MARKER_NAMES', 'Reason', 'silhouette_to_centre',
           'StereoDetection', 'StereoDetector']
