"""
Each servo law against camera calibration error, in the model-only loop (no ROS).

The controllers' camera (what a calibration gives) differs from the true camera that makes
the features, as ``sim_node``'s ``camera_pose_error_xyz_m`` and ``focal_length_error`` do in
the graph: the calibrated frame is the true one moved by ``position_error_m`` along the unit
vector :data:`POSITION_ERROR_DIRECTION` of the true camera's axes, and the calibrated f_u,
f_v are the true ones times (1 + ``focal_error``). Each law runs from scenario 1 with the
target features p_bar from the model (F at the target with the calibrated camera, eq. 30)
or taught (measured by the true camera with the true robot at the target). The result per
run: the true flange's final position error and tool-axis error, and the time after which
it stays within 1 mm.

The noise sweep (:func:`noise_sweep`): Gaussian noise on the measured features, the RMS
error over the last second. ``python -m ibvs_experiments.calibration_sweep`` prints both
markdown tables.
"""

import argparse
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from ibvs_common.shared_params import TargetSource
from ibvs_control.closed_loop import LoopConfig, simulate
from ibvs_control.servo_laws import SERVO_LAWS
from ibvs_model import (CameraRobotModel, default_model, forward_kinematics, paper,
                        StereoCamera, StereoIntrinsics)
import numpy as np

#: Camera position errors (m) and focal length errors (fraction) of the sweep.
POSITION_ERRORS_M = (0.0, 0.0025, 0.005, 0.01)
FOCAL_ERRORS = (0.005, 0.01, 0.02)
#: The calibrated camera's offset direction in the true camera frame (x right, y down, z
#: along the optical axis): equal parts of each.
POSITION_ERROR_DIRECTION = np.ones(3) / np.sqrt(3.0)
TARGET_SOURCES = tuple(source.value for source in TargetSource)
DURATION_S = 3.0


@dataclass(frozen=True)
class SweepRun:
    """One run of the sweep: its setting and what the true flange did."""

    law: str
    target: str
    position_error_m: float
    focal_error: float
    final_position_error_m: float
    final_axis_error_deg: float
    time_to_1mm_s: float


def calibrated_camera(camera: StereoCamera, position_error_m: float = 0.0,
                      focal_error: float = 0.0) -> StereoCamera:
    """Return ``camera`` as a calibration with these errors gives it (module docstring)."""
    k = camera.intrinsics
    scale = 1.0 + float(focal_error)
    intrinsics = StereoIntrinsics(k.width, k.height, k.fu * scale, k.fv * scale, k.cu, k.cv,
                                  k.baseline)
    shift = np.eye(4)
    shift[:3, 3] = position_error_m * POSITION_ERROR_DIRECTION
    return StereoCamera(intrinsics, camera.pose_C_O @ shift)


def run_one(law: str, target: str, position_error_m: float = 0.0, focal_error: float = 0.0,
            duration_s: float = DURATION_S, **options: Any) -> SweepRun:
    """Return the :class:`SweepRun` of one law with one calibration error (scenario 1)."""
    true = default_model()
    model = CameraRobotModel(calibrated_camera(true.camera, position_error_m, focal_error),
                             true.params)
    r = simulate(LoopConfig.for_law(law, target_features_source=target, **options),
                 duration_s, model=model, plant_camera=true.camera)
    pose = paper.target_pose()
    flange = np.array([forward_kinematics(q, true.params) for q in r.q_true])
    error = np.linalg.norm(flange[:, :3, 3] - pose[:3, 3], axis=1)
    cos = np.clip(flange[-1, :3, 2] @ pose[:3, 2], -1.0, 1.0)
    outside = np.nonzero(error > 1e-3)[0]
    t_1mm = (float('nan') if outside.size and outside[-1] + 1 >= r.t.size
             else float(r.t[outside[-1] + 1]) if outside.size else 0.0)
    return SweepRun(law, target, float(position_error_m), float(focal_error),
                    float(error[-1]), float(np.degrees(np.arccos(cos))), t_1mm)


#: Feature noise of the noise sweep (px, standard deviation per value and frame).
NOISE_PX = (0.0, 0.1, 0.3, 1.0)
#: The noise sweep's error is the RMS over this last part of the run (s).
TAIL_S = 1.0


