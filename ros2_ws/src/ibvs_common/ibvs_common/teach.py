"""
The taught pair: how a stereo pair of the tool held at the target is made from frames.

One rule for whoever makes one: the simulator for its own teach pair
(:meth:`ibvs_sim.simulator.Simulator._teach`) and ``ibvs teach`` on a cell
(:mod:`ibvs_experiments.teach`). ``teach_frames`` consecutive 8-bit pairs of the still
tool are averaged pixel by pixel and channel by channel and rounded to 8 bits
(:class:`FrameMean`): each frame's image noise is independent, the scene is not, so the
features measured on the mean carry 1 / sqrt(teach_frames) of one frame's noise (and the
rounding's 1 / sqrt(12) of a level). No ROS here.
"""

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from .params import Param

#: Most frames a taught pair may average.
MAX_TEACH_FRAMES = 100
TEACH_FRAMES = Param(
    'teach_frames', 1, 'stereo frames of the tool held at the target that the teach pair '
    "averages, pixel by pixel (each its own image noise; target_features_source 'taught'): "
    'the features of the taught target then carry 1 / sqrt(teach_frames) of one '
    "frame's noise; 1: one frame", '-', low=1, high=MAX_TEACH_FRAMES)


class FrameMean:
    """
    The pixelwise mean of stereo pairs, rounded to 8 bits (module docstring).

    :meth:`add` each pair (a sequence of uint8 images, the same shapes every time);
    :meth:`mean` returns the pair of rounded means. The sums are float64, exact for up to
    2**45 frames of 8-bit pixels, so the mean does not depend on the order of the frames.
    """

    def __init__(self) -> None:
        """Start with no frame."""
        self._sums = None
        self.count = 0

    def add(self, pair: Sequence[NDArray[np.uint8]]) -> None:
        """Add one pair; ValueError for images of another shape than the first pair's."""
        images = [np.asarray(image) for image in pair]
        if self._sums is None:
            self._sums = [np.zeros(image.shape, np.float64) for image in images]
        shapes = [s.shape for s in self._sums]
        if [image.shape for image in images] != shapes:
            raise ValueError(f'images of shapes {[i.shape for i in images]}, the first pair '
                             f'had {shapes}')
        for total, image in zip(self._sums, images):
            total += image
        self.count += 1

    def mean(self) -> tuple[NDArray[np.uint8], ...]:
        """Return the mean pair, rounded to 8 bits; ValueError before any frame."""
        if not self.count:
            raise ValueError('no frame to average')
        return tuple(np.rint(total / self.count).astype(np.uint8) for total in self._sums)
