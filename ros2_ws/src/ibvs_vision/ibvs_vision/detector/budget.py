"""
The detector's time budget per stereo pair: counted work, priced by a measured cost model.

A noisy, textured or crowded image gives the Hough transform tens of thousands of edge
pixels and thousands of circle centres: a full-image search of one noisy HD720 pair takes
12-30 s, while the simulator, the controllers and their heartbeats wait. The detector
therefore prices each step before it runs it (:class:`WorkBudget`) and stops the pair, with
:attr:`Reason.OVER_BUDGET <.config.Reason.OVER_BUDGET>`, at the first step the rest of the
budget cannot pay for.

The price is not the wall clock: a decision taken on the wall clock would depend on the
machine's load, and the same run twice would not give the same numbers (docs/design.md §4).
It is the work counted (pixels of each pass, edge pixels of each Hough transform, pixels
of each refined window) times what that work cost on one core of this repository's 2-core
machine (:data:`COSTS`, measured by ``python -m ibvs_vision.bench --calibrate``, which
prints them again): an estimate of the wall time of one core, the same on every machine.
The wall time itself is measured by the feature node and reported beside it.

The Hough transform's cost grows faster than its edge pixels: OpenCV's HOUGH_GRADIENT votes
along each edge pixel's gradient for every radius, then, for every centre above
``hough_votes``, sorts the distances to the edge pixels around it; on noise, checkerboards
and crowds of circles the number of centres grows with the edge pixels, and the time
with about their power 1.5 (measured, :data:`COSTS` takes the dearest kind).
"""

from dataclasses import dataclass
import math

#: Cost of each kind of step: (ns per unit of work, ns per call), one core of the 2-core
#: machine, OpenCV on one thread: the upper end of what ``python -m ibvs_vision.bench
#: --calibrate`` measured (load average 1.2-2.5) over rendered, synthetic, noisy (0.05-0.5),
#: checkerboard and many-circle HD720 images. 'score': per image pixel, the hue-selective
#: channels of both markers (0.5-0.6 measured). 'hot': per pixel, the hot-block search of
#: one marker (0.2). 'edges': per pixel of a search window, its blur and Canny edges (1.2 on
#: a clean image, 12 on heavy noise, whose edges Canny follows; more on the smallest
#: windows: the per-call part). 'hough': per edge pixel to the power HOUGH_EXPONENT (up to
#: 470 on noise, 90 on many circles, 35-120 on checkerboards), and 'hough_pixel' per pixel
#: of the window. 'refine': per pixel of a refined candidate's window (18 median, up to 90
#: on the smallest windows: the per-call part, which also covers the axis band's centre).
#: 'pair': once a pair, what no step counts (the pairing, the windows, Python's calls; a
#: pair that stopped at 8.32 ms estimated took 8.64 ms of CPU).
COSTS = {'score': (0.6, 0.0), 'hot': (0.25, 0.0), 'edges': (12.0, 1e5),
         'hough': (470.0, 0.0), 'hough_pixel': (2.0, 0.0), 'refine': (45.0, 3e5),
         'pair': (0.0, 5e5)}
HOUGH_EXPONENT = 1.5


def hough_cost_ms(edge_pixels: int, pixels: int) -> float:
    """
    Return the estimated cost (ms) of a Hough transform of a window.

    Parameters
    ----------
    edge_pixels : int
        The window's Canny edge pixels (those HOUGH_GRADIENT votes from).
    pixels : int
        The window's pixels.

    Returns
    -------
    float
        The 'hough' cost of edge_pixels ** HOUGH_EXPONENT plus the 'hough_pixel' cost of
        the pixels (COSTS), in ms.

    """
    return (pass_cost_ms('hough', float(edge_pixels) ** HOUGH_EXPONENT)
            + pass_cost_ms('hough_pixel', pixels))


def pass_cost_ms(kind: str, units: float) -> float:
    """
    Return the estimated cost (ms) of one step of ``kind`` (a key of COSTS) over ``units``.

    Parameters
    ----------
    kind : str
        A key of COSTS.
    units : float
        Its units of work (pixels; for 'hough', edge pixels to the power HOUGH_EXPONENT).

    Returns
    -------
    float
        The cost in ms: per unit times units, plus per call.

    """
    per_unit, per_call = COSTS[kind]
    return 1e-6 * (per_unit * float(units) + per_call)


class OverBudget(Exception):
    """Raised by :meth:`WorkBudget.pay` when a step costs more than what is left."""


@dataclass
class WorkBudget:
    """
    The estimated cost (ms) a stereo pair may take, and what its steps have cost so far.

    ``limit_ms`` None: no limit (the cost is still counted). ``steps`` counts the steps paid
    for; ``refused`` names the step that was not, with its cost.
    """

    limit_ms: float | None = None
    spent_ms: float = 0.0
    steps: int = 0
    refused: str = ''

    def __post_init__(self):
        """Reject a limit that is not a positive finite number."""
        if self.limit_ms is not None and not (math.isfinite(self.limit_ms)
                                              and self.limit_ms > 0.0):
            raise ValueError(f'limit_ms must be a positive finite number or None, got '
                             f'{self.limit_ms!r}')

    def pay(self, cost_ms: float, what: str) -> None:
        """
        Spend ``cost_ms`` on step ``what``, or raise OverBudget and spend nothing.

        Parameters
        ----------
        cost_ms : float
            The step's estimated cost (ms).
        what : str
            The step, for the reason of a refusal.

        """
        if self.limit_ms is not None and self.spent_ms + cost_ms > self.limit_ms:
            self.refused = (f'{what} would cost {cost_ms:.2f} ms with {self.spent_ms:.2f} of '
                            f'{self.limit_ms:.2f} ms spent')
            raise OverBudget(self.refused)
        self.spent_ms += cost_ms
        self.steps += 1
