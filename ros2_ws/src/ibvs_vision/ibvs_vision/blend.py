"""
Bumpless switch between measured and estimated features (paper section 2.3, eq. 46).

The feature node publishes the measured p^_I (eq. 2-3) when the camera sees both
fiducials and the estimate p~_I = F(q_T) (eq. 46) when it does not. Switching the source
outright would step the published features by the model error (a disturbance d_q or a
wrong link length makes F(q_T) differ from what the camera sees) and kick the feedback
loop. Instead, at a switch at frame k the output goes on from where it was, moved by what
the model predicts for this frame, and the offset to the new source then fades out
linearly over ``blend_time_s``::

    out_k = out_k-1 + (F(q_T,k) - F(q_T,k-1))              (the switch frame)
    offset = out_k - source_k
    out(t) = source(t) + offset * max(0, 1 - (t - t_k) / blend_time_s)

The estimate F(q_T) exists at every frame (encoders), so it carries the arm's motion across
the switch: holding the last output instead would lag a moving arm by all the motion since
the last frame of the old source (hundreds of pixels during the fast feedforward start).
Where no estimate exists (a marker behind the camera) the switch frame holds the output.
So the output never jumps: at a switch frame it moves like the model, afterwards by the
change of the source plus at most |offset| * dt / blend_time_s per frame. A switch during
a blend starts a new one from the current output. Outside blends the output is the source
exactly (estimated features equal F(q_T) bit for bit). Time is the image stamp in integer
nanoseconds of sim time (never the wall clock), so the blend ends exactly on the frame that
reaches ``blend_time_s``.
"""

from ibvs_common.contract import (FEATURE_BLENDING as BLENDING,
                                  FEATURE_ESTIMATED as ESTIMATED,
                                  FEATURE_MEASURED as MEASURED)
from ibvs_common.timing import seconds_to_ns
import numpy as np
from numpy.typing import ArrayLike, NDArray


class BumplessSwitch:
    """Select the measured or the estimated p_I each frame and blend across switches."""

    def __init__(self, blend_time_s: float, hold_model_error: bool = False) -> None:
        """
        Blend over ``blend_time_s`` seconds (0 switches outright).

        Parameters
        ----------
        blend_time_s : float
            How long the offset fades out after a switch (s), >= 0.
        hold_model_error : bool
            At a switch from measured to estimated, keep the offset (the model error the
            last measurement showed, carried by the model) for as long as the estimate is
            used, instead of fading it out: the estimate is then F(q_T) + offset.

        """
        blend_time_s = float(blend_time_s)
        if not (np.isfinite(blend_time_s) and blend_time_s >= 0.0):
            raise ValueError(f'blend_time_s must be finite and >= 0, got {blend_time_s}')
        self.blend_ns = seconds_to_ns(blend_time_s)
        self.source = None
        self.mode = None
        self.last_switch_ns = None
        self.switches = 0
        self._offset = np.zeros(6)
        self.hold_model_error = bool(hold_model_error)
        self._held = None
        self._output = None
        self._estimate = None

    def blend_weight(self, t_ns: int) -> float:
        """
        Return the share (1 to 0) of the offset still applied at time ``t_ns``.

        Parameters
        ----------
        t_ns : int
            Image stamp (ns of sim time).

        Returns
        -------
        float

        """
        if self.last_switch_ns is None:
            return 0.0
        left = self.blend_ns - (int(t_ns) - self.last_switch_ns)
        return left / self.blend_ns if left > 0 else 0.0

    def update(self, t_ns: int, measured: ArrayLike | None,
               estimate: ArrayLike | None) -> NDArray[np.float64]:
        """
        Return the p_I to publish at time ``t_ns`` and set :attr:`mode`.

        Parameters
        ----------
        t_ns : int
            Image stamp (ns of sim time).
        measured : array_like, shape (6,), or None
            The detector's p_I (eq. 2-3), or None.
        estimate : array_like, shape (6,), or None
            F(q_T) (eq. 46); may be None while a measurement is available.

        Returns
        -------
        ndarray, shape (6,)
            The p_I to publish (px).

        Raises
        ------
        ValueError
            When neither ``measured`` nor ``estimate`` is given.

        """
        if measured is not None:
            source, value = MEASURED, np.asarray(measured, dtype=float).reshape(6)
        elif estimate is not None:
            source, value = ESTIMATED, np.asarray(estimate, dtype=float).reshape(6)
        else:
            raise ValueError('neither a measurement nor an estimate')
        estimate = None if estimate is None else np.asarray(estimate, dtype=float).reshape(6)
        if self._output is not None and source != self.source:
            carried = self._output.copy()
            if estimate is not None and self._estimate is not None:
                carried += estimate - self._estimate
            self._offset = carried - value
            self.last_switch_ns = int(t_ns)
            self.switches += 1
            self._held = (self._offset.copy() if self.hold_model_error and source == ESTIMATED
                          else None)
        self._estimate = estimate
        self.source = source
        if self._held is not None:
            self.mode = ESTIMATED
            self._output = value + self._held
            return self._output.copy()
        weight = self.blend_weight(t_ns)
        if weight > 0.0 and np.any(self._offset != 0.0):
            output = value + weight * self._offset
            self.mode = BLENDING
        else:
            output = value.copy()
            self.mode = source
        self._output = output
        return output.copy()
