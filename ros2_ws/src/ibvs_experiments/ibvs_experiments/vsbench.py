"""
``make vsbench``: the workspace benchmark (500 seeded tasks, three servo laws).

The benchmark is data (:mod:`.vsbench_tasks`, committed as ``benchmarks/vsbench-3.json``):
500 tasks of the workspace sampler (:func:`ibvs_model.task_sampler.tasks`, version
``workspace-3``, seed :data:`TASK_SEED`: every target rendered and its markers detected),
each with its own drawn imperfections (camera
calibration error within +-3 mm per axis, +-0.3 deg per axis, focal length within
+-0.5 %, and the ``camera_seed`` of its image noise and lost frames: seed
:data:`.vsbench_tasks.IMPERFECTION_SEED`) and the conditions every run shares
(:data:`CONDITIONS`: limited actuators, 67 ms latency, image noise 0.01, 5 % lost frames, a
taught target, the safety envelope on), and the latency axis every law also runs
(:data:`LATENCY_AXIS`, :data:`MISMODELLED`). Anyone can run their law on the same 500 tasks
from the file alone.

Two ways through the tasks, the same success rule (:data:`ibvs_analysis.convergence.SUCCESS`):

- the model loop (:func:`ibvs_control.closed_loop.simulate`, no ROS, seconds per run) for
  every task and law, in a process pool (:func:`screen`): the calibration error as the
  model's camera against the true one, the detector's measured feature noise
  (:data:`FEATURE_NOISE_PX`, on every frame; on the taught target divided by the square
  root of ``teach_frames``) and the lost frames;
- the node graph (``ibvs run``, HD720, lockstep: deterministic) for the first
  ``--graph-tasks`` tasks and every law as a study on Ray (:func:`graph_spec`; resumable:
  the study cache keeps finished runs).

Per run (:func:`run_metrics`): success and why not (:func:`miss_class`), time to 1 mm,
overshoot, path-length ratio (tool path / straight start-target distance), peak joint
speed / rated speed, the envelope's interventions, the smallest distance to a joint limit
and the smallest self and scene clearance (capsules) with the violations (samples past a
limit, clearances <= 0). Per law (:mod:`.vsbench_report`): the success rate with its 95 %
Wilson interval (``scipy.stats.binomtest(...).proportion_ci(method='wilson')``) and whether
model and graph agree on their common tasks. ``results/vsbench.md``, a CSV and JSON of
every run, and figures of success against start distance and start angle.
"""

import argparse
from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
import json
import math
import os
from pathlib import Path
import sys
import time
from typing import Any

from ibvs_analysis import analysis
from ibvs_analysis.convergence import SUCCESS
from ibvs_analysis.metrics import compute_metrics
from ibvs_analysis.study_table import reason_category
from ibvs_common import shared_params
from ibvs_control.closed_loop import LoopConfig, simulate
from ibvs_control.controllers import limited_time_optimal_s
from ibvs_control.envelope import Intervention
from ibvs_control.prediction import LATENCY_COMPENSATIONS
from ibvs_model import (CameraRobotModel, default_model, forward_kinematics_batch, IRB4600,
                        pose_from, StereoCamera, task_sampler)
from ibvs_model.capsules import Cell, clearances
import numpy as np
from numpy.typing import ArrayLike

from . import study
from .runner import with_servo_law
from .study import default_parallel
from .vsbench_report import timing_lines, write_results
from .vsbench_tasks import (BENCHMARK_FILE, CONDITIONS, DURATION_S, GRAPH_RESOLUTION, LAWS,
                            load, NAME, TASK_SEED, TASKS, VERSION, VERSIONS, write_definition)

