"""
``make bench``: the cost of each piece, and the real-time factor of the whole graph.

Each package's ``bench.run(report)`` times its own hot paths (physics step, stereo render,
detection per pair, feedback and joint-loop updates) and calls ``report(name, seconds)``
with per-iteration timings; those run pinned to one core. Then scenario 1 runs through the
whole graph (every node its own process, as ``ibvs run`` starts them) for one simulated
second, at HD720 and at VGA, and the bench prints the wall time per simulated second and
where it goes: each node times its hot sections (:mod:`ibvs_common.profiling`) and
publishes the totals on /diagnostics, which the run records; the recorder times itself.
The graph runs ``--runs`` times per resolution (medians against the targets below, the
load average printed before each run; the simulator's one renderer, ibvs_sim.gl_renderer,
on the device it chose, which the run's metrics name). The accuracy of the features
(:func:`ibvs_analysis.analysis.feature_errors`), and the wall time of a
0.3 s ``ibvs run`` (start-up, run, stop, analysis, figures), are printed
against their targets too (the short run's target is start to metrics: until
``metrics.json`` is written; start to exit, with the figures, is printed beside it). Last,
the nodes alone against a real cell's clock (:mod:`.nodes_bench`): a recorded
real-cell run replayed on the wall clock into the feature, feedback, feedforward and
joint-controller nodes, at HD720 and VGA, its servo part (both markers in view: the
detector's windows around the predicted markers, the hot path of a run) at 30 and 60 Hz
and its lost part (the slew before the markers are in view: a full search every frame)
at 30 Hz, each apart: frame-to-command latency (mean, p95, max) and each node's CPU,
against the targets below, each after the split of the feature node's CPU a frame
(deserialisation, the detector's stages, the node's own handling of the messages:
:func:`.nodes_bench.frame_split`). ``--only`` runs some of the parts (``--only nodes-alone``:
the nodes alone and nothing else). Figures go to stdout and ``bench/results.json``.
Benchmarks print numbers; no test asserts on time.
"""

import argparse
from collections.abc import Sequence
import importlib
import json
import os
from pathlib import Path
import platform
import subprocess
import sys
import tempfile
import time
from typing import Any

import numpy as np

PACKAGES = ('ibvs_sim.bench', 'ibvs_vision.bench', 'ibvs_control.bench')
#: Sections of the graph breakdown: (node, section, what it is). Per simulated second.
BREAKDOWN = (
    ('sim_node', 'render', 'rendering (both lenses)'),
    ('sim_node', 'image_messages', 'image messages: build and publish'),
    ('sim_node', 'physics', 'physics steps'),
    ('sim_node', 'tool_path', 'tool poses (evaluation only): FK, batch, publish'),
    ('sim_node', 'step_messages', 'per-step messages (/clock, /joint_states): build, publish'),
    ('feature_node', 'detection', 'detection (Hough, stereo)'),
    ('adaptive_feedback_node', 'feedback_update', 'feedback update (F^-1, C1, SVD)'),
    ('joint_controller_node', 'joint_loop', 'joint loop (M, h, G_c)'),
    ('sim_node', 'lockstep_round_trip', 'lockstep round trips (/joint_states out, command in)'),
    ('recorder', 'recording', 'recording (another process, off the lockstep)'),
)
#: The targets on the 2-core machine of docs/speed.md: the lockstep round trip per physics
#: step (ms), the wall time per simulated second of scenario 1 by resolution (s), the
#: median feature error against the true projection (px), and the wall time of a 0.3 s
#: ``ibvs run`` from start to metrics (s).
ROUND_TRIP_MS_TARGET = 0.5
WALL_PER_SIM_S_TARGET = {'HD720': 1.0, 'VGA': 0.6}
FEATURE_ERROR_PX_TARGET = 0.05
SHORT_RUN_S = 0.3
SHORT_RUN_WALL_S_TARGET = 4.75
#: Floors of the graph's parts (ms a pass): the lockstep round trip of this layout in one
#: process; rendering: the same pair rendered alone (ibvs_sim.bench, pinned to one core, so
#: on two idle cores the graph's render can come in under it).
ROUND_TRIP_FLOOR_MS = 0.09
#: The targets of the nodes alone: on the servo part of a run (the hot path), the
#: frame-to-command latency p95 (ms) at every camera rate, and the feature node's CPU a
#: frame (ms); on any part, the p95 within one frame period.
NODES_ALONE_SERVO_P95_MS_TARGET = 8.0
NODES_ALONE_FEATURE_CPU_MS_TARGET = 4.0
#: The parts of the bench (``--only``).
PARTS = ('pieces', 'graph', 'short-run', 'nodes-alone')


