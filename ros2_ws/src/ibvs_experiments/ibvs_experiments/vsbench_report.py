"""
The workspace benchmark summed up: success rates with their intervals, the two loops side by side.

Per law and loop (:func:`summarise`): the success rate with its 95 % Wilson interval
(:func:`wilson`) and the medians and extremes of the runs' rows (:func:`.vsbench.run_metrics`);
per law, whether the model loop and the graph agree on their common tasks
(:func:`agreement`). :func:`write_results` writes ``vsbench.md``, the CSV and JSON of every
run and the figures; :func:`timing_lines` says what the run took and what the full
benchmark would.
"""

from collections.abc import Mapping, Sequence
import csv
import json
import math
from pathlib import Path
from typing import Any

from ibvs_analysis.convergence import SUCCESS
import numpy as np
from scipy import stats

from .vsbench_tasks import LAWS, SCENARIO, TASKS, VERSION


def wilson(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Return the Wilson interval of a rate (scipy's ``binomtest``); (nan, nan) for n = 0."""
    if n == 0:
        return float('nan'), float('nan')
    ci = stats.binomtest(int(successes), int(n)).proportion_ci(confidence, method='wilson')
    return float(ci.low), float(ci.high)


def _median(rows, key, only=None):
    values = [float(r[key]) for r in rows
              if r.get(key) is not None and (only is None or only(r))
              and math.isfinite(float(r[key]))]
    return float(np.median(values)) if values else float('nan')


def summarise(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """
    Return per (source, law): runs, successes, rate and its 95 % Wilson interval, medians.

    Medians over the successful runs for time to 1 mm; over all finished runs for overshoot,
    path-length ratio and peak speed ratio; sums of interventions and violations, and the
    smallest limit distance and clearances; the count of each miss class.
    """
    out = []
    keys = dict.fromkeys((r['source'], r['law']) for r in rows)
    for source, law in keys:
        group = [r for r in rows if r['source'] == source and r['law'] == law]
        done = [r for r in group if 'min_limit_distance_rad' in r]
        wins = sum(bool(r['success']) for r in group)
        low, high = wilson(wins, len(group))
        classes = {}
        for r in group:
            if not r['success']:
                classes[r['miss_reason']] = classes.get(r['miss_reason'], 0) + 1
        out.append({
            'source': source, 'law': law, 'runs': len(group), 'successes': wins,
            'rate': wins / len(group) if group else float('nan'), 'ci_low': low,
            'ci_high': high,
            'time_to_1mm_s': _median(group, 'time_to_1mm_s', lambda r: r['success']),
            'overshoot_m': _median(done, 'overshoot_m'),
            'path_length_ratio': _median(done, 'path_length_ratio'),
            'peak_speed_ratio': _median(done, 'peak_speed_ratio'),
            'peak_speed_ratio_max': max((r['peak_speed_ratio'] for r in done),
                                        default=float('nan')),
            'interventions': sum(r.get('interventions', 0) for r in done),
            'runs_with_interventions': sum(bool(r.get('interventions')) for r in done),
            'limit_violations': sum(r['limit_violations'] for r in done),
            'collisions': sum(r['collisions'] for r in done),
            'min_limit_distance_rad': min((r['min_limit_distance_rad'] for r in done),
                                          default=float('nan')),
            'min_self_clearance_m': min((r['min_self_clearance_m'] for r in done),
                                        default=float('nan')),
            'min_scene_clearance_m': min((r['min_scene_clearance_m'] for r in done),
                                         default=float('nan')),
            'miss_classes': classes,
        })
    return out


def agreement(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """
    Return per law, on the tasks both sources ran: each rate, interval, and whether they agree.

    Agree: each source's rate lies within the other's 95 % Wilson interval.
    """
    out = []
    for law in dict.fromkeys(r['law'] for r in rows):
        by = {s: {r['task']: r for r in rows if r['law'] == law and r['source'] == s}
              for s in ('model', 'graph')}
        common = sorted(set(by['model']) & set(by['graph']))
        if not common:
            continue
        entry = {'law': law, 'tasks': len(common)}
        for source in ('model', 'graph'):
            wins = sum(bool(by[source][t]['success']) for t in common)
            entry[source] = {'successes': wins, 'rate': wins / len(common),
                             'ci': wilson(wins, len(common))}
        m, g = entry['model'], entry['graph']
        entry['agree'] = bool(g['ci'][0] <= m['rate'] <= g['ci'][1]
                              and m['ci'][0] <= g['rate'] <= m['ci'][1])
        entry['same_verdict'] = sum(bool(by['model'][t]['success'])
                                    == bool(by['graph'][t]['success']) for t in common)
        out.append(entry)
    return out


# ------------------------------------------------------------------------------ the latency axis

#: A law fails at a latency when its success rate there falls below this.
FAILING_RATE = 0.95


def point_of(row: Mapping[str, Any]) -> tuple[float, float]:
    """Return a row's latency point: (``latency_s``, ``latency_error_s``), rounded to 1 us."""
    return (round(float(row.get('latency_s', float('nan'))), 6),
            round(float(row.get('latency_error_s', 0.0)), 6))


def at_point(rows: Sequence[Mapping[str, Any]], latency: float, error: float = 0.0
             ) -> list[Mapping[str, Any]]:
    """Return the rows of one latency point (the law assuming ``latency`` + ``error``)."""
    key = (round(float(latency), 6), round(float(error), 6))
    return [r for r in rows if point_of(r) == key]


def latency_axis(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """
    Return per (source, law, latency point): success with its interval, and medians.

    Over the successful runs: time to 1 mm and its excess over the task's time-optimal
    bound (``time_to_1mm_over_optimal_s``); over the finished runs: the bound, overshoot and
    the position error's ripple over the last 0.5 s. Sorted by source, law (in the order
    the rows hold them), latency and error.
    """
    out = []
    laws = list(dict.fromkeys(r['law'] for r in rows))  # in the order they ran
    keys = sorted({(r['source'], r['law']) + point_of(r) for r in rows},
                  key=lambda k: (('model', 'graph').index(k[0]) if k[0] in ('model', 'graph')
                                 else 2, laws.index(k[1]), k[2], k[3]))
    for source, law, latency, error in keys:
        group = [r for r in at_point(rows, latency, error)
                 if r['source'] == source and r['law'] == law]
        done = [r for r in group if 'min_limit_distance_rad' in r]
        wins = sum(bool(r['success']) for r in group)
        low, high = wilson(wins, len(group))
        out.append({'source': source, 'law': law, 'latency_s': latency,
                    'latency_error_s': error, 'runs': len(group), 'successes': wins,
                    'rate': wins / len(group), 'ci_low': low, 'ci_high': high,
                    'time_to_1mm_s': _median(group, 'time_to_1mm_s', lambda r: r['success']),
                    'excess_s': _median(group, 'time_to_1mm_over_optimal_s',
                                        lambda r: r['success']),
                    'time_optimal_s': _median(done, 'time_optimal_s'),
                    'overshoot_m': _median(done, 'overshoot_m'),
                    'ripple_m': _median(done, 'ripple_m')})
    return out


def first_failing(axis: Sequence[Mapping[str, Any]], rate: float = FAILING_RATE
                  ) -> dict[tuple[str, str], float | None]:
    """
    Return per (source, law) the first latency of the axis at which it fails, or None.

    Fails: its success rate below ``rate`` with the latency it assumes right (error 0).
    """
    out = {}
    for entry in axis:
        key = (entry['source'], entry['law'])
        out.setdefault(key, None)
        if entry['latency_error_s'] == 0.0 and out[key] is None and entry['rate'] < rate:
            out[key] = entry['latency_s']
    return out


def latency_table(axis: Sequence[Mapping[str, Any]]) -> list[str]:
    """Return the markdown lines of :func:`latency_axis` and :func:`first_failing`."""
    lines = ['| source | law | latency [ms] | assumed off by [ms] | runs | success | '
             '95 % interval | time to 1 mm [s] | over the bound [s] (bound) | '
             'overshoot [mm] | ripple, last 0.5 s [mm] |',
             '|---|---|---|---|---|---|---|---|---|---|---|']
    for e in axis:
        lines.append(
            f"| {e['source']} | {e['law']} | {e['latency_s'] * 1e3:.0f} | "
            f"{e['latency_error_s'] * 1e3:+.0f} | {e['runs']} | {e['successes']} "
            f"({_fmt(e['rate'], 100, 4)} %) | {_fmt(e['ci_low'], 100, 3)}-"
            f"{_fmt(e['ci_high'], 100, 3)} % | {_fmt(e['time_to_1mm_s'])} | "
            f"{_fmt(e['excess_s'])} ({_fmt(e['time_optimal_s'])}) | "
            f"{_fmt(e['overshoot_m'], 1e3)} | {_fmt(e['ripple_m'], 1e3)} |")
    lines += ['', f'First latency at which a law fails (success below '
              f'{100 * FAILING_RATE:g} %):', '']
    for (source, law), latency in first_failing(axis).items():
        lines.append(f'- {source} loop, `{law}`: '
                     + ('none on the axis' if latency is None else f'{latency * 1e3:.0f} ms'))
    return lines


def latency_figure(axis: Sequence[Mapping[str, Any]], out_dir: Path) -> Path:
    """Draw success (with its interval) and time to 1 mm against latency, per law and loop."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    laws = list(dict.fromkeys(e['law'] for e in axis))
    for source, style in (('model', '-o'), ('graph', 's')):
        for i, law in enumerate(laws):
            line = [e for e in axis if e['source'] == source and e['law'] == law
                    and e['latency_error_s'] == 0.0]
            if not line:
                continue
            x = np.array([e['latency_s'] for e in line]) * 1e3
            rate = np.array([e['rate'] for e in line]) * 100
            err = np.array([[e['rate'] - e['ci_low'], e['ci_high'] - e['rate']]
                            for e in line]).T * 100
            label = f'{law}, {source} loop (n = {line[0]["runs"]})'
            colour = f'C{i}'
            top.errorbar(x, rate, yerr=err, fmt=style, color=colour, capsize=3,
                         mfc='none' if source == 'graph' else colour, label=label)
            bottom.plot(x, [e['time_to_1mm_s'] for e in line], style, color=colour,
                        mfc='none' if source == 'graph' else colour, label=label)
            if source == 'model' and i == 0:  # one bound per task, whatever the law
                bottom.plot(x, [e['time_optimal_s'] for e in line], ':', color='grey',
                            label='time-optimal bound (median of the tasks)')
    top.axhline(100 * FAILING_RATE, color='grey', lw=0.8, ls='--')
    top.set_ylabel('success [%]')
    top.set_title('success and time to 1 mm against the camera latency')
    bottom.set_ylabel('time to 1 mm, median of successes [s]')
    bottom.set_xlabel('camera latency (feedback_latency_s) [ms]')
    for ax in (top, bottom):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    path = out_dir / 'vsbench_latency.png'
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


# ------------------------------------------------------------------------------ the report

CSV_COLUMNS = ('source', 'task', 'index', 'law', 'success', 'miss_reason',
               'final_position_error_m', 'final_tool_axis_error_deg', 'time_to_1mm_s',
               'overshoot_m', 'path_length_ratio', 'peak_speed_ratio', 'interventions',
               'min_limit_distance_rad', 'limit_violations', 'min_self_clearance_m',
               'min_scene_clearance_m', 'collisions', 'start_distance_m', 'start_angle_deg',
               'observability', 'latency_s', 'latency_error_s', 'time_optimal_s',
               'time_to_1mm_over_optimal_s', 'ripple_m', 'dropped_frames', 'wall_s',
               'miss_reason_text')


def _fmt(value, scale=1.0, digits=3):
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return '-'
    return f'{value * scale:.{digits}g}'


def summary_table(summary: Sequence[Mapping[str, Any]]) -> list[str]:
    """Return the markdown lines of :func:`summarise`."""
    lines = ['| source | law | runs | success | 95 % interval | time to 1 mm [s] | '
             'overshoot [mm] | path ratio | peak speed / rated (median, max) | '
             'interventions (runs) | min limit distance [deg] | limit violations | '
             'min clearance self / scene [mm] | collisions | misses |',
             '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for s in summary:
        misses = ', '.join(f'{k} {v}' for k, v in sorted(s['miss_classes'].items())) or '-'
        lines.append(
            f"| {s['source']} | {s['law']} | {s['runs']} | {s['successes']} "
            f"({_fmt(s['rate'], 100, 4)} %) | {_fmt(s['ci_low'], 100, 3)}-"
            f"{_fmt(s['ci_high'], 100, 3)} % | {_fmt(s['time_to_1mm_s'])} | "
            f"{_fmt(s['overshoot_m'], 1e3)} | {_fmt(s['path_length_ratio'])} | "
            f"{_fmt(s['peak_speed_ratio'])}, {_fmt(s['peak_speed_ratio_max'])} | "
            f"{s['interventions']} ({s['runs_with_interventions']}) | "
            f"{_fmt(s['min_limit_distance_rad'], 180 / math.pi)} | {s['limit_violations']} | "
            f"{_fmt(s['min_self_clearance_m'], 1e3)} / {_fmt(s['min_scene_clearance_m'], 1e3)}"
            f" | {s['collisions']} | {misses} |")
    return lines


def agreement_table(entries: Sequence[Mapping[str, Any]]) -> list[str]:
    """Return the markdown lines of :func:`agreement`."""
    lines = ['| law | common tasks | model | graph | agree | same verdict |',
             '|---|---|---|---|---|---|']
    for e in entries:
        cells = [f"{e[s]['successes']} ({100 * e[s]['rate']:.3g} %, "
                 f"{100 * e[s]['ci'][0]:.3g}-{100 * e[s]['ci'][1]:.3g} %)"
                 for s in ('model', 'graph')]
        lines.append(f"| {e['law']} | {e['tasks']} | {cells[0]} | {cells[1]} | "
                     f"{'yes' if e['agree'] else 'no'} | {e['same_verdict']} of "
                     f"{e['tasks']} |")
    return lines


def write_figures(rows: Sequence[Mapping[str, Any]], out_dir: Path) -> list[Path]:
    """Draw success against start distance and start angle, per source; failures marked."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    paths = []
    laws = list(dict.fromkeys(r['law'] for r in rows))
    sources = [s for s in ('model', 'graph') if any(r['source'] == s for r in rows)]
    for key, label, scale in (('start_distance_m', 'start distance [m]', 1.0),
                              ('start_angle_deg', 'start angle (tool axis) [deg]', 1.0)):
        fig, axes = plt.subplots(len(sources), 1, figsize=(8, 2.2 + 2.0 * len(sources)),
                                 squeeze=False)
        for ax, source in zip(axes[:, 0], sources):
            for i, law in enumerate(laws):
                group = [r for r in rows if r['source'] == source and r['law'] == law
                         and key in r]
                ok = [r[key] * scale for r in group if r['success']]
                bad = [r[key] * scale for r in group if not r['success']]
                ax.scatter(ok, [i] * len(ok), marker='o', s=14, color='tab:green',
                           label='success' if i == 0 else None)
                ax.scatter(bad, [i] * len(bad), marker='x', s=30, color='tab:red',
                           label='miss' if i == 0 else None)
            ax.set_yticks(range(len(laws)), laws)
            ax.set_ylim(-0.6, len(laws) - 0.4)
            ax.set_title(f'{source} loop: success against {label}')
            ax.set_xlabel(label)
            ax.grid(True, axis='x', alpha=0.3)
            ax.legend(loc='upper right', fontsize=8)
        fig.tight_layout()
        path = out_dir / f'vsbench_success_vs_{key.rsplit("_", 1)[0]}.png'
        fig.savefig(path, dpi=100)
        plt.close(fig)
        paths.append(path)
    return paths


def _teach_noise(conditions: Mapping[str, Any]) -> str:
    """Return the report's words for the noise of the taught target under ``conditions``."""
    frames = int(conditions.get('teach_frames', 1))
    if frames <= 1:
        return 'the taught target'
    return f'the taught target divided by sqrt({frames}), the mean of its {frames} frames'


def write_results(rows: Sequence[Mapping[str, Any]], out_dir: str | Path,
                  meta: Mapping[str, Any]) -> Path:
    """Write ``vsbench.md``, ``vsbench_runs.csv``, ``vsbench.json`` and the figures."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    conditions = meta.get('conditions') or {}
    base = at_point(rows, conditions.get('feedback_latency_s', float('nan')))
    summary = summarise(base)
    agree = agreement(base)
    axis = latency_axis(rows)
    latencies = sorted({point_of(r) for r in rows})
    axis_agree = [{**e, 'latency_s': x} for x, error in latencies if error == 0.0
                  for e in agreement(at_point(rows, x))]
    with open(out_dir / 'vsbench_runs.csv', 'w', newline='') as f:
        writer = csv.DictWriter(f, fieldnames=list(CSV_COLUMNS), extrasaction='ignore')
        writer.writeheader()
        for r in rows:
            writer.writerow(r)
    (out_dir / 'vsbench.json').write_text(json.dumps(
        {'meta': dict(meta), 'summary': summary, 'agreement': agree, 'latency_axis': axis,
         'latency_agreement': axis_agree, 'runs': list(rows)},
        indent=1, default=float) + '\n')
    figures = write_figures(base, out_dir)
    lines = [f"# {meta.get('version', VERSION)}: the workspace benchmark", '',
             f"{meta.get('scope', '')}", '',
             f"Success: {SUCCESS.describe()} at the end of {meta.get('duration_s')} s of sim "
             f"time. Conditions (every run): `{json.dumps(meta.get('conditions'))}`; per task "
             'its drawn calibration error and camera seed (the benchmark file). Model loop: '
             f"feature noise {meta.get('feature_noise_px')} px per value (measured, every "
             f'frame and {_teach_noise(meta.get("conditions") or {})}), lost frames held. '
             'Graph: '
             f"lockstep, `{SCENARIO}`'s rates and gains. Both at {meta.get('resolution')}.",
             '',
             '## Success per law', '',
             f"At the benchmark's latency, {1e3 * conditions.get('feedback_latency_s', 0):.0f}"
             ' ms.', ''] + summary_table(summary)
    if agree:
        lines += ['', '## Model loop against the graph (the tasks both ran)', '',
                  "Agree: each rate lies within the other's 95 % Wilson interval.", '']
        lines += agreement_table(agree)
    if len(latencies) > 1:
        figures.append(latency_figure(axis, out_dir))
        lines += ['', '## Across latencies', '',
                  'Every law at each latency (the feedback designed for it), and with the '
                  "latency it assumes off; the bound: per task, Ruckig's time-optimal move "
                  'from start to target under the same limits (`vsbench.time_optimal_s`); '
                  'the graph on its first tasks only (the table says how many).', '']
        lines += latency_table(axis)
        if axis_agree:
            head, rule, *body = agreement_table(axis_agree)
            lines += ['', 'The loops on their common tasks, per latency:', '',
                      '| latency [ms] ' + head, '|---' + rule]
            lines += [f"| {e['latency_s'] * 1e3:.0f} " + line
                      for e, line in zip(axis_agree, body)]
    lines += ['', '## Figures', ''] + [f'![{p.stem}]({p.name})' for p in figures]
    misses = [r for r in rows if not r['success']]
    if misses:
        lines += ['', '## Misses', '', '| source | task | law | class | why |',
                  '|---|---|---|---|---|']
        lines += [f"| {r['source']} | {r['task']} | {r['law']} | {r['miss_reason']} | "
                  f"{r.get('miss_reason_text', '')} |" for r in misses[:60]]
        if len(misses) > 60:
            lines.append(f'| ... | {len(misses) - 60} more in vsbench_runs.csv | | | |')
    timing = meta.get('timing')
    if timing:
        lines += ['', '## Time', ''] + [f'- {line}' for line in timing]
    path = out_dir / 'vsbench.md'
    path.write_text('\n'.join(lines) + '\n')
    return path


def timing_lines(rows: Sequence[Mapping[str, Any]], walls: Mapping[str, float],
                 workers: Mapping[str, int], tasks: int = TASKS, graph_tasks: int = 100,
                 laws: int = len(LAWS), points: int = 1) -> list[str]:
    """
    Return the measured times and the extrapolation to the full benchmark (as words).

    Full time = runs x mean wall time per run / runs at once, per stage:
    ``tasks x points x laws x t_model / workers + graph_tasks x laws x t_graph / parallel``
    (``points``: the model loop's latency points; ``graph_tasks``: the graph's runs per law,
    its latency axis counted in).
    """
    out = []
    total = 0.0
    for source, n in (('model', tasks * points), ('graph', graph_tasks)):
        group = [float(r['wall_s']) for r in rows if r['source'] == source and r.get('wall_s')]
        if not group:
            continue
        per_run = float(np.mean(group))
        full = n * laws * per_run / max(1, workers[source])
        total += full
        out.append(f'{source}: {len(group)} runs in {walls.get(source, float("nan")):.0f} s '
                   f'wall ({workers[source]} at once), {per_run:.2f} s per run (mean, '
                   f'median {np.median(group):.2f} s); full: {n} x {laws} x {per_run:.2f} s / '
                   f'{workers[source]} = {full / 60:.1f} min')
    if out:
        out.append(f'full benchmark, extrapolated: {total / 60:.1f} min '
                   f'({"within" if total <= 7200 else "over"} two hours)')
    return out