#: The feature noise (px, standard deviation per value and frame) the detector gives with
#: image noise 0.01, per image size: :func:`measure_feature_noise` on the first 8 tasks'
#: targets, 20 noise draws each (RMS over the six values of the per-pose standard
#: deviations). At HD720 the model loop with it ends scenario 1 as the graph does (the
#: figures of both: docs/vsbench.md).
FEATURE_NOISE_PX = {'VGA': 0.017, 'HD720': 0.0076}
#: The model loop's 'limited' actuators (the bare double integrator, M = I): acceleration
#: limits (rad/s^2), per joint the smallest (tau_max - |g(q)|) / M_ii over the first 50
#: tasks' targets (:func:`acceleration_limits`, the URDF's torque limits and masses),
#: rounded down; joint 6's is capped at the parameter's range.
ACCELERATION_LIMITS = (57.0, 24.0, 120.0, 14000.0, 56000.0, 1.0e6)
#: Joint-limit distance (rad) under which a stalled run is classed 'limit'.
LIMIT_CLASS_RAD = 0.1
#: The latency axis (s of ``feedback_latency_s``): every law at each, the benchmark's
#: condition (67 ms) among them; from a camera with no delay to past the stability limit
#: of the law designed without it (193 ms).
LATENCY_AXIS = (0.0, 0.067, 0.133, 0.2, 0.3)
#: The mis-modelled points: (latency, how much longer the latency the law assumes is, s).
#: The frames' encoder angles are those of the assumed exposure (``closed_loop.simulate``'s
#: ``stamp_error_s`` = -error), which is what a stamp off by a constant does to the
#: predictor.
MISMODELLED = ((0.133, 0.02), (0.133, -0.02))


# ----------------------------------------------------------------------------- the model loop

def target_pose(task: Mapping[str, Any]) -> np.ndarray:
    """Return a task's target flange pose T_E^O (4x4)."""
    return pose_from(task['target_position'], np.reshape(task['target_rotation'], (3, 3)))


def calibrated_model(true: CameraRobotModel, task: Mapping[str, Any]) -> CameraRobotModel:
    """Return the controllers' model: the true camera as the task's calibration gives it."""
    from ibvs_sim.camera_effects import calibrated_intrinsics, calibrated_pose
    camera = StereoCamera(
        calibrated_intrinsics(true.camera.intrinsics, task['focal_length_error']),
        calibrated_pose(true.camera.pose_C_O, task['camera_pose_error_xyz_m'],
                        task['camera_pose_error_rpy_deg']))
    return CameraRobotModel(camera, true.params)


def loop_config(law: str, task: Mapping[str, Any], conditions: Mapping[str, Any]
                ) -> LoopConfig:
    """Return the model loop's config of one run (the graph's parameters where it has them)."""
    keys = set(LoopConfig.__dataclass_fields__)
    values = {k: (tuple(v) if isinstance(v, list) else v) for k, v in conditions.items()
              if k in keys}
    return LoopConfig.for_law(law, **values, torque_limits=ACCELERATION_LIMITS,
                              start_joints=tuple(task['start_joints']))


def time_optimal_s(task: Mapping[str, Any], conditions: Mapping[str, Any]) -> float | None:
    """
    Return a task's time-optimal bound (s) under ``conditions``' actuators, else None.

    With 'limited' actuators: Ruckig's move of the model loop's plant from the task's start
    to its target joints at rest (:func:`ibvs_control.controllers.limited_time_optimal_s`
    with :data:`ACCELERATION_LIMITS`), one bound per task for both loops. With the paper's
    ideal actuators there is none.
    """
    if conditions.get('actuators') != 'limited':
        return None
    return limited_time_optimal_s(task['start_joints'], task['target_joints'],
                                  ACCELERATION_LIMITS)


