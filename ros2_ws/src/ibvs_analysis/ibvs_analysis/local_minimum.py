"""
Why classic IBVS stalls in scenario 1: a local minimum of the image error, shown from a run.

Classic IBVS moves the arm by q_dot = -lambda J^+ e (e = F(q) - p_bar, the six features of
the two markers against their target; J = dF/dq, :meth:`ibvs_model.CameraRobotModel.jacobian`):
a Gauss-Newton descent of |e|^2. It stops wherever J^+ e = 0, which is the target (e = 0)
or any point where e lies in the kernel of J^+ (Chaumette 1998, "Potential problems of
stability and convergence in image-based and position-based visual servoing": local
minima). This module takes a run's bag (``ibvs run scenario1 -p servo_law:=ibvs ...``,
docs/servo_laws.md gives the command) and, with the run's camera model and target, draws:

1. the tool's errors against time (position, mm; tool axis, deg) and the image error
   |e| (px) of the true joint angles;
2. the Gauss-Newton step |J^+ e| (rad) and the joint-space distance to the target against
   time: the step vanishes far from the target (a stationary point of the law);
3. |e| along the straight joint-space path from where the run ended to the target's joint
   angles: it rises before it falls to 0, so no descent leads from one to the other.

It writes ``ibvs_local_minimum.png`` and ``ibvs_local_minimum.json`` (the numbers) into
``-o`` and prints the numbers.
"""

import argparse
import json
from pathlib import Path
import sys
from typing import Any

from ibvs_model import CameraRobotModel, inverse_kinematics, IRB4600
import numpy as np

from .analysis import load_joints, load_run
from .metrics import axis_angle_deg

#: Samples of the run used (s of sim time between them), and points along the path.
SAMPLE_S = 0.01
PATH_POINTS = 101


def stationarity(model: CameraRobotModel, q: np.ndarray, p_target: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Return |e| (px) and the Gauss-Newton step |J^+ e| (rad) at each row of ``q``."""
    error = np.empty(len(q))
    step = np.empty(len(q))
    for k, qk in enumerate(q):
        e = model.features(qk) - p_target
        error[k] = np.linalg.norm(e)
        step[k] = np.linalg.norm(np.linalg.pinv(model.jacobian(qk), rcond=1e-6) @ e)
    return error, step


def path_profile(model: CameraRobotModel, q_from: np.ndarray, q_to: np.ndarray,
                 p_target: np.ndarray, points: int = PATH_POINTS
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Return s in [0, 1] and |F(q_from + s (q_to - q_from)) - p_target| (px)."""
    s = np.linspace(0.0, 1.0, points)
    error = np.array([np.linalg.norm(model.features(q_from + sk * (q_to - q_from)) - p_target)
                      for sk in s])
    return s, error


def analyse(bag: str | Path) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Return the numbers (module docstring) and the series to plot, from a run's bag."""
    run = load_run(bag)
    model = CameraRobotModel(run.camera, IRB4600)
    q_target = inverse_kinematics(run.target, IRB4600)
    p_target = model.features(q_target)
    t, q = load_joints(bag)[:2]  # the encoders': true = encoder + d_q (disturbance_deg)
    keep = np.searchsorted(t, np.arange(t[0], t[-1], SAMPLE_S))
    t = t[keep]
    q = q[keep] + np.radians(run.params.get('disturbance_deg', [0.0] * 6))
    error, step = stationarity(model, q, p_target)
    s, along = path_profile(model, q[-1], q_target, p_target)
    # Joint 6 turns the tool about its own axis, which no feature sees: left out.
    distance = np.linalg.norm(q[:, :5] - q_target[:5], axis=1)
    position = np.linalg.norm(run.position - run.target[:3, 3], axis=1)
    axis = axis_angle_deg(run.rotation, run.target[:3, :3])
    numbers = {
        'bag': str(bag),
        'servo_law': run.params.get('servo_law'),
        'final_position_error_mm': float(position[-1] * 1e3),
        'final_tool_axis_error_deg': float(axis[-1]),
        'final_image_error_px': float(error[-1]),
        'final_gauss_newton_step_rad': float(step[-1]),
        'initial_gauss_newton_step_rad': float(step[0]),
        'final_joint_distance_rad': float(distance[-1]),
        'end_joints_deg': [float(v) for v in np.degrees(q[-1])],
        'target_joints_deg': [float(v) for v in np.degrees(q_target)],
        'path_max_image_error_px': float(along.max()),
        'path_max_at': float(s[int(np.argmax(along))]),
    }
    series = {'t': t, 'error': error, 'step': step, 'distance': distance, 'run_t': run.t,
              'position': position, 'axis': axis, 's': s, 'along': along}
    return numbers, series


def plot(numbers: dict[str, Any], series: dict[str, np.ndarray], path: Path) -> None:
    """Draw the three panels (module docstring) into ``path``."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    ax = axes[0]
    ax.semilogy(series['run_t'], series['position'] * 1e3, label='position error [mm]')
    ax.semilogy(series['run_t'], series['axis'], label='tool axis error [deg]')
    ax.semilogy(series['t'], series['error'], label='image error |e| [px]')
    ax.set_xlabel('sim time [s]')
    ax.set_title(f"the run: it stops {numbers['final_position_error_mm']:.1f} mm and "
                 f"{numbers['final_tool_axis_error_deg']:.1f} deg off", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(True, which='both', alpha=0.3)
    ax = axes[1]
    ax.semilogy(series['t'], series['step'], label='Gauss-Newton step |J+ e| [rad]')
    ax.semilogy(series['t'], series['distance'],
                label='joint distance to the target, joints 1-5 [rad]')
    ax.set_xlabel('sim time [s]')
    ax.set_title(f"the law's step falls to {numbers['final_gauss_newton_step_rad']:.0e} rad, "
                 f"{numbers['final_joint_distance_rad']:.2f} rad from the target",
                 fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(True, which='both', alpha=0.3)
    ax = axes[2]
    ax.plot(series['s'], series['along'])
    ax.set_xlabel('s: q_end + s (q_target - q_end), joint space')
    ax.set_ylabel('image error |e| [px]')
    ax.set_title('towards the target the error first rises to '
                 f"{numbers['path_max_image_error_px']:.1f} px", fontsize=10)
    ax.grid(True, alpha=0.3)
    fig.suptitle('classic IBVS (q_dot = -lambda J+ e) in a local minimum of the image error '
                 f"({numbers['servo_law']}, scenario 1)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """``python -m ibvs_analysis.local_minimum BAG [-o DIR]``."""
    parser = argparse.ArgumentParser(prog='python -m ibvs_analysis.local_minimum',
                                     description=__doc__.strip().splitlines()[0])
    parser.add_argument('bag', help="a run's bag folder")
    parser.add_argument('-o', '--out', default='results', help='where the PNG and JSON go')
    args = parser.parse_args(argv)
    numbers, series = analyse(args.bag)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    plot(numbers, series, out / 'ibvs_local_minimum.png')
    (out / 'ibvs_local_minimum.json').write_text(json.dumps(numbers, indent=1) + '\n')
    print(json.dumps(numbers, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
