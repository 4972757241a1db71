"""
``make bench``: the cost of each piece, and the real-time factor of the whole graph.

Each package's ``bench.run(report)`` times its own hot paths (physics step, stereo render,
detection per pair, feedback and joint-loop updates) and calls ``report(name, seconds)``
with per-iteration timings; those run pinned to one core. Then scenario 1 runs through the
graph for a short sim time and its real-time factor is printed. Figures go to stdout and
``bench/results.json``. Benchmarks print numbers; no test asserts on time.
"""

import argparse
import importlib
import json
import os
from pathlib import Path
import platform
import sys
import time

import numpy as np

PACKAGES = ('ibvs_sim.bench', 'ibvs_vision.bench', 'ibvs_control.bench')


class Table:
    """Collects timings and prints one line per benchmark."""

    def __init__(self):
        """Start with no rows."""
        self.rows = []

    def report(self, name, seconds):
        """Record per-iteration timings (s) of ``name`` and print median, p95 and count."""
        s = np.asarray(seconds, dtype=float)
        row = {'name': name, 'n': int(s.size), 'median_ms': float(np.median(s) * 1e3),
               'p95_ms': float(np.percentile(s, 95) * 1e3), 'min_ms': float(s.min() * 1e3)}
        self.rows.append(row)
        print(f"  {name:48s} median {row['median_ms']:9.3f} ms   p95 {row['p95_ms']:9.3f} ms"
              f"   (n={row['n']})", flush=True)


def main(argv=None):
    """Run every package benchmark, then the graph's real-time factor."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--graph-duration', type=float, default=1.0,
                        help='sim seconds of scenario 1 for the real-time factor (0: skip)')
    parser.add_argument('--out', default='bench', help='directory of results.json')
    args = parser.parse_args(argv)
    table = Table()
    print(f'machine: {platform.processor() or platform.machine()}, '
          f'{os.cpu_count()} cores, Python {platform.python_version()}')
    cores = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {min(cores)})
    print('per-piece timings, pinned to one core:')
    for module in PACKAGES:
        try:
            bench = importlib.import_module(module)
        except ImportError as exc:
            print(f'  {module}: not available ({exc})')
            continue
        bench.run(table.report)
    os.sched_setaffinity(0, cores)
    graph = None
    if args.graph_duration > 0:
        from . import runner
        print(f'graph: scenario 1 for {args.graph_duration:.2f} s of sim time, all cores')
        start = time.monotonic()
        result = runner.run_scenario('scenario1', Path(args.out) / 'graph_scenario1',
                                     duration_s=args.graph_duration,
                                     progress=lambda line: print(line, flush=True))
        graph = {k: result.metrics.get(k) for k in
                 ('sim_duration_s', 'wall_duration_s', 'real_time_factor')}
        graph['total_wall_s_with_startup'] = time.monotonic() - start
        print(f"  real-time factor {graph['real_time_factor']:.3f} "
              f"({graph['sim_duration_s']:.3f} s sim in {graph['wall_duration_s']:.1f} s wall)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / 'results.json').write_text(json.dumps({'pieces': table.rows, 'graph': graph},
                                                 indent=2) + '\n')
    print(f'wrote {out / "results.json"}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
