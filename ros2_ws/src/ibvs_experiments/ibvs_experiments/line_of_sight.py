"""
Whether the camera sees a target's markers: the target rendered and detected.

The workspace sampler's margins (:mod:`ibvs_model.task_sampler`) are geometric: both
markers in both images, apart, clear of the wrist's back. What hides a marker behind the
arm's own links they do not see. :class:`RenderedLineOfSight` is workspace-3's check: the
arm at the target's joint angles in the simulator's world (:class:`ibvs_sim.world.World`,
the links' solids as ``sim_node`` draws them), both lenses rendered as the simulator
renders them, and the detector run on the pair as the feature node runs it on a whole pair
(:class:`ibvs_vision.detector.StereoDetector`): a target is seen when both markers are
measured in both images. It is exact where a bound on the links (the capsules of
:mod:`ibvs_model.capsules`, conservative by design) would also refuse targets the camera
sees.
"""

from types import TracebackType

from ibvs_model import default_model
import numpy as np
from numpy.typing import ArrayLike

#: The resolution the check renders at: the graph's (``vsbench_tasks.GRAPH_RESOLUTION``).
RESOLUTION = 'HD720'


class RenderedLineOfSight:
    """
    The line-of-sight check of workspace-3: ``check(q)`` says why the markers are not seen.

    A context manager: the world's physics client and renderer are closed on exit.

    Parameters
    ----------
    resolution : str
        The camera's resolution (``default_model``'s names).

    """

    def __init__(self, resolution: str = RESOLUTION) -> None:
        """Open the world and the detector of the default cell at ``resolution``."""
        from ibvs_sim.world import World
        from ibvs_vision.detector import StereoDetector
        self.model = default_model(resolution)
        self.detector = StereoDetector(self.model.camera.intrinsics)
        self.world = World()
        self.checked = 0

    def __call__(self, q: ArrayLike) -> str | None:
        """Return why the markers are not both measured in both images at ``q``, or None."""
        self.checked += 1
        self.world.reset(np.asarray(q, dtype=float))
        detection = self.detector.detect(*self.world.render_stereo(self.model.camera))
        if detection.ok:
            return None
        return f'{detection.reason.value} in the rendered target'

    def close(self) -> None:
        """Close the world."""
        self.world.close()

    def __enter__(self) -> 'RenderedLineOfSight':
        """Return the check."""
        return self

    def __exit__(self, kind: type | None, value: BaseException | None,
                 traceback: TracebackType | None) -> None:
        """Close the world."""
        self.close()
