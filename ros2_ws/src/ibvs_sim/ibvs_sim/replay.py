"""
The camera images of a recorded run, rendered again from its joint states (no ROS).

A run's bag need not carry its camera images (2.7 MB each at HD720, 160 MB a simulated
second): the simulator's images are a function of the run's parameters and the true joint
angles at each frame, and the renderer is deterministic. :func:`replayed_frames` builds the
run's :class:`.simulator.Simulator` from its parameters (the same camera, renderer,
supersampling and camera effects, the taught pair first where the run taught its target, so
that the effects' random draws come in the same order) and, frame by frame, sets the
arm to the recorded state of the frame's physics step and takes the frame as the run did
(:meth:`.simulator.Simulator.take_frame`: the same stamp rule, frame drops and noise).

The recorded states are the encoders' (q_T = q - d_q, ``/ibvs/joint_path``); the true
angles are q_T + d_q, equal to the run's to the last bit or within one unit of it, which
moves no pixel of a float32 rasteriser in practice (tests/test_video.py compares the
replayed images with the recorded ones).
"""

from collections.abc import Iterator, Mapping
from typing import Any

from ibvs_common.shared_params import target_from_parameters, taught
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .node_params import SimConfig
from .simulator import Simulator


def simulator_of(params: Mapping[str, Any]) -> Simulator:
    """Return the :class:`Simulator` of a run's parameters (defaults for those not set)."""
    values = {p.name: params.get(p.name, p.default) for p in SimConfig.params()}
    teach = taught(params)
    return Simulator(SimConfig.from_values(values),
                     teach_pose=target_from_parameters(params) if teach else None)


def replayed_frames(params: Mapping[str, Any], stamps_ns: ArrayLike, encoders: ArrayLike
                    ) -> Iterator[tuple[int, tuple[NDArray[np.uint8], NDArray[np.uint8]]
                                        | None, bool]]:
    """
    Yield (stamp ns, (left, right) or None, lost) of each camera frame of a recorded run.

    ``params``: the run's parameters (its bag's); ``stamps_ns`` (N,), ``encoders`` (N, 6):
    the encoder angles of its physics steps in time order (``/ibvs/joint_path``), each
    stamp a whole number of steps. A frame is yielded for every frame due at a recorded
    step, in order; a lost one (``frame_drop_probability``) with None.
    """
    sim = simulator_of(params)
    try:
        for t_ns, q_t in zip(np.asarray(stamps_ns, dtype=np.int64), np.asarray(encoders)):
            if t_ns % sim.dt_ns:
                raise ValueError(f'stamp {int(t_ns)} ns is not on the {sim.dt_ns} ns step grid')
            sim.k = int(t_ns // sim.dt_ns)
            if sim.frame_due() is None:
                continue
            sim.world.reset(np.asarray(q_t, dtype=float) + sim.d_q)
            while sim.frame_due() is not None:
                yield sim.take_frame()
    finally:
        sim.close()