def model_run(task: Mapping[str, Any], law: str, conditions: Mapping[str, Any] = CONDITIONS,
              duration_s: float = DURATION_S, resolution: str = GRAPH_RESOLUTION,
              feature_noise_px: float | None = None, latency_error_s: float = 0.0
              ) -> dict[str, Any]:
    """
    Run one task with one law through the model loop; return :func:`run_metrics`' row.

    The true camera makes the features, the calibrated one is the controllers' model; the
    feature noise on every frame and on the taught target (divided by the square root of
    ``teach_frames`` there), the lost frames and their seed
    (``camera_seed``) as the task gives them. ``feature_noise_px``: default
    :data:`FEATURE_NOISE_PX` of ``resolution`` (the camera's image size).
    ``latency_error_s``: how much longer than ``feedback_latency_s`` the latency the law
    assumes is (:data:`MISMODELLED`).
    """
    start = time.perf_counter()
    true = default_model(resolution)
    if feature_noise_px is None:
        feature_noise_px = FEATURE_NOISE_PX[resolution]
    noise = feature_noise_px if conditions.get('image_noise_stddev', 0.0) > 0.0 else 0.0
    taught = shared_params.taught(conditions)
    # The teach pair averages teach_frames frames (sim_node): 1 / sqrt of one frame's noise.
    teach_noise = noise / math.sqrt(conditions.get('teach_frames', 1)) if taught else 0.0
    result = simulate(loop_config(law, task, conditions), duration_s,
                      model=calibrated_model(true, task), plant_camera=true.camera,
                      disturbance=np.radians(conditions.get('disturbance_deg', [0.0] * 6)),
                      target=target_pose(task), feature_noise_px=noise,
                      target_noise_px=teach_noise, seed=int(task['camera_seed']),
                      frame_drop_probability=float(conditions.get('frame_drop_probability',
                                                                  0.0)),
                      stamp_error_s=-latency_error_s)
    modes = ['measured' if m else 'estimated' for m in result.measured]
    row = run_metrics(task, law, result.t, result.q_true, modes=modes,
                      mode_t=result.frame_t, interventions=result.interventions,
                      conditions=conditions, latency_error_s=latency_error_s)
    row.update(source='model', wall_s=time.perf_counter() - start,
               dropped_frames=result.dropped_frames)
    return row


def measure_feature_noise(resolution: str = GRAPH_RESOLUTION, image_noise: float = 0.01,
                          poses: int = 8, draws: int = 20, seed: int = 0
                          ) -> tuple[float, int, int]:
    """
    Measure the detector's feature noise (px) under image noise: what FEATURE_NOISE_PX holds.

    The simulator's renderer draws the first ``poses`` tasks' targets; each pair gets
    ``draws`` draws of the simulator's image noise (:func:`ibvs_sim.camera_effects.
    add_image_noise`) and is detected as the feature node tracks (prior: the clean pair's
    features). Returns (RMS over the six values of the per-pose standard deviations,
    detections, detections that failed).
    """
    from ibvs_sim.camera_effects import add_image_noise
    from ibvs_sim.world import World
    from ibvs_vision.detector import StereoDetector
    model = default_model(resolution)
    detector = StereoDetector(model.camera.intrinsics)
    rng = np.random.default_rng(seed)
    world = World()
    spreads, count, failed = [], 0, 0
    try:
        for task in task_sampler.tasks(poses, TASK_SEED):
            world.reset(np.asarray(task['target_joints']))
            left, right = world.render_stereo(model.camera)
            clean = detector.detect(left, right).features
            found = []
            for _ in range(draws):
                count += 1
                d = detector.detect(add_image_noise(left, image_noise, rng),
                                    add_image_noise(right, image_noise, rng), prior=clean)
                if d.features is None:
                    failed += 1
                else:
                    found.append(d.features)
            if len(found) > 1:
                spreads.append(np.std(found, axis=0, ddof=1))
    finally:
        world.close()
    return float(np.sqrt(np.mean(np.square(spreads)))), count, failed


def acceleration_limits(n_tasks: int = 50) -> np.ndarray:
    """
    Return per joint the smallest (tau_max - |g(q)|) / M_ii over the first tasks' targets.

    The URDF's torque limits and masses (:class:`ibvs_control.dynamics.RobotDynamics`), the
    arm at rest (the bias is gravity): the acceleration each joint has left at the worst
    target, what :data:`ACCELERATION_LIMITS` holds rounded down.
    """
    from ibvs_control.dynamics import RobotDynamics
    dynamics = RobotDynamics()
    try:
        out = np.full(6, np.inf)
        for task in task_sampler.tasks(n_tasks, TASK_SEED):
            q = np.asarray(task['target_joints'])
            spare = np.maximum(dynamics.torque_limits - np.abs(dynamics.bias(q, np.zeros(6))),
                               0.1 * dynamics.torque_limits)
            out = np.minimum(out, spare / np.diag(dynamics.mass_matrix(q)))
        return out
    finally:
        dynamics.close()