def noise_sweep(laws: Iterable[str] = SERVO_LAWS, noise_px: Iterable[float] = NOISE_PX,
                duration_s: float = DURATION_S, seed: int = 0
                ) -> dict[tuple[str, float], tuple[float, float]]:
    """
    Return {(law, noise): (RMS position error, RMS axis error)} over the last TAIL_S.

    Model-only loop from scenario 1, Gaussian noise of ``noise_px`` on every measured
    feature (``closed_loop.simulate(feature_noise_px=...)``), the same seed for every law.
    """
    pose = paper.target_pose()
    out = {}
    for law in laws:
        for sigma in noise_px:
            r = simulate(LoopConfig.for_law(law), duration_s, feature_noise_px=sigma,
                         seed=seed)
            tail = r.t >= r.t[-1] - TAIL_S
            flange = np.array([forward_kinematics(q, r.model.params) for q in r.q_true[tail]])
            position = np.linalg.norm(flange[:, :3, 3] - pose[:3, 3], axis=1)
            axis = np.degrees(np.arccos(np.clip(flange[:, :3, 2] @ pose[:3, 2], -1.0, 1.0)))
            out[law, sigma] = (float(np.sqrt(np.mean(position ** 2))),
                               float(np.sqrt(np.mean(axis ** 2))))
    return out


def noise_table(results: dict[tuple[str, float], tuple[float, float]]) -> list[str]:
    """Return the markdown lines of :func:`noise_sweep`: one row per law."""
    noise = sorted({sigma for _, sigma in results})
    lines = ['| law | ' + ' | '.join(f'noise {sigma:g} px' for sigma in noise) + ' |',
             '|---|' + '---|' * len(noise)]
    for law in dict.fromkeys(law for law, _ in results):
        lines.append(f'| {law} | ' + ' | '.join(
            f'{1e3 * results[law, sigma][0]:.2f} mm / {results[law, sigma][1]:.2f} deg'
            for sigma in noise) + ' |')
    return lines


def settings() -> list[tuple[float, float]]:
    """Return the (position error, focal error) of every sweep point: one error at a time."""
    return ([(d, 0.0) for d in POSITION_ERRORS_M] + [(0.0, f) for f in FOCAL_ERRORS])


def sweep(laws: Iterable[str] = SERVO_LAWS, targets: Iterable[str] = TARGET_SOURCES,
          points: Iterable[tuple[float, float]] | None = None, **options: Any
          ) -> list[SweepRun]:
    """Return the :class:`SweepRun` of every law, target source and sweep point."""
    points = settings() if points is None else points
    return [run_one(law, target, d, f, **options)
            for target in targets for law in laws for d, f in points]


def table(runs: Sequence[SweepRun]) -> list[str]:
    """Return the markdown lines: one row per law and target, one column per sweep point."""
    points = list(dict.fromkeys((r.position_error_m, r.focal_error) for r in runs))
    head = ['no error' if d == f == 0.0 else f'camera position {1e3 * d:.1f} mm' if f == 0.0
            else f'focal {100 * f:.1f} %' if d == 0.0
            else f'camera position {1e3 * d:.1f} mm, focal {100 * f:.1f} %' for d, f in points]
    lines = ['| target | law | ' + ' | '.join(head) + ' |',
             '|---|---|' + '---|' * len(points)]
    for target in dict.fromkeys(r.target for r in runs):
        for law in dict.fromkeys(r.law for r in runs):
            cells = []
            for point in points:
                run = next(r for r in runs if r.target == target and r.law == law
                           and (r.position_error_m, r.focal_error) == point)
                cells.append(f'{1e3 * run.final_position_error_m:.2f} mm / '
                             f'{run.final_axis_error_deg:.2f} deg')
            lines.append(f'| {target} | {law} | ' + ' | '.join(cells) + ' |')
    return lines


def main(argv: Sequence[str] | None = None) -> int:
    """Print the sweep's table (final position / axis error of the true flange)."""
    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument('--duration', type=float, default=DURATION_S, help='sim time, s')
    args = parser.parse_args(argv)
    print('\n'.join(table(sweep(duration_s=args.duration))))
    print()
    print('\n'.join(noise_table(noise_sweep(duration_s=args.duration))))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