class Table:
    """Collects timings and prints one line per benchmark."""

    def __init__(self) -> None:
        """Start with no rows."""
        self.rows = []

    def report(self, name: str, seconds: Sequence[float]) -> None:
        """Record per-iteration timings (s) of ``name`` and print median, p95 and count."""
        s = np.asarray(seconds, dtype=float)
        row = {'name': name, 'n': int(s.size), 'median_ms': float(np.median(s) * 1e3),
               'p95_ms': float(np.percentile(s, 95) * 1e3), 'min_ms': float(s.min() * 1e3)}
        self.rows.append(row)
        print(f"  {name:48s} median {row['median_ms']:9.3f} ms   p95 {row['p95_ms']:9.3f} ms"
              f"   (n={row['n']})", flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    """Run every package benchmark, then the graph's real-time factor."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--graph-duration', type=float, default=1.0,
                        help='sim seconds of scenario 1 for the real-time factor (0: skip)')
    parser.add_argument('--out', default='bench', help='directory of results.json')
    parser.add_argument('--runs', type=int, default=3,
                        help=f'graph runs per resolution and {SHORT_RUN_S} s runs for the '
                        'start-up (medians)')
    parser.add_argument('--nodes-alone-s', type=float, default=20.0,
                        help='wall seconds of replay into the nodes alone per resolution '
                        '(0: skip)')
    parser.add_argument('--nodes-alone-record-s', type=float, default=5.0,
                        help='sim seconds of the real-cell run recorded for the replay (once '
                        'per resolution: a bag in OUT/nodes_alone/<resolution> is used '
                        'again); the slew and the servo part of real_cell need 5 s')
    parser.add_argument('--nodes-alone-resolutions', nargs='+', default=['HD720', 'VGA'],
                        choices=('HD720', 'VGA'), help='resolutions of the nodes alone')
    parser.add_argument('--nodes-alone-rates', nargs='+', type=float, default=[30.0, 60.0],
                        help='camera rates (Hz) the servo part is replayed at (the lost '
                        'part: the first)')
    parser.add_argument('--nodes-alone-segments', nargs='+', default=['servo', 'lost'],
                        choices=('servo', 'lost', 'all'),
                        help="parts of the bag replayed: 'servo' (both markers in view), "
                        "'lost' (the slew before it), 'all' (the whole bag)")
    parser.add_argument('--only', nargs='+', choices=PARTS, default=list(PARTS),
                        help='run only these parts of the bench')
    args = parser.parse_args(argv)
    table = Table()
    print(f'machine: {platform.processor() or platform.machine()}, '
          f'{os.cpu_count()} cores, Python {platform.python_version()}')
    if 'pieces' in args.only:
        pieces(table)
    graph = {}
    if args.graph_duration > 0 and 'graph' in args.only:
        for resolution in ('HD720', 'VGA'):
            graph[resolution] = repeated_graph(resolution, args.graph_duration,
                                               Path(args.out), args.runs, table)
    short = short_run(args.runs) if args.runs > 0 and 'short-run' in args.only else {}
    alone = {}
    if args.nodes_alone_s > 0 and 'nodes-alone' in args.only:
        for resolution in args.nodes_alone_resolutions:
            alone[resolution] = nodes_alone(resolution, Path(args.out) / 'nodes_alone',
                                            args.nodes_alone_s, args.nodes_alone_record_s,
                                            args.nodes_alone_rates, args.nodes_alone_segments)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'results.json').write_text(json.dumps(
        {'pieces': table.rows, 'graph': graph, 'short_run': short, 'nodes_alone': alone},
        indent=2) + '\n')
    print(f'wrote {out / "results.json"}')
    return 0


def _load():
    """Return the 1-minute load average, as text."""
    return f'{os.getloadavg()[0]:.2f}'


def pieces(table: Table) -> None:
    """Time each package's hot paths, pinned to one core (module docstring)."""
    cores = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(cores)})
    print('per-piece timings, pinned to one core:')
    try:
        for module in PACKAGES:
            try:
                bench = importlib.import_module(module)
            except ImportError as exc:
                print(f'  {module}: not available ({exc})')
                continue
            if module == 'ibvs_vision.bench':
                # the detector on the simulator's images too (ibvs_vision does not import it)
                sim = importlib.import_module('ibvs_sim.bench')
                bench.run(table.report, render=sim.stereo_frames)
            else:
                bench.run(table.report)
    finally:
        os.sched_setaffinity(0, cores)