def _model_job(args):
    return model_run(*args)


def run_metrics(task: Mapping[str, Any], law: str, t: ArrayLike, q: ArrayLike,
                modes: Sequence[str] = (), mode_t: ArrayLike = (),
                interventions: Mapping[int, int] | None = None,
                metrics: Mapping[str, Any] | None = None, every: int = 10,
                conditions: Mapping[str, Any] = CONDITIONS, latency_error_s: float = 0.0
                ) -> dict[str, Any]:
    """
    Return one run's row from its true joint angles ``q`` (N, 6) at times ``t`` (s).

    The tool's metrics are :func:`ibvs_analysis.metrics.compute_metrics`' (or ``metrics``, a
    graph run's own, for the errors, time to 1 mm, overshoot and the ripple over the last
    0.5 s); the rest from ``q``: path length / straight distance, peak joint speed /
    ``qd_max``, the smallest distance to a joint limit (rad) and the samples past one, and
    every ``every``-th sample's self and scene clearance (m,
    :func:`ibvs_model.capsules.clearances`) and those <= 0. The run's latency point
    (``conditions``' ``feedback_latency_s`` and ``latency_error_s``) and its bound
    (:func:`time_optimal_s`, and the time to 1 mm less it) label the row.
    """
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    poses = forward_kinematics_batch(q, IRB4600)
    target = target_pose(task)
    if metrics is None:
        metrics = compute_metrics(t, poses[:, :3, 3], poses[:, :3, :3], target,
                                  np.asarray(mode_t, dtype=float), list(modes))
    position = poses[:, :3, 3]
    straight = float(np.linalg.norm(target[:3, 3] - position[0]))
    path = float(np.linalg.norm(np.diff(position, axis=0), axis=1).sum())
    qd = np.diff(q, axis=0) / np.maximum(np.diff(t), 1e-12)[:, None]
    q_min, q_max = np.asarray(IRB4600.q_min), np.asarray(IRB4600.q_max)
    margin = np.minimum(q - q_min, q_max - q)
    cell = Cell()
    sampled = q[::every] if q.shape[0] else q
    sampled = np.vstack([sampled, q[-1:]])
    clear = np.array([clearances(qq, cell, IRB4600)[:2] for qq in sampled])
    counts = {Intervention(int(k)).name: int(v) for k, v in (interventions or {}).items()}
    start_axis, target_axis = poses[0, :3, 2], target[:3, 2]
    row = {
        'task': task['id'], 'index': int(task['index']), 'law': law,
        'observability': float(task['observability']),
        'start_distance_m': float(np.linalg.norm(target[:3, 3] - position[0])),
        'start_angle_deg': float(np.degrees(np.arccos(
            np.clip(start_axis @ target_axis, -1.0, 1.0)))),
        'success': bool(SUCCESS.final(metrics)),
        'final_position_error_m': metrics.get('final_position_error_m'),
        'final_tool_axis_error_deg': metrics.get('final_tool_axis_error_deg'),
        'time_to_1mm_s': metrics.get('time_to_1mm_s'),
        'overshoot_m': metrics.get('max_overshoot_m'),
        'path_length_ratio': path / straight if straight > 0.0 else float('nan'),
        'peak_speed_ratio': float((np.abs(qd) / np.asarray(IRB4600.qd_max)).max(initial=0.0)),
        'interventions': int(sum(counts.values())),
        'intervention_codes': counts,
        'min_limit_distance_rad': float(margin.min()),
        'limit_violations': int(np.count_nonzero((margin < 0.0).any(axis=1))),
        'min_self_clearance_m': float(clear[:, 0].min()),
        'min_scene_clearance_m': float(clear[:, 1].min()),
        'collisions': int(np.count_nonzero((clear <= 0.0).any(axis=1))),
        'miss_reason_text': metrics.get('miss_reason') or '',
        'ripple_m': metrics.get('position_error_ripple_last_0_5s_m'),
        'latency_s': float(conditions.get('feedback_latency_s', 0.0)),
        'latency_error_s': float(latency_error_s),
    }
    bound = time_optimal_s(task, conditions)
    reached = row['time_to_1mm_s']
    row['time_optimal_s'] = bound
    row['time_to_1mm_over_optimal_s'] = None if bound is None or reached is None \
        else reached - bound
    last = t >= t[-1] - 0.5
    row['miss_reason'] = miss_class(row, margin[last].min() if last.any() else margin.min())
    return row


