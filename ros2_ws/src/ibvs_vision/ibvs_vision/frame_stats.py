"""
The feature node's timings and counts, as its /diagnostics shows them: pure, no ROS.

Rolling windows of the detector's wall time, CPU time and estimated cost, of each frame's
whole processing time, and the count of frames estimated per reason (docs/nodes.md).
"""

from collections import deque

import numpy as np

#: Frames whose times the means, medians and maxima cover.
TIMING_WINDOW = 200


class FrameStats:
    """
    The feature node's rolling timings and why frames were estimated.

    Each method takes one frame's numbers and returns the /diagnostics values they change,
    by name, in the order the node has always published them.
    """

    def __init__(self, budget_ms: float, window: int = TIMING_WINDOW) -> None:
        """Compare the detector's CPU time with ``budget_ms``; keep ``window`` frames."""
        self.budget_ms = budget_ms
        self._detection = {key: deque(maxlen=window) for key in ('wall', 'cpu', 'cost')}
        self._processing = deque(maxlen=window)
        self._estimated = {}

    def detection(self, wall_ms: float, cpu_ms: float, cost_ms: float) -> dict[str, object]:
        """
        Keep one detection's wall time, CPU time and estimated cost; return the values.

        The CPU time is the detecting thread's, what the detector took; the wall time also
        holds the waits for a core that other processes had. ``detection_within_budget``
        compares the largest CPU time with the budget.
        """
        kept = self._detection
        for key, value in (('wall', wall_ms), ('cpu', cpu_ms), ('cost', cost_ms)):
            kept[key].append(value)
        return {'detection_ms_last': wall_ms,
                'detection_ms_mean': float(np.mean(kept['wall'])),
                'detection_ms_max': float(max(kept['wall'])),
                'detection_cpu_ms_mean': float(np.mean(kept['cpu'])),
                'detection_cpu_ms_max': float(max(kept['cpu'])),
                'detection_cost_ms_max': float(max(kept['cost'])),
                'detection_within_budget': bool(max(kept['cpu']) <= self.budget_ms)}

    def processing(self, elapsed_ms: float) -> dict[str, float]:
        """Keep one frame's processing time; return the last, the median and the max."""
        self._processing.append(elapsed_ms)
        return {'processing_ms_last': elapsed_ms,
                'processing_ms_median': float(np.median(self._processing)),
                'processing_ms_max': float(max(self._processing))}

    def estimated(self, reason: str | None = None) -> dict[str, int]:
        """Count a frame estimated for ``reason`` (None: measured); return every count."""
        if reason is not None:
            self._estimated[reason] = self._estimated.get(reason, 0) + 1
        return {f'estimated_because[{key}]': n for key, n in self._estimated.items()}