def nodes_alone(resolution: str, out_dir: Path, replay_s: float, record_s: float,
                rates_hz: Sequence[float] = (30.0,),
                segments: Sequence[str] = ('servo', 'lost')) -> dict[str, Any]:
    """
    Measure the nodes alone at ``resolution`` (:mod:`.nodes_bench`) against the targets.

    The servo part at each of ``rates_hz``, the others at the first; each result keyed
    '<part> <rate> Hz'.
    """
    from . import nodes_bench
    out = {}
    for which in segments:
        rates = rates_hz if which == 'servo' else rates_hz[:1]
        for result in nodes_bench.measure(resolution, out_dir, replay_s, record_s,
                                          rates_hz=rates, segments=[which], split=True):
            rate = result['camera_rate_hz']
            targets = {}
            if result.get('latency_p95_ms') is not None:
                where = f'{resolution}, {which} part at {rate:g} Hz'
                targets['frames_used'] = _target(
                    f'frames without a command at {where}',
                    result['frames_sent'] - result['frames_used'], 0, 'frames')
                targets['period'] = _target(
                    f'frame-to-command latency p95 at {where}, within a frame period',
                    result['latency_p95_ms'], 1e3 / rate, 'ms')
                if which == 'servo':
                    targets['latency_p95_ms'] = _target(
                        f'frame-to-command latency p95 at {where}', result['latency_p95_ms'],
                        NODES_ALONE_SERVO_P95_MS_TARGET, 'ms')
                    targets['feature_cpu_ms'] = _target(
                        f'feature node CPU a frame at {where}',
                        result['cpu']['feature_node']['ms_per_frame'],
                        NODES_ALONE_FEATURE_CPU_MS_TARGET, 'ms')
            result['targets'] = targets
            out[f'{which} {rate:g} Hz'] = result
    return out


def repeated_graph(resolution: str, duration_s: float, out_dir: Path, runs: int,
                   table: Table) -> dict[str, Any]:
    """Run the graph ``runs`` times; print medians against targets."""
    results = [graph_breakdown(resolution, duration_s, out_dir, table)
               for _ in range(max(runs, 1))]
    per_sim = float(np.median([r['wall_s_per_sim_s'] for r in results]))
    print(f'graph at {resolution}, median of {len(results)} runs '
          f'(load averages {", ".join(r["load_average"] for r in results)}):')
    targets = {'wall_s_per_sim_s': _target(
        f'wall time per simulated second at {resolution}', per_sim,
        WALL_PER_SIM_S_TARGET[resolution], 's')}
    errors = [r['feature_error_median_px'] for r in results
              if r.get('feature_error_median_px') is not None]
    if errors:
        targets['feature_error_median_px'] = _target(
            'median feature error against the true projection', float(np.median(errors)),
            FEATURE_ERROR_PX_TARGET, 'px')
    return {'runs': results, 'wall_s_per_sim_s_median': per_sim, 'targets': targets}


