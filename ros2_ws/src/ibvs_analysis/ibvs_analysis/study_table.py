"""
A study's table and figures: each run's outcome from its record, and what decided it.

A study (ibvs_experiments.study) records every run in ``<run dir>/run.json``: its status
(``ok``, or the runner's failure and its ``reason``), its metrics (the run's
``metrics.json``, from its bag), its timings. This module reads those records: whether a
run succeeded (:func:`succeeded`, :data:`.convergence.SUCCESS`), why not
(:func:`why_missed`, in one category: :func:`miss_category`), and writes ``table.csv``,
``table.md`` and the figures of what decides success (:func:`write_results`).
"""

from collections.abc import Mapping, Sequence
import csv
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from .convergence import miss_reason, SUCCESS

#: Metrics in the study table, in this order: both deciding errors (1 mm, 0.5 deg), then
#: what the loop ran on: the feedback's time on model estimates, the joints' peak speed
#: against the IRB 4600's (docs/results.md, glossary).
TABLE_METRICS = ('final_position_error_m', 'final_tool_axis_error_deg', 'time_to_1mm_s',
                 'max_overshoot_m', 'time_estimated_s', 'peak_joint_speed_ratio')
#: Metrics of free-running runs only (:func:`.metrics.free_running_metrics`), in the table when a
#: run of the study has them: the camera-to-command latency, the real-time factor the
#: simulator held, the frames the controller used; and stale holds and interventions,
#: should the metrics carry them (none does yet).
OPTIONAL_METRICS = ('frame_latency_mean_s', 'frame_latency_max_s', 'real_time_factor_held_min',
                    'real_time_factor_held_mean', 'frames_used', 'stale_holds',
                    'interventions')


class Study(Protocol):
    """What the table reads of a study: its spec (ibvs_experiments.study_spec.Spec)."""

    name: str
    scenario: str
    description: str
    draws: Any

    def swept_names(self) -> list[str]:
        """Return the names of the parameters the study varies, in its order."""


def succeeded(record: Mapping[str, Any]) -> bool:
    """Return whether a run finished within :data:`.convergence.SUCCESS` (1 mm, 0.5 deg)."""
    return record.get('status') == 'ok' and SUCCESS.final(record.get('metrics') or {})


def why_missed(record: Mapping[str, Any]) -> str:
    """
    Return why a run is not a success ('' when it is one).

    A failed run: its failure (a node's death, a stall of the graph, ...: the runner's
    words); a finished run outside :data:`.convergence.SUCCESS`: what its metrics show
    (:func:`.convergence.miss_reason`: timed out, stalled, features lost, final errors).
    """
    if record.get('status') != 'ok':
        return f"run failed: {record.get('reason', '')}".strip()
    return miss_reason(record.get('metrics') or {}) or ''


#: ``miss_reason`` of a run, the first that applies (:func:`miss_category`); the words of
#: :func:`.convergence.miss_reason` and the runner's failures, shortened to one category.
MISS_CATEGORIES = (
    # (category, applies to a failed run's reason, to a finished run's reason)
    ('refused', ('exited with code 2', 'is invalid', 'refused'), ()),
    ('node died', ('node died', 'died'), ()),
    ('teach failed', ('teach',), ()),
    ('graph stalled', ('run stalled',), ()),
    ('no final pose', (), ('no final pose',)),
    ('lost features', (), ('features lost',)),
    ('local minimum', (), ('local minimum',)),
    ('stalled', (), ('stalled',)),
    ('timed out', (), ('timed out',)),
)


def miss_category(record: Mapping[str, Any]) -> str:
    """
    Return why a run is not a success in one or two words ('' for a success).

    From :func:`why_missed`: a failed run's runner words ('refused': a parameter or a rule
    refused at start; 'node died'; 'teach failed': the taught target could not be
    measured; 'graph stalled': no progress for ``--stall-s``; else 'failed'), a finished
    run's :func:`.convergence.miss_reason` ('no final pose', 'lost features', 'local
    minimum', 'stalled', 'timed out'). Joint limits, singularities and collisions are not
    told apart: no metric records them (a run that stops at one reads 'stalled').
    """
    reason = why_missed(record)
    if not reason:
        return ''
    return reason_category(reason, failed=record.get('status') != 'ok')