def miss_class(row: Mapping[str, Any], last_limit_distance: float) -> str:
    """
    Return a run's miss class ('' for a success): the category of why it missed.

    'collision' (a clearance reached 0, or the envelope halted for one), 'limit' (stalled
    within :data:`LIMIT_CLASS_RAD` of a joint limit in the last 0.5 s), 'singular' (the
    envelope halted for a singularity and the run stalled), else the study's category of
    :func:`ibvs_analysis.convergence.miss_reason`'s words
    (:func:`ibvs_analysis.study_table.reason_category`): 'lost features', 'local minimum' (a
    graph run's: the model loop records no image error), 'stalled', 'timed out', 'no final
    pose'.
    """
    if row['success']:
        return ''
    text = row.get('miss_reason_text', '')
    codes = row.get('intervention_codes', {})
    if row.get('collisions') or codes.get('HALT_FOR_COLLISION'):
        return 'collision'
    category = reason_category(text, failed=False)  # the study's words for the reason
    if category == 'stalled':
        if last_limit_distance < LIMIT_CLASS_RAD:
            return 'limit'
        if codes.get('HALT_FOR_SINGULARITY'):
            return 'singular'
    return category


class Progress:
    """Progress lines with an ETA: mean wall time per run x runs left / workers."""

    def __init__(self, total: int, workers: int, what: str,
                 out: Callable[[str], None] = print) -> None:
        """Start the clock."""
        self.total, self.workers, self.what, self.out = total, max(1, workers), what, out
        self.done = 0
        self.wall = 0.0
        self.start = time.monotonic()

    def update(self, row: Mapping[str, Any]) -> None:
        """Print one line for a finished run."""
        self.done += 1
        self.wall += float(row.get('wall_s') or 0.0)
        left = self.total - self.done
        eta = self.wall / self.done * math.ceil(left / self.workers)
        elapsed = time.monotonic() - self.start
        self.out(f'[{self.what} {self.done}/{self.total}] {row["task"]} {row["law"]}: '
                 f'{"ok" if row["success"] else row["miss_reason"]}; elapsed '
                 f'{elapsed:.0f} s, ETA {eta:.0f} s')


def latency_points(latencies: Iterable[float], mismodelled: Iterable[tuple[float, float]]
                   = MISMODELLED) -> list[tuple[float, float]]:
    """
    Return the (latency, error) points of a run: each latency with the law assuming it.

    Then each mis-modelled point (:data:`MISMODELLED`) whose latency is among them.
    """
    latencies = [float(x) for x in latencies]
    return [(x, 0.0) for x in latencies] + [
        (float(x), float(e)) for x, e in mismodelled if any(math.isclose(x, y)
                                                            for y in latencies)]


def screen(tasks: Sequence[Mapping[str, Any]], laws: Iterable[str] = LAWS,
           conditions: Mapping[str, Any] = CONDITIONS, duration_s: float = DURATION_S,
           workers: int | None = None, out: Callable[[str], None] = print,
           resolution: str = GRAPH_RESOLUTION,
           points: Sequence[tuple[float, float]] | None = None) -> list[dict[str, Any]]:
    """
    Run every task with every law through the model loop in a process pool; rows in order.

    ``points``: the (latency, error) points (:func:`latency_points`), each a run of every
    task and law; default the one of ``conditions``.
    """
    if points is None:
        points = ((conditions['feedback_latency_s'], 0.0),)
    jobs = [(task, law, {**conditions, 'feedback_latency_s': latency}, duration_s, resolution,
             None, error) for latency, error in points for task in tasks for law in laws]
    workers = workers or os.cpu_count() or 1
    progress = Progress(len(jobs), workers, 'model', out)
    rows = []
    if workers == 1:
        for job in jobs:
            rows.append(_model_job(job))
            progress.update(rows[-1])
        return rows
    with ProcessPoolExecutor(workers) as pool:
        for row in pool.map(_model_job, jobs):
            rows.append(row)
            progress.update(row)
    return rows


