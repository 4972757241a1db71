"""
Where the fiducials appear in a rendered stereo pair.

Colour masks, image moments, and the exact centre of a sphere's image. Used by the tests
and the benchmark to check the renderer against the pinhole model (eq. 16-22); the detector
of the stack is ibvs_vision's Hough.

A sphere projects to an ellipse (a circle only on the optical axis). Its centre is not the
projection of the sphere's centre: the tangent cone of half-angle alpha = asin(r / d) cuts
the image plane in an ellipse stretched away from the principal point, whose centre lies
about f alpha^2 tan(theta) / cos^2(theta) further out (theta: angle off the optical axis),
0.1 to 0.3 px for the 25 mm markers at 2 m. :func:`sphere_image_centre` gives it exactly.
"""

from collections.abc import Sequence
from typing import TYPE_CHECKING

from ibvs_model.scene import MARKER_RGB
import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from ibvs_model.camera import StereoCamera

#: A pixel belongs to a marker when its dominant channel (that of the marker's colour)
#: exceeds both others by this factor and is at least MIN_LEVEL.
DOMINANCE = 1.8
MIN_LEVEL = 40


def colour_masks(image: ArrayLike, colours: Sequence[Sequence[int]] = MARKER_RGB
                 ) -> list[NDArray[np.bool_]]:
    """
    Return one boolean mask (H, W) per marker colour: pixels of that colour's hue.

    A colour is identified by its dominant channel (red for marker 1, blue for marker 2);
    shading scales all channels alike, so the test holds on the dark side of a sphere too.
    """
    img = np.asarray(image, dtype=np.int32)
    masks = []
    for rgb in colours:
        c = int(np.argmax(rgb))
        others = [i for i in range(3) if i != c]
        main = img[:, :, c]
        mask = main >= MIN_LEVEL
        for o in others:
            mask &= main * 10 > img[:, :, o] * int(DOMINANCE * 10)
        masks.append(mask)
    return masks


def mask_centre(mask: ArrayLike) -> tuple[float, float, int] | None:
    """Return (u, v, pixel count) of a mask by its first image moments; None if empty."""
    v, u = np.nonzero(mask)
    if u.size == 0:
        return None
    return float(u.mean()), float(v.mean()), int(u.size)


def marker_centres(left: ArrayLike, right: ArrayLike,
                   colours: Sequence[Sequence[int]] = MARKER_RGB
                   ) -> tuple[NDArray[np.float64], NDArray[np.int_]]:
    """
    Return (features (2, 3) as rows (u_l, u_r, v), pixel counts (2, 2)) from a stereo pair.

    v is the mean of the two images' v. A marker missing from an image gives NaN.
    """
    features = np.full((len(colours), 3), np.nan)
    counts = np.zeros((len(colours), 2), dtype=int)
    for side, image in enumerate((left, right)):
        for k, mask in enumerate(colour_masks(image, colours)):
            centre = mask_centre(mask)
            if centre is None:
                continue
            features[k, side] = centre[0]
            features[k, 2] = centre[1] if side == 0 else 0.5 * (features[k, 2] + centre[1])
            counts[k, side] = centre[2]
    return features, counts


def sphere_image_centre(camera: 'StereoCamera', centre_O: ArrayLike, radius: float
                        ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """
    Return the centre (u_l, u_r, v) of the ellipses a sphere projects to, and their areas.

    The tangent cone from a lens centre to the sphere (centre c in lens coordinates) is
    m^T A m = 0 with A = c c^T - (|c|^2 - r^2) I, its inside m^T A m > 0. On the normalised
    image plane m = (x, y, 1) this is the ellipse (x - x0)^T (-A2) (x - x0) < f0 with
    A2 = A[:2, :2], x0 = -A2^-1 A[:2, 2] and f0 = A[2, 2] + A[:2, 2] . x0; its area is
    pi f0 / sqrt(det A2), times f_u f_v in pixels. v is the mean of the two images' v, as
    in :func:`marker_centres`. Returns ((3,), areas (2,) in px^2, left and right).
    """
    k = camera.intrinsics
    c_cam = camera.to_camera(np.asarray(centre_O, float)[None])[0]
    out = np.empty(3)
    areas = np.empty(2)
    v = []
    for side, shift in enumerate((k.baseline / 2.0, -k.baseline / 2.0)):
        c = c_cam + np.array([shift, 0.0, 0.0])  # lens at x = -b/2 (left) or +b/2 (right)
        conic = np.outer(c, c) - (c @ c - radius * radius) * np.eye(3)
        a2 = conic[:2, :2]
        x0 = -np.linalg.solve(a2, conic[:2, 2])
        f0 = conic[2, 2] + conic[:2, 2] @ x0
        areas[side] = np.pi * f0 / np.sqrt(np.linalg.det(a2)) * k.fu * k.fv
        out[side] = k.fu * x0[0] + k.cu
        v.append(k.fv * x0[1] + k.cv)
    out[2] = 0.5 * (v[0] + v[1])
    return out, areas