def reason_category(reason: str, failed: bool) -> str:
    """Return the :data:`MISS_CATEGORIES` category of a failed or finished run's reason."""
    for category, if_failed, if_finished in MISS_CATEGORIES:
        if any(word in reason for word in (if_failed if failed else if_finished)):
            return category
    return 'failed' if failed else 'missed'


#: Record fields that are timings of the machine, not results of the run: in the study's
#: table.csv, and in table.md under a heading of their own.
TIMING_COLUMNS = ('wall_s', 'cpu_s')


def table_rows(spec: Study, records: Sequence[Mapping[str, Any]]
               ) -> list[dict[str, Any]]:
    """
    Return the study table as dicts: run, swept parameters, metrics, status, wall time.

    ``success``: :func:`succeeded`; ``reason``: :func:`why_missed`.
    """
    optional = [k for k in OPTIONAL_METRICS
                if any(k in (r.get('metrics') or {}) for r in records)]
    rows = []
    for record in records:
        metrics = record.get('metrics') or {}
        row = {'run': record['index']}
        row.update({name: record['swept'].get(name, '') for name in spec.swept_names()})
        row.update({k: metrics.get(k) for k in TABLE_METRICS + tuple(optional)})
        row.update(status=record['status'], success=succeeded(record),
                   miss_reason=miss_category(record),
                   attempts=record.get('attempts', 1),
                   wall_s=record.get('wall_s'), cpu_s=record.get('cpu_s'),
                   reason=why_missed(record),
                   run_dir=record['run_dir'])
        rows.append(row)
    return rows


def _cell(value):
    if value is None:
        return '-'
    if isinstance(value, float):
        return f'{value:.6g}'
    return str(value).replace('|', '/')


def write_results(spec: Study, records: Sequence[Mapping[str, Any]],
                  study_dir: str | Path) -> list[dict[str, Any]]:
    """
    Write ``table.csv``, ``table.md`` and the figures of one study; return the rows.

    ``table.md``: the runs' results (from each run's bag: ``metrics.json``), then the
    machine's timings of each run in a table of their own.
    """
    study_dir = Path(study_dir)
    study_dir.mkdir(parents=True, exist_ok=True)
    rows = table_rows(spec, records)
    with open(study_dir / 'table.csv', 'w', newline='') as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    columns = [c for c in rows[0] if c != 'run_dir' and c not in TIMING_COLUMNS]
    ok = sum(r['success'] for r in rows)
    lines = [f'# Study {spec.name}', '', spec.description, '',
             f'Scenario {spec.scenario}, {len(rows)} runs, '
             f"{sum(r['status'] != 'ok' for r in rows)} failed, success (final error within "
             f'{SUCCESS.describe()}, `ibvs_analysis.convergence.SUCCESS`): '
             f"{ok}/{len(rows)}. Source: each run's bag (graph run), read by "
             '`ibvs analyse`; `reason`: why a run is not a success. The metrics are defined '
             'in docs/results.md (glossary).',
             '', '| ' + ' | '.join(columns) + ' |', '|' + '---|' * len(columns)]
    lines += ['| ' + ' | '.join(_cell(r[c]) for c in columns) + ' |' for r in rows]
    figures = write_figures(spec, rows, study_dir)
    lines += [''] + [f'![{p.stem}]({p.name})' for p in figures] + ['']
    lines += ['## Machine timings', '',
              'Wall and CPU seconds of each run on the machine that ran it (not results of '
              'the loop: they change with the machine and its load).', '',
              '| run | ' + ' | '.join(TIMING_COLUMNS) + ' |',
              '|---|' + '---|' * len(TIMING_COLUMNS)]
    lines += ['| ' + ' | '.join(_cell(r[c]) for c in ('run',) + TIMING_COLUMNS) + ' |'
              for r in rows]
    (study_dir / 'table.md').write_text('\n'.join(lines + ['']))
    return rows


#: What decides a run's success, as the study figures draw it: (row key, label, scale to
#: the axis unit, the tolerance of :data:`.convergence.SUCCESS` in that unit, the unit).
DECIDING_ERRORS = (
    ('final_position_error_m', 'final position error [mm]', 1e3, 1e3 * SUCCESS.position_m,
     'mm'),
    ('final_tool_axis_error_deg', 'final tool-axis error [deg]', 1.0, SUCCESS.axis_deg, 'deg'))


def _plotted(value, scale):
    """Return ``value * scale`` for a log axis (NaN when absent), floored at 1e-9."""
    if value is None or not np.isfinite(value):
        return float('nan')
    return max(value * scale, 1e-9)