# ------------------------------------------------------------------------------- the graph

def graph_overrides(task: Mapping[str, Any], law: str, conditions: Mapping[str, Any],
                    resolution: str = GRAPH_RESOLUTION) -> dict[str, Any]:
    """Return the ``ibvs run`` parameters of one graph run (:func:`.runner.with_servo_law`'s)."""
    run = with_servo_law({**conditions, 'resolution': resolution, 'servo_law': law})
    return {**run, 'start_joints': list(task['start_joints']),
            'target_position': list(task['target_position']),
            'target_rotation': list(task['target_rotation']),
            'camera_pose_error_xyz_m': list(task['camera_pose_error_xyz_m']),
            'camera_pose_error_rpy_deg': list(task['camera_pose_error_rpy_deg']),
            'focal_length_error': task['focal_length_error'],
            'camera_seed': task['camera_seed']}


def graph_spec(bench: Mapping[str, Any], n_tasks: int, laws: Iterable[str] = LAWS,
               duration_s: float | None = None, name: str = f'{NAME}_graph',
               resolution: str | None = None):
    """
    Return the graph runs as a study (:class:`.study_spec.Spec`): the first ``n_tasks``.

    One grid point per task and law (a list of one-point products, their union), so each
    run's key holds the task's values: the study cache resumes a benchmark stopped half way.
    """
    from .study_spec import Spec
    tasks = bench['tasks'][:n_tasks]
    laws = tuple(laws)
    resolution = resolution or bench['graph']['resolution']
    grid = tuple({k: [v] for k, v in graph_overrides(task, law, bench['conditions'],
                                                     resolution).items()}
                 for task in tasks for law in laws)
    return Spec(name=name, scenario=bench['graph']['scenario'],
                duration_s=duration_s or bench['duration_s'], grid=grid,
                description=f"{bench['version']}: {len(tasks)} tasks x {len(laws)} laws "
                            f'through the graph at {resolution}')


def graph_row(task: Mapping[str, Any], law: str, record: Mapping[str, Any],
              conditions: Mapping[str, Any] = CONDITIONS) -> dict[str, Any]:
    """Return a graph run's row from its study record (its metrics.json and bag)."""
    run_dir = Path(record['run_dir'])
    wall = record.get('wall_s')
    if record.get('status') != 'ok':
        return {'task': task['id'], 'index': int(task['index']), 'law': law,
                'source': 'graph', 'success': False, 'miss_reason': 'failed',
                'miss_reason_text': str(record.get('error', record.get('reason', ''))),
                'wall_s': wall, 'latency_s': float(conditions['feedback_latency_s']),
                'latency_error_s': 0.0}
    metrics = json.loads((run_dir / 'metrics.json').read_text())
    t, q, *_ = analysis.load_joints(run_dir / 'bag')
    row = run_metrics(task, law, t, q, metrics=metrics,
                      interventions=analysis.envelope_interventions(run_dir / 'bag'),
                      conditions=conditions)
    row.update(source='graph', wall_s=wall)
    return row


