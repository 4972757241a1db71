"""Hough detector of the two fiducials in stereo images, and the feature node (eq. 2-3, 46)."""