def short_run(runs: int) -> dict[str, Any]:
    """
    Time ``ibvs run scenario1 --duration 0.3``: start to metrics, and start to exit.

    Start to metrics: until ``metrics.json`` exists (the run's start, the run, its stop and
    its analysis); start to exit adds the figures.
    """
    to_metrics, to_exit = [], []
    for _ in range(runs):
        with tempfile.TemporaryDirectory(prefix='ibvs_bench_') as tmp:
            load = _load()
            metrics = Path(tmp) / 'metrics.json'
            start = time.perf_counter()
            proc = subprocess.Popen([sys.executable, '-m', 'ibvs_experiments.cli', 'run',
                                     'scenario1', '--duration', str(SHORT_RUN_S), '-o', tmp],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            seen = None
            while proc.poll() is None:
                if seen is None and metrics.exists():
                    seen = time.perf_counter() - start
                time.sleep(0.005)
            to_exit.append(time.perf_counter() - start)
            to_metrics.append(seen if seen is not None else float('nan'))
        print(f'short run: {SHORT_RUN_S} s ibvs run, metrics after {to_metrics[-1]:.2f} s, '
              f'exit after {to_exit[-1]:.2f} s of wall time (exit code {proc.returncode}, '
              f'load average {load})', flush=True)
    wall = float(np.median(to_metrics))
    return {'walls_s': to_exit, 'wall_s_median': float(np.median(to_exit)),
            'to_metrics_s': to_metrics, 'to_metrics_s_median': wall,
            'target': _target(f'a {SHORT_RUN_S} s ibvs run, start to metrics (median of '
                              f'{runs})', wall, SHORT_RUN_WALL_S_TARGET, 's')}


def graph_breakdown(resolution: str, duration_s: float, out_dir: Path,
                    table: Table | None = None) -> dict[str, Any]:
    """Run scenario 1 through the graph; print and return wall time per sim second by part."""
    from ibvs_analysis import analysis

    from . import runner
    overrides = {'resolution': resolution}
    load = _load()
    print(f'graph: scenario 1 at {resolution}, {duration_s:.2f} s of sim time, all cores, '
          f'load average {load}')
    name = f'graph_scenario1_{resolution}'
    result = runner.run_scenario('scenario1', out_dir / name,
                                 overrides=overrides, duration_s=duration_s,
                                 progress=lambda line: print(line, flush=True))
    sim_s, wall_s = result.metrics['sim_duration_s'], result.metrics['wall_duration_s']
    timings = analysis.node_timings(result.bag_path)
    timings['recorder'] = {
        'sim_time_s': float(result.recording.get('profiled_sim_time_s', 0.0)),
        'sections': {'recording': (float(result.recording.get('wall[recording]_s', 0.0)),
                                   int(result.recording.get('count[recording]', 0)))}}
    rows = []
    for node, section, label in BREAKDOWN:
        entry = timings.get(node, {})
        total, count = entry.get('sections', {}).get(section, (0.0, 0))
        covered = entry.get('sim_time_s', 0.0)
        per_sim_s = total / covered if covered > 0 else float('nan')
        per_pass_ms = total / count * 1e3 if count else float('nan')
        floor = _floor_ms(section, resolution, table)
        rows.append({'node': node, 'section': section, 'what': label,
                     'wall_s_per_sim_s': per_sim_s, 'per_pass_ms': per_pass_ms,
                     'passes': count, 'sim_time_s': covered, 'floor_ms': floor})
        floor_text = f'   floor {floor:8.3f} ms' if floor is not None else ''
        print(f'  {label:58s} {per_sim_s:7.3f} s per sim s   {per_pass_ms:8.3f} ms x {count}'
              + floor_text)
    per_sim = wall_s / sim_s
    print(f'  {"wall time per simulated second (total)":58s} {per_sim:7.3f} s '
          f'(real-time factor {sim_s / wall_s:.3f}; {sim_s:.3f} s sim in {wall_s:.1f} s; '
          f'rendered on {result.metrics.get("render_device", "?")})')
    targets = {}
    trip = next(r['per_pass_ms'] for r in rows if r['section'] == 'lockstep_round_trip')
    targets['round_trip_ms'] = _target('lockstep round trip', trip, ROUND_TRIP_MS_TARGET, 'ms')
    errors = analysis.feature_errors(analysis.load_run(result.bag_path))
    median_error = float(np.median(np.abs(errors))) if errors.size else None
    if median_error is not None:
        print(f'  {"features against the true projection, median |error|":58s} '
              f'{median_error:7.4f} px ({len(errors)} measured frames)')
    return {'resolution': resolution, 'render_device': result.metrics.get('render_device'),
            'render_hardware': result.metrics.get('render_hardware'), 'load_average': load,
            'sim_duration_s': sim_s, 'wall_duration_s': wall_s,
            'wall_s_per_sim_s': per_sim, 'real_time_factor': sim_s / wall_s,
            'final_position_error_m': result.metrics.get('final_position_error_m'),
            'final_tool_axis_error_deg': result.metrics.get('final_tool_axis_error_deg'),
            'feature_error_median_px': median_error, 'breakdown': rows, 'targets': targets}


def _floor_ms(section, resolution, table):
    """Return the floor (ms a pass) of a graph section where one is known, else None."""
    if section == 'lockstep_round_trip':
        return ROUND_TRIP_FLOOR_MS
    if section == 'render' and table is not None:
        wanted = f'sim: stereo pair {resolution} (opengl, simulator default'
        for row in table.rows:
            if row['name'].startswith(wanted):
                return row['median_ms']
    return None


def _target(what, value, limit, unit):
    """Print whether ``value`` is within ``limit``; return both and the verdict."""
    met = bool(value <= limit)
    print(f'  target: {what} at most {limit:g} {unit}: {value:.3f} {unit}, '
          f'{"met" if met else "NOT met"}')
    return {'value': value, 'limit': limit, 'met': met}


if __name__ == '__main__':
    sys.exit(main())
