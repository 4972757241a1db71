"""
"Converged": the one definition, with the tolerances each use of the word needs.

A run, a study, the law table and the report each ask whether the tool reached the target,
but not the same question; each question is a named :class:`Convergence` here, and its
docstring says why its tolerances are what they are:

- :data:`HOLD`: the runner's early stop (``converge_hold_s``), 0.1 mm and 0.01 deg held.
- :data:`AT_END`: a run's ``converged`` flag at its time limit, 1 mm (position only).
- :data:`ACCEPTANCE`: issue 6's acceptance, 1 mm and 0.1 deg at the end: a study run's
  success and the report's "scenario 1 final pose" verdict.
- :data:`LAW_TABLE`: "converged" in the servo-law table, 1 mm and 0.5 deg, 1 mm reached.
- :data:`REACHED`: the metric ``time_to_1mm_s``, the first time within 1 mm.
"""

from collections.abc import Mapping
from dataclasses import dataclass
import math
from typing import Any

from numpy.typing import ArrayLike


@dataclass(frozen=True)
class Convergence:
    """
    Within ``position_m`` (m) of the target position and ``axis_deg`` (deg) of its tool axis.

    ``axis_deg`` = inf: position only.
    """

    position_m: float
    axis_deg: float = math.inf

    def within(self, position_error_m: ArrayLike, axis_error_deg: ArrayLike = 0.0) -> Any:
        """
        Return whether the errors are within the tolerances (elementwise for arrays).

        NaN (no pose yet) is not within.
        """
        return (position_error_m <= self.position_m) & (axis_error_deg <= self.axis_deg)

    def final(self, metrics: Mapping[str, Any]) -> bool:
        """Return whether a run's metrics end within the tolerances (missing: not within)."""
        return bool(self.within(metrics.get('final_position_error_m', math.inf),
                                metrics.get('final_tool_axis_error_deg', math.inf)))


#: The runner stops a run early (``converge_hold_s``) once the tool has stayed this close
#: for that long (sim time): ten times tighter than :data:`ACCEPTANCE` in position and in
#: angle, so that a run cut short has settled well inside what any later check asks.
HOLD = Convergence(1e-4, 0.01)
#: A run that reaches its time limit reports ``converged`` when its last tool position is
#: within 1 mm: the runner's quick answer (``ibvs run``'s exit message); the tool axis is
#: left to the metrics.
AT_END = Convergence(1e-3)
#: Issue 6's acceptance of a reproduction: the final pose within 1 mm and 0.1 deg, what the
#: paper's "exact (IBVS)" final pose is checked against. A study run succeeds with it.
ACCEPTANCE = Convergence(1e-3, 0.1)
#: The servo-law table (:mod:`ibvs_experiments.laws_report`): converged when 1 mm was reached
#: and the run ended within 1 mm and 0.5 deg. Not :data:`ACCEPTANCE`: the table compares
#: servo laws (which of them get there at all), it does not accept a reproduction, and its
#: published "converged" column was made with 0.5 deg.
LAW_TABLE = Convergence(1e-3, 0.5)
#: ``time_to_1mm_s`` (:mod:`ibvs_experiments.analysis`): the first time the position error is
#: within 1 mm, the paper's "1 mm" milestone.
REACHED = Convergence(1e-3)
