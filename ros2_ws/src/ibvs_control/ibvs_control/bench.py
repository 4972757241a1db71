"""
Benchmarks of the controllers' hot paths (``make bench`` calls :func:`run`).

- one feedback update: q~ = F^-1(p_hat) (eq. 42), C1 = J(q~) (eq. 31), SVD (eq. 34) and one
  step of k (eq. 38-41), on frames of a model-only scenario 1 run (target: <= 1 ms);
- one joint-loop update: M(q) and h(q, qdot) from PyBullet and one step of G_c with
  u = M v + h (eq. 26), along the same run (target: <= 0.3 ms), ideal and limited;
- one prediction of a frame to its action time (:func:`.prediction.predicted_features`,
  two F), what the latency costs the feedback per frame;
- one position reference: the shaper re-planning Ruckig's move to a new target (the
  q_feedback of a new frame) and sampling it, every command period at 250 Hz (4 ms);
- the feedforward node's start-up, from a joint state to its message: the two-point
  trajectory of the joint controller's own move (position interface, limited actuators)
  and T_forward's trajectory (ideal actuators) at the paper's ``tau_in`` and at 0.05, 0.2
  and 1 s (the slowest, a 60 s trajectory).

No assertion on time: numbers to read. ``python -m ibvs_control.bench`` prints median/p95.
"""

from collections.abc import Callable
import time

from ibvs_common.bench import print_timing
from ibvs_common.msg_trajectory import joint_trajectory_bytes
from ibvs_model import default_model, IRB4600, paper
import numpy as np

from .closed_loop import LoopConfig, simulate
from .controllers import AdaptiveFeedback, Feedforward, JointLoop
from .dynamics import RobotDynamics
from .position_interface import PositionShaper
from .prediction import predicted_features


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
    pairs = [(model, p, run_.q[max(int(round(t * 1000)) - 100, 0)],
              run_.q[int(round(t * 1000))]) for p, t in zip(run_.features, run_.frame_t)]
    _timed(predicted_features, pairs[:5])
    report('ibvs_control: prediction of a frame to its action time (2 F)',
           _timed(predicted_features, pairs * 5))

    shaper = PositionShaper(250.0, max_speed=np.radians(60.0))
    shaper.start(run_.q[0])
    rng = np.random.default_rng(0)
    targets = [(run_.q_target + rng.normal(0.0, 1e-3, 6), 0.004) for _ in range(2000)]
    report('ibvs_control: position reference, Ruckig re-planned to a new target (6 joints)',
           _timed(shaper.step, targets))

    def start_up(tau_in, two_points):
        """Do the feedforward node's work from a joint state to its message (IK, filter)."""
        ff = Feedforward(paper.target_pose(), tau_in, 1e-3)
        ff.start(run_.q[0])
        positions = np.array([run_.q[0], ff.goal]) if two_points else ff.trajectory()
        return joint_trajectory_bytes(0, 1_000_000, positions)
    report('ibvs_control: feedforward start-up, own move (IK, two points, bytes)',
           _timed(start_up, [(paper.TAU_IN, True)] * 20))
    for tau_in in (paper.TAU_IN, 0.05, 0.2, 1.0):
        report(f'ibvs_control: feedforward start-up, T_forward at tau_in {tau_in:g} '
               '(IK, trajectory, bytes)', _timed(start_up, [(tau_in, False)] * 3))

    dynamics = RobotDynamics(IRB4600, with_tool=True)
    try:
        qd = np.gradient(run_.q, run_.t, axis=0)
        for mode in ('ideal', 'limited'):
            # limited: the loop makes its own move to the goal (controllers.makes_own_move)
            steps = [((run_.q_target if mode == 'limited' else run_.q_feedforward[k])
                      + run_.q_feedback[k], run_.q[k], qd[k])
                     for k in range(0, len(run_.t), 2)]
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
