"""
Wall time spent per section of a node's work, for ``make bench``; plain Python, no rclpy.

A node times its hot sections (``with stopwatch.section('render'): ...``) and tells the
stopwatch how far in sim time its work has reached (:meth:`Stopwatch.reached`). Its
:class:`ibvs_common.diagnostics.Diagnostics` publishes the totals on /diagnostics as
``wall[<section>]_s`` and ``count[<section>]``, with ``profiled_sim_time_s``, so that
whoever records the run can tell the cost of each section per simulated second. Timing
costs two ``perf_counter`` calls per section; nothing here changes what a node computes.
"""

from collections import defaultdict
from collections.abc import Iterator
from contextlib import contextmanager
import time

#: Key prefixes on /diagnostics (ibvs_experiments.bench reads them back).
WALL_KEY = 'wall[{}]_s'
COUNT_KEY = 'count[{}]'
SIM_TIME_KEY = 'profiled_sim_time_s'


class Stopwatch:
    """Total wall time and number of passes of named sections, and the sim time reached."""

    def __init__(self) -> None:
        """Start with nothing timed."""
        self.totals = defaultdict(float)
        self.counts = defaultdict(int)
        self.sim_ns = 0

    @contextmanager
    def section(self, name: str) -> Iterator[None]:
        """Time the body of the ``with`` statement as one pass of section ``name``."""
        start = time.perf_counter()
        try:
            yield
        finally:
            self.add(name, time.perf_counter() - start)

    def add(self, name: str, seconds: float) -> None:
        """Add one pass of ``seconds`` to section ``name``."""
        self.totals[name] += seconds
        self.counts[name] += 1

    def reached(self, t_ns: int) -> None:
        """Note that the node's work has reached sim time ``t_ns`` (never goes back)."""
        self.sim_ns = max(self.sim_ns, int(t_ns))

    def values(self) -> dict[str, str]:
        """Return the totals as /diagnostics key/value pairs (empty before any section)."""
        if not self.totals:
            return {}
        out = {SIM_TIME_KEY: f'{self.sim_ns * 1e-9:.9f}'}
        for name in sorted(self.totals):
            out[WALL_KEY.format(name)] = f'{self.totals[name]:.6f}'
            out[COUNT_KEY.format(name)] = str(self.counts[name])
        return out