def _error_panels(ax_pair, rows, x_of, xlabel, plt):
    """
    Draw both deciding errors of ``rows`` against ``x_of(row)`` on ``ax_pair``.

    Successes as green dots, finished runs outside :data:`.convergence.SUCCESS` as orange
    squares, failed runs as red crosses on the top edge; each tolerance a dashed line.
    """
    for ax, (key, label, scale, tolerance, unit) in zip(ax_pair, DECIDING_ERRORS):
        for which, style, colour, name in (
                (lambda r: r['success'], 'o', 'tab:green', 'success'),
                (lambda r: r['status'] == 'ok' and not r['success'], 's', 'tab:orange',
                 f'finished outside {SUCCESS.describe()}')):
            sel = [r for r in rows if which(r)]
            if sel:
                ax.plot([x_of(r) for r in sel], [_plotted(r[key], scale) for r in sel],
                        style, color=colour, label=name, ms=6)
        bad = [r for r in rows if r['status'] != 'ok']
        if bad:
            ax.plot([x_of(r) for r in bad], [1.0] * len(bad), 'x', color='tab:red', ms=10,
                    mew=2, transform=ax.get_xaxis_transform(), clip_on=False,
                    label='failed run (no metrics)')
        ax.axhline(tolerance, color='black', ls='--', lw=1,
                   label=f'success: within {tolerance:g} {unit}')
        ax.set_yscale('log')
        ax.set_xlabel(xlabel)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3, which='both')
    ax_pair[0].legend(fontsize=8)


def write_figures(spec: Study, rows: Sequence[Mapping[str, Any]],
                  study_dir: Path) -> list[Path]:
    """
    Draw what decides each run against each swept parameter, CDFs for draws, the outcomes.

    ``error_vs_<name>.png``: the final position and tool-axis errors against a numeric swept
    parameter (not a seed: a seed's value says nothing), with :data:`.convergence.SUCCESS`'s
    tolerances and the misses and failures marked; ``error_cdf.png`` for draws: both errors'
    distributions; ``success_rate.png``: successes, misses and failures. Returns the paths.
    """
    # Here, not at import: every `ibvs` command imports this module for its defaults, and
    # pyplot costs seconds of start-up.
    from .plots import plt
    paths = []
    for name in spec.swept_names():
        sel = [r for r in rows if r[name] != '']
        if (not sel or name.endswith('seed')
                or not all(isinstance(r[name], (int, float)) for r in sel)):
            continue
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        _error_panels(axes, sel, lambda r: r[name], name, plt)
        fig.suptitle(f'{spec.name}: what decides success against {name}')
        paths.append(_save(fig, study_dir / f'error_vs_{name}.png'))
    finished = [r for r in rows if r['status'] == 'ok']
    if spec.draws and finished:
        fig, axes = plt.subplots(1, 2, figsize=(11, 4))
        for ax, (key, label, scale, tolerance, unit) in zip(axes, DECIDING_ERRORS):
            values = np.sort([_plotted(r[key], scale) for r in finished])
            ax.step(values, np.arange(1, values.size + 1) / len(rows), where='post')
            ax.axvline(tolerance, color='black', ls='--', lw=1,
                       label=f'success: within {tolerance:g} {unit}')
            ax.set_xscale('log')
            ax.set_xlabel(label)
            ax.set_ylabel('fraction of all runs')
            ax.grid(alpha=0.3, which='both')
            ax.legend(fontsize=8)
        fig.suptitle(f'{spec.name}: CDF over {len(rows)} runs (failed runs never reach 1)')
        paths.append(_save(fig, study_dir / 'error_cdf.png'))
    missed = sum(r['status'] == 'ok' and not r['success'] for r in rows)
    counts = {'success': sum(r['success'] for r in rows),
              f'outside {SUCCESS.describe()}': missed,
              'failed run': sum(r['status'] != 'ok' for r in rows)}
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.bar(list(counts), list(counts.values()),
           color=['tab:green', 'tab:orange', 'tab:red'])
    ax.set_ylabel('runs')
    ax.set_title(f"{spec.name}: success rate {counts['success']}/{len(rows)} "
                 f"({100 * counts['success'] / len(rows):.0f} %)")
    paths.append(_save(fig, study_dir / 'success_rate.png'))
    return paths


def _save(fig, path):
    from .plots import plt
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
