"""
Benchmarks of the controllers' hot paths (``make bench`` calls :func:`run`).

- one feedback update: q~ = F^-1(p_hat) (eq. 42), C1 = J(q~) (eq. 31), SVD (eq. 34) and one
  step of k (eq. 38-41), on frames of a model-only scenario 1 run (target: <= 1 ms);
- one joint-loop update: M(q) and h(q, qdot) from PyBullet and one step of G_c with
  u = M v + h (eq. 26), along the same run (target: <= 0.3 ms), ideal and limited.

No assertion on time: numbers to read. ``python -m ibvs_control.bench`` prints median/p95.
"""

from collections.abc import Callable
import time

from ibvs_common.bench import print_timing
from ibvs_model import default_model, IRB4600, paper
import numpy as np

from .closed_loop import LoopConfig, simulate
from .controllers import AdaptiveFeedback, JointLoop
from .dynamics import RobotDynamics


def _timed(fn, args_list):
    out = []
    for args in args_list:
        start = time.perf_counter()
        fn(*args)
        out.append(time.perf_counter() - start)
    return out


def run(report: Callable[[str, list[float]], None]) -> None:
    """Time the feedback and joint-loop updates; ``report(name, seconds_list)`` each."""
    model = default_model()
    run_ = simulate(LoopConfig(scenario=1), duration_s=1.0)
    frames = [(p, run_.q[int(round(t * 1000))], np.zeros(6))
              for p, t in zip(run_.features, run_.frame_t)]
    feedback = AdaptiveFeedback(model, paper.target_pose(), paper.TAU_IN, paper.OMEGA_N,
                                paper.ZETA, 1.0 / 30.0)
    _timed(feedback.update, frames[:5])  # warm-up
    seconds = []
    for _ in range(5):
        feedback.reset()
        seconds += _timed(feedback.update, frames)
    report('ibvs_control: feedback update (F^-1, C1, SVD, k)', seconds)

    dynamics = RobotDynamics(IRB4600, with_tool=True)
    try:
        qd = np.gradient(run_.q, run_.t, axis=0)
        steps = [(run_.q_feedforward[k] + run_.q_feedback[k], run_.q[k], qd[k])
                 for k in range(0, len(run_.t), 2)]
        for mode in ('ideal', 'limited'):
            loop = JointLoop(paper.TAU_IN, 1e-3, mode, IRB4600.qd_max,
                             dynamics.torque_limits)

            def update(q_ref, q, qdot, loop=loop):
                loop.step(q_ref, q, qdot, dynamics.mass_matrix(q), dynamics.bias(q, qdot))
            _timed(update, steps[:20])
            report(f'ibvs_control: joint loop update, {mode} (M, h PyBullet + G_c)',
                   _timed(update, steps))
    finally:
        dynamics.close()


def main() -> None:
    """Print median and p95 of each benchmark."""
    run(print_timing)


if __name__ == '__main__':
    main()