def run_graph(bench: Mapping[str, Any], n_tasks: int, out_dir: Path,
              laws: Iterable[str] = LAWS, parallel: int | None = None,
              duration_s: float | None = None, out=sys.stdout,
              resolution: str | None = None, latencies: Iterable[float] = (),
              latency_tasks: int = 0) -> list[dict[str, Any]]:
    """
    Run :func:`graph_spec` on Ray (study machinery, cached) and return its rows.

    ``latencies``: besides the benchmark's condition, each (s) on the first
    ``latency_tasks`` tasks, a study of its own (the latency in its name).
    """
    laws = tuple(laws)
    resolution = resolution or bench['graph']['resolution']
    base = bench['conditions']['feedback_latency_s']
    points = [(base, n_tasks)] + [(float(x), min(latency_tasks, n_tasks)) for x in latencies
                                  if not math.isclose(x, base) and latency_tasks]
    specs, benches = [], []
    for latency, n in points:
        point = {**bench, 'conditions': {**bench['conditions'], 'feedback_latency_s': latency}}
        name = f'{NAME}_graph_{resolution.lower()}' + (
            '' if latency == base else f'_latency_{round(latency * 1e3)}ms')
        specs.append(graph_spec(point, n, laws, duration_s, name=name, resolution=resolution))
        benches.append((point, n))
    records = study.run_studies(specs, out_dir, parallel=parallel, out=out)
    rows = []
    for spec, (point, n) in zip(specs, benches):
        pairs = [(task, law) for task in point['tasks'][:n] for law in laws]
        rows += [graph_row(task, law, record, point['conditions'])
                 for (task, law), record in zip(pairs, records[spec.name])]
    return rows


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m ibvs_experiments.vsbench``: run the benchmark, write the report."""
    parser = argparse.ArgumentParser(prog='ibvs vsbench',
                                     description='The workspace benchmark (module docstring).')
    parser.add_argument('--tasks', type=int, default=TASKS,
                        help=f'tasks through the model loop (default {TASKS})')
    parser.add_argument('--graph-tasks', type=int, default=100,
                        help='of those, the first M through the graph (default 100; 0: none)')
    parser.add_argument('--laws', default=','.join(LAWS), help='comma-separated laws')
    parser.add_argument('--workers', type=int, default=None,
                        help='model-loop processes (default: one per core)')
    parser.add_argument('--parallel', type=int, default=None,
                        help='graph runs at once on Ray (default: one per core)')
    parser.add_argument('--duration', type=float, default=None,
                        help=f"sim time per run (default the benchmark's, {DURATION_S} s)")
    parser.add_argument('--resolution', choices=tuple(FEATURE_NOISE_PX), default=None,
                        help="image size of both loops (default the benchmark's, "
                        f'{GRAPH_RESOLUTION})')
    parser.add_argument('--only', type=int, metavar='K', default=None,
                        help='run task K alone through the model loop, print its rows, exit')
    parser.add_argument('--measure-noise', action='store_true',
                        help='measure the feature noise at --resolution and exit')
    parser.add_argument('--benchmark', default=None, help='the benchmark file, or a '
                        f'version ({", ".join(VERSIONS)}: its committed file; default '
                        f'{BENCHMARK_FILE})')
    parser.add_argument('-o', '--out', default='results', help='report folder')
    parser.add_argument('--studies', default='results/studies',
                        help='parent of the graph study folder (its cache)')
    parser.add_argument('--write-definition', metavar='PATH', default=None,
                        help='write the benchmark file (all 500 tasks; the version '
                        '--benchmark names, default the newest) and exit')
    parser.add_argument('--latency', type=float, metavar='S', default=None,
                        help='camera latency of every run, feedback_latency_s (default the '
                        "benchmark's condition); with it no latency axis")
    parser.add_argument('--latencies', default=','.join(f'{x:g}' for x in LATENCY_AXIS),
                        help='the latency axis (s, comma-separated; default %(default)s, '
                        'with the mis-modelled points at 0.133 s); "" for the benchmark\'s '
                        'latency alone')
    parser.add_argument('--graph-latency-tasks', type=int, default=10,
                        help='of the graph tasks, the first K also at every other latency of '
                        'the axis (default %(default)s)')
    parser.add_argument('--latency-compensation', choices=LATENCY_COMPENSATIONS, default=None,
                        help="the feedback's design for the latency (default the benchmark's "
                        'condition: encoders; none: the laws as published)')
    args = parser.parse_args(argv)
    if args.write_definition:
        version = args.benchmark if args.benchmark in VERSIONS else VERSION
        data = write_definition(args.write_definition, version=version)
        print(f"wrote {len(data['tasks'])} tasks of {version} to {args.write_definition}")
        return 0
    resolution = args.resolution or GRAPH_RESOLUTION
    if args.measure_noise:
        noise, count, failed = measure_feature_noise(resolution)
        print(f'{resolution}: feature noise {noise:.4f} px ({count} detections, {failed} '
              'failed)')
        return 0
    bench = load(args.benchmark)
    overrides = {'feedback_latency_s': args.latency,
                 'latency_compensation': args.latency_compensation}
    bench['conditions'] = {**bench['conditions'],
                           **{k: v for k, v in overrides.items() if v is not None}}
    if not 0.0 <= bench['conditions']['feedback_latency_s'] <= 1.0:
        parser.error('--latency must be within [0, 1] s (feedback_latency_s)')
    resolution = args.resolution or bench['graph']['resolution']
    laws = tuple(law for law in args.laws.split(',') if law)
    if args.only is not None:
        for law in laws:
            row = model_run(bench['tasks'][args.only], law, bench['conditions'],
                            args.duration or bench['duration_s'], resolution)
            print(json.dumps(row))
        return 0
    if not 0 <= args.graph_tasks <= args.tasks <= len(bench['tasks']):
        parser.error(f"need 0 <= --graph-tasks <= --tasks <= {len(bench['tasks'])}")
    try:
        axis = () if args.latency is not None else tuple(
            float(x) for x in args.latencies.split(',') if x.strip())
    except ValueError:
        parser.error(f'--latencies must be numbers separated by commas, got {args.latencies!r}')
    if not all(0.0 <= x <= 1.0 for x in axis):
        parser.error('every --latencies value must be within [0, 1] s (feedback_latency_s)')
    base = bench['conditions']['feedback_latency_s']
    points = latency_points(axis) if axis else [(base, 0.0)]
    if not any(math.isclose(x, base) and e == 0.0 for x, e in points):
        points.insert(0, (base, 0.0))
    duration = args.duration or bench['duration_s']
    workers = args.workers or os.cpu_count() or 1
    start = time.monotonic()
    rows = screen(bench['tasks'][:args.tasks], laws, bench['conditions'], duration, workers,
                  resolution=resolution, points=points)
    walls = {'model': time.monotonic() - start}
    if args.graph_tasks:
        start = time.monotonic()
        rows += run_graph(bench, args.graph_tasks, Path(args.studies), laws, args.parallel,
                          duration, resolution=resolution, latencies=axis,
                          latency_tasks=args.graph_latency_tasks)
        walls['graph'] = time.monotonic() - start
    parallel = {'model': workers, 'graph': args.parallel or 0}
    if args.graph_tasks and not args.parallel:
        parallel['graph'] = default_parallel()
    reduced = args.tasks < TASKS or args.graph_tasks < 100
    meta = {'version': bench['version'], 'duration_s': duration,
            'conditions': bench['conditions'], 'resolution': resolution,
            'feature_noise_px': FEATURE_NOISE_PX[resolution],
            'tasks': args.tasks, 'graph_tasks': args.graph_tasks, 'laws': list(laws),
            'latency_points': [list(point) for point in points],
            'graph_latency_tasks': min(args.graph_latency_tasks, args.graph_tasks)
            if axis else 0,
            'scope': (f"{'A reduced run' if reduced else 'The full benchmark'}: "
                      f'{args.tasks} tasks x {len(laws)} laws x {len(points)} latency points '
                      f'through the model loop, the first {args.graph_tasks} x {len(laws)} '
                      'through the graph'
                      + (f', its first {min(args.graph_latency_tasks, args.graph_tasks)} at '
                         f'each other latency' if axis and args.graph_tasks else '')
                      + (f' (the benchmark is {TASKS} and 100).' if reduced else '.')),
            'timing': timing_lines(
                rows, walls, parallel, laws=len(laws), points=len(latency_points(LATENCY_AXIS)),
                graph_tasks=100 + 10 * sum(not math.isclose(x, base) for x in LATENCY_AXIS))}
    path = write_results(rows, args.out, meta)
    print(f'wrote {path}')
    for line in meta['timing']:
        print(line)
    return 0


if __name__ == '__main__':
    sys.exit(main())
