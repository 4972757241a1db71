"""
The reproduction report: scenarios 1-3 and the L2/L4 robustness sweep (paper Figure 13).

Every number in ``results/report.md`` comes from a run's ``metrics.json``, which comes from
its bag; the table puts each claim of the paper next to what we measured.

Every run is part of a study (:mod:`ibvs_experiments.study`): the studies named in
:data:`REPORT_STUDIES` (spec files in ``ibvs_experiments/studies/``, installed to the package's
share directory) run together on one Ray session, cached, into ``<out>/studies/<name>/``.
To add a study to the report, add its spec file there and its name to
:data:`EXTRA_STUDIES`: the report then shows its table and figures.
"""

from collections.abc import Mapping, Sequence
import dataclasses
import json
from pathlib import Path
from typing import Any

from ibvs_analysis import study_table
from ibvs_analysis.convergence import SUCCESS
from ibvs_control.servo_laws import SERVO_LAWS
import matplotlib

matplotlib.use('Agg')

import matplotlib.pyplot as plt  # noqa: E402

from . import laws_report, study, study_spec  # noqa: E402

SCENARIO_STUDIES = ('scenario1', 'scenario2', 'scenario3')
SWEEP_STUDY = 'fig13_link_lengths'
#: Studies beyond the paper's that the report shows as they are (table and figures).
EXTRA_STUDIES = ()
REPORT_STUDIES = SCENARIO_STUDIES + (SWEEP_STUDY,) + EXTRA_STUDIES
#: The sweep factors of ``--quick``: the endpoints and nominal.
QUICK_SCALES = (0.5, 1.0, 1.1)


def _fmt(value, unit='', scale=1.0, digits=3):
    if value is None:
        return 'not reached'
    return f'{value * scale:.{digits}f}{unit}'


#: What the report reads as the paper's "small overshoot" (scenario 1), m.
SMALL_OVERSHOOT_M = 0.005
#: The law whose limited-actuator runs (:data:`.laws_report.CASES` 'limited') the claims
#: table sets beside the ideal ones: the paper's.
PAPER_LAW = SERVO_LAWS[0]
#: Metrics that are timings of the machine (wall time), not of the loop: the report lists
#: them in a section of their own, never in a results table.
TIMING_KEYS = ('wall_duration_s', 'real_time_factor', 'real_time_factor_held_mean',
               'real_time_factor_held_min')


def _verdict(ok, why=''):
    return ('met' if ok else 'not met') + (f' ({why})' if why else '')


def actuators_text(case: str, metrics: Mapping[str, Any]) -> str:
    """
    Return a claims-table cell: the actuators of a run and how hard they were driven.

    ``case``: 'ideal' or 'limited' (:data:`.laws_report.CASES`); the peak joint speed and
    torque as multiples of the IRB 4600's rated speed and estimated torque limit
    (``peak_joint_speed_ratio``, ``peak_joint_torque_ratio``: 1 is the real arm's limit).
    """
    latency = laws_report.CASES['limited']['feedback_latency_s']
    words = {'ideal': 'ideal (unlimited)',
             'limited': f"IRB 4600's limits, {latency:g} s latency"}.get(case, case)
    speed, torque = metrics.get('peak_joint_speed_ratio'), metrics.get('peak_joint_torque_ratio')
    peaks = []
    if speed is not None:
        peaks.append(f'peak joint speed {speed:.3g}x rated')
    if torque is not None:
        peaks.append(f'torque {torque:.3g}x the estimated limit')
    return words + (': ' + ', '.join(peaks) if peaks else '')


def _fast(m):
    t1, settle = m['time_to_1mm_s'], m['settling_time_2pct_s']
    return (f'2 % settling {_fmt(settle, " s")}, within 1 mm from {_fmt(t1, " s")}',
            settle is not None and settle <= 0.3,
            '2 % settling' + ('' if t1 is not None and t1 <= 0.3 else '; 1 mm takes longer'))


def _overshoot(m):
    return (_fmt(m['max_overshoot_m'], ' mm', 1e3, 2),
            m['max_overshoot_m'] <= SMALL_OVERSHOOT_M,
            f'at most {SMALL_OVERSHOOT_M * 1e3:g} mm read as small')


def _final(m):
    return (f'{_fmt(m["final_position_error_m"], " mm", 1e3, 4)}, axis '
            f'{_fmt(m["final_tool_axis_error_deg"], " deg", 1.0, 4)}',
            SUCCESS.final(m), f'within {SUCCESS.describe()}')


def _out_of_view(m):
    t = m['time_to_1mm_s']
    return (f'1 mm at {_fmt(t, " s")}, overshoot {_fmt(m["max_overshoot_m"], " mm", 1e3, 1)}, '
            f'estimated for {_fmt(m["time_estimated_s"], " s")}',
            t is not None and t < 1.0, 'within 1 mm in under 1 s')


def _decide(test, ideal, limited):
    """
    Return (measured, actuators, verdict) of one claim: ideal actuators, then the limits'.

    ``test(metrics)`` -> (measured text, met, why); ``limited``: the metrics of the same
    scenario with the IRB 4600's limited actuators, or None (not run).
    """
    text, ok, why = test(ideal)
    actuators = actuators_text('ideal', ideal)
    if limited is None:
        return (text, actuators, _verdict(ok, why) + (
            " with ideal actuators; not run with the IRB 4600's limits" if ok else ''))
    lim_text, lim_ok, _ = test(limited)
    actuators += '; ' + actuators_text('limited', limited)
    text += f"; with the IRB 4600's limits: {lim_text}"
    if ok and not lim_ok:
        return (text, actuators, f"met with ideal actuators ({why}); with the IRB 4600's "
                f'limits: not met ({lim_text})')
    if ok:
        return text, actuators, f"met ({why}), with ideal actuators and with the IRB 4600's limits"
    return text, actuators, _verdict(False, why) + (
        "; with the IRB 4600's limits: met" if lim_ok else '')


def claims(s1: Mapping[str, Any], s2: Mapping[str, Any], s3: Mapping[str, Any],
           worst: Mapping[str, Any], limited: Mapping[str, Mapping[str, Any]] | None = None
           ) -> list[tuple[str, str, str, str, str]]:
    """
    Return the rows (claim, the paper's words, ours, actuators, verdict) of the paper's claims.

    ``s1``..``s3``: each scenario's metrics (the paper's ideal actuators); ``worst``: the
    sweep row (link, scale, final_position_error_m, metrics) with the largest final
    position error; ``limited``: {scenario name: metrics} of the paper's law on the
    scenarios with the IRB 4600's limited actuators and 0.067 s latency (the law study's
    runs), where run. The paper (section 5): scenario 1 responds "within 0.3 seconds"
    with "small overshoots"; out of view (2, 3) it "converges fast (less than a second)";
    in Figure 13 every steady-state error is "less than 1%", read here as 1 % of the
    distance from the start to the target. A claim met only with ideal actuators says so,
    with what the limited run measured.
    """
    limited = limited or {}
    rows = [('scenario 1 reaches the target fast', 'within about 0.3 s',
             *_decide(_fast, s1, limited.get('scenario1'))),
            ('scenario 1 overshoot', 'small', *_decide(_overshoot, s1, limited.get('scenario1'))),
            ('scenario 1 final pose', 'exact (IBVS)',
             *_decide(_final, s1, limited.get('scenario1')))]
    for name, key, s in (('scenario 2', 'scenario2', s2), ('scenario 3 (with d_q)', 'scenario3',
                                                           s3)):
        rows.append((f'{name} converges out of view', 'under 1 s, large overshoot',
                     *_decide(_out_of_view, s, limited.get(key))))
    share = worst['final_position_error_m'] / worst['metrics']['initial_position_error_m']
    rows.append(('L2, L4 from 50 % to 110 %: steady-state error', 'under 1 %',
                 f'worst {_fmt(worst["final_position_error_m"], " mm", 1e3, 4)} '
                 f'({worst["link"]} at {100 * worst["scale"]:.0f} %), '
                 f'{100 * share:.4f} % of the distance to go',
                 actuators_text('ideal', worst['metrics']),
                 _verdict(share < 0.01) + ("; not run with the IRB 4600's limits"
                                           if share < 0.01 else '')))
    return rows


def limited_metrics(runs: Sequence['laws_report.LawRun'], law: str = PAPER_LAW
                    ) -> dict[str, dict[str, Any]]:
    """
    Return {scenario: metrics} of ``law``'s limited-actuator runs of the law study.

    Each with ``peak_joint_speed_ratio`` from the run's joint speeds where its metrics
    lack it (:class:`.laws_report.LawRun`).
    """
    return {r.scenario: {'peak_joint_speed_ratio': r.peak_speed_ratio, **r.metrics}
            for r in runs if r.law == law and r.case == 'limited'}


def load_specs(quick: bool = False) -> list[study_spec.Spec]:
    """Return the report's study specs; ``quick`` keeps the sweep's endpoints and nominal."""
    specs = [study_spec.load(study.study_path(name)) for name in REPORT_STUDIES]
    if quick:
        specs = [_quick(spec) if spec.name == SWEEP_STUDY else spec for spec in specs]
    return specs


def _quick(spec):
    grid = tuple({k: [v for v in values if v in QUICK_SCALES] for k, values in product.items()}
                 for product in spec.grid)
    return dataclasses.replace(spec, name=f'{spec.name}_quick', grid=grid)


def sweep_rows(records: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Return the Figure 13 sweep's rows (link, scale, metrics) from its study's records."""
    rows = []
    for record in records:
        (name, scale), = record['swept'].items()
        metrics = record.get('metrics') or {}
        rows.append({'link': name[:2].upper(), 'scale': scale, 'metrics': metrics,
                     'status': record['status'],
                     'final_position_error_m': metrics.get('final_position_error_m',
                                                           float('nan'))})
    return rows


def sweep_figure(rows: Sequence[Mapping[str, Any]], path: str | Path) -> None:
    """
    Plot final position error against the L2 and L4 factors (paper Figure 13).

    With the paper's bound, 1 % of the distance to go (:data:`PAPER_SHARE` of the runs'
    initial position error: 25.6 mm from scenario 1's start), and the success criterion's
    1 mm (:data:`ibvs_analysis.convergence.SUCCESS`); a point outside it is drawn open.
    """
    fig, ax = plt.subplots(figsize=(7, 4))
    for i, (link, marker) in enumerate((('L2', 'o'), ('L4', 's'))):
        sel = [r for r in rows if r['link'] == link]
        x = [100 * r['scale'] for r in sel]
        y = [1e3 * r['final_position_error_m'] for r in sel]
        ax.plot(x, y, color=f'C{i}', label=link)
        ok = [SUCCESS.final(r['metrics']) for r in sel]
        ax.scatter([a for a, good in zip(x, ok) if good], [b for b, good in zip(y, ok) if good],
                   marker=marker, color=f'C{i}', zorder=3)
        ax.scatter([a for a, good in zip(x, ok) if not good],
                   [b for b, good in zip(y, ok) if not good], marker=marker,
                   facecolors='none', edgecolors=f'C{i}', zorder=3, s=60,
                   label=f'{link} outside {SUCCESS.describe()}' if not all(ok) else None)
    bound = PAPER_SHARE * min(r['metrics']['initial_position_error_m'] for r in rows)
    ax.axhline(1e3 * bound, color='tab:red', ls='--',
               label=f'paper: 1 % of the distance to go ({1e3 * bound:.1f} mm)')
    ax.axhline(1e3 * SUCCESS.position_m, color='black', ls=':',
               label=f'success: {SUCCESS.position_m * 1e3:g} mm')
    ax.set_yscale('log')
    ax.set_xlabel('simulated link length [% of nominal]')
    ax.set_ylabel('final position error [mm]')
    ax.set_title('robustness to model uncertainty (scenario 1)')
    ax.grid(alpha=0.3, which='both')
    ax.set_ylim(top=20.0 * 1e3 * bound)  # room above the paper's bound for the legend
    ax.legend(fontsize=8, loc='upper left', ncols=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run_identity(scenario_name: str, overrides: Mapping[str, Any],
                 duration_s: float | None) -> str:
    """
    Return what decides a graph run, as text: every node parameter's value and the sim time.

    Each parameter a node declares takes its default (:func:`graph_params.declared`), then
    the scenario file's value, then the override's, and the sim time is ``duration_s`` or
    the scenario's, as ``ibvs run`` resolves them (:func:`.runner.resolve`). Two runs with
    the same identity run the same graph with the same values: the lockstep run is
    deterministic, so they record the same bag, whichever study names them (a study's cache
    key, :func:`.study_spec.run_key`, hashes the overrides as written instead).
    """
    from ibvs_bringup import graph_params
    from ibvs_common.params import plain_value
    from .runner import resolve
    params, duration_s = resolve(scenario_name, overrides, duration_s)
    declared = graph_params.declared()
    values = {name: param.default for name, param in declared.items()}
    values.update(params)
    values = {name: plain_value(value, declared[name].default) if name in declared else value
              for name, value in values.items()}
    return json.dumps({'parameters': values, 'duration_s': duration_s}, sort_keys=True,
                      default=str)


def shared_runs(specs: Sequence[study_spec.Spec]
                ) -> tuple[list[study_spec.Spec], dict[tuple[str, int], tuple[str, int]]]:
    """
    Return ``specs`` with every run that an earlier run makes already left out, and which.

    A run is made already when an earlier one (in ``specs`` order) has the same
    :func:`run_identity` and draws its figures if this one does (``run_figures``). The
    answer: the specs to run (a study that keeps some of its grid points has them as a grid
    of one-point products, which names the same overrides, hence the same cache keys; a
    study with nothing left is dropped), and ``{(study, index): (study, index)}`` from each
    run left out to the run that makes it. Studies with draws are kept whole.
    """
    made, shared, out = {}, {}, []
    for spec in specs:
        runs = spec.runs()
        kept = []
        for run in runs:
            identity = None if spec.draws else run_identity(spec.scenario, run.overrides,
                                                            spec.duration_s)
            first = made.get(identity)
            if first is not None and (first[1] or not spec.run_figures):
                shared[spec.name, run.index] = first[0]
                continue
            kept.append(run)
            if identity is not None and (first is None or spec.run_figures):
                made[identity] = ((spec.name, run.index), spec.run_figures)
        if len(kept) == len(runs):
            out.append(spec)
        elif kept:
            out.append(dataclasses.replace(spec, grid=tuple(
                {name: [value] for name, value in run.swept.items()} for run in kept)))
    return out, shared


def with_shared(specs: Sequence[study_spec.Spec], records: Mapping[str, Sequence[dict]],
                shared: Mapping[tuple[str, int], tuple[str, int]]
                ) -> dict[str, list[dict[str, Any]]]:
    """
    Return every run's record of ``specs``, those :func:`shared_runs` left out included.

    ``records``: ``run_studies``'s answer for the specs that were run. A run left out gets a
    copy of the record of the run that made it (its metrics and run folder), with its own
    study, index, swept values and overrides, and ``same_as``: 'study#index' of that run.
    """
    done = {}
    for name, rs in records.items():
        spec = next(s for s in specs if s.name == name)
        left = [run for run in spec.runs() if (name, run.index) not in shared]
        for run, record in zip(left, rs):
            done[name, run.index] = {**record, 'index': run.index}
    out = {}
    for spec in specs:
        out[spec.name] = []
        for run in spec.runs():
            source = shared.get((spec.name, run.index))
            record = done[spec.name, run.index] if source is None else {
                **done[source], 'study': spec.name, 'index': run.index, 'swept': run.swept,
                'overrides': run.overrides, 'same_as': f'{source[0]}#{source[1]}'}
            out[spec.name].append(record)
    return out


class ModelOnlySweeps:
    """
    The law study's work beside its graph runs, on their Ray session (:class:`.study.Job`).

    The model-only calibration and noise sweeps (:mod:`ibvs_experiments.calibration_sweep`)
    as one job per law and target source (1-2 s each), and each law run read back
    (:func:`.laws_report.read_run`, about 0.3 s) as it finishes, on the session's cores
    beside the graph runs, not after the last run on one core.
    """

    def __init__(self) -> None:
        """Start empty: :meth:`jobs` fills it."""
        from ibvs_experiments import calibration_sweep
        self._sweep = calibration_sweep
        self._calibration: dict[tuple[str, str], list] = {}
        self._noise: dict[str, dict] = {}
        #: The law runs read so far: {run folder: LawRun}.
        self.law_runs: dict[str, laws_report.LawRun] = {}

    def jobs(self) -> list[study.Job]:
        """Return the sweeps as jobs: calibration per target source and law, noise per law."""
        out = [study.Job(f'calibration sweep, {law}, {target} target', self._sweep.sweep,
                         ((law,), (target,)),
                         lambda runs, key=(target, law): self._calibration.update({key: runs}))
               for target in self._sweep.TARGET_SOURCES for law in SERVO_LAWS]
        out += [study.Job(f'noise sweep, {law}', self._sweep.noise_sweep, ((law,),),
                          lambda result, law=law: self._noise.update({law: result}))
                for law in SERVO_LAWS]
        return out

    def calibration(self) -> list:
        """Return the calibration sweep's runs, in ``calibration_sweep.sweep``'s order."""
        return [run for target in self._sweep.TARGET_SOURCES for law in SERVO_LAWS
                for run in self._calibration[target, law]]

    def noise(self) -> dict:
        """Return the noise sweep's results, as ``calibration_sweep.noise_sweep`` does."""
        return {k: v for law in SERVO_LAWS for k, v in self._noise[law].items()}

    def keep_law_run(self, record: Mapping[str, Any]) -> None:
        """Read a finished law run back (``run_studies``'s ``on_record``)."""
        if laws_report.is_law_study(record['study']) and record['status'] == 'ok':
            try:
                self.law_runs[record['run_dir']] = laws_report.read_run(record['run_dir'])
            except Exception:  # noqa: B902 read again after the runs, where it is raised
                pass


class ReportRunsFailed(RuntimeError):
    """Runs of the report failed: no report is written; ``failed`` names each, with why."""

    def __init__(self, failed: list[str]) -> None:
        """Keep ``failed``: one line per run, 'study#index: reason'."""
        super().__init__(f'{len(failed)} report run(s) failed (logs in their run '
                         'directories):\n' + '\n'.join(failed))
        self.failed = failed


def _run_studies(out_dir: Path, quick: bool, laws: bool, address: str | None,
                 parallel: int | None, domains: tuple[int, int], retry_failed: bool
                 ) -> tuple[list, list, dict, 'ModelOnlySweeps | None']:
    """
    Run the report's studies (:func:`build_report`); return their specs, records and sweeps.

    Returns the report's specs, the law studies', every study's records by name (the shared
    runs filled in) and the model-only sweeps (None without ``laws``), every study's table
    written; raises :class:`ReportRunsFailed` when a run failed.
    """
    specs = load_specs(quick)
    law_specs = laws_report.specs() if laws else []
    to_run, shared = shared_runs(specs + law_specs)
    if shared:
        print(f'{len(shared)} run(s) that two studies name run once: '
              + ', '.join(f'{a}#{i} = {b}#{j}' for (a, i), (b, j) in shared.items()),
              flush=True)
    model_only = ModelOnlySweeps() if laws else None
    ran = study.run_studies(to_run, out_dir / 'studies', address=address,
                            parallel=parallel, domains=domains, retry_failed=retry_failed,
                            jobs=model_only.jobs() if laws else (),
                            on_record=model_only.keep_law_run if laws else None)
    records = with_shared(specs + law_specs, ran, shared)
    for spec in specs + law_specs:
        if spec not in to_run:
            study_table.write_results(spec, records[spec.name], out_dir / 'studies' / spec.name)
    failed = [f"{r['study']}#{r['index']}: {r.get('reason', '')}"
              for rs in records.values() for r in rs if r['status'] != 'ok'
              and 'same_as' not in r]
    if failed:
        raise ReportRunsFailed(failed)
    return specs, law_specs, records, model_only


def build_report(out_dir: str | Path, quick: bool = False, address: str | None = None,
                 parallel: int | None = None,
                 domains: tuple[int, int] = study.DOMAIN_IDS,
                 laws: bool | None = None, retry_failed: bool = False) -> Path:
    """
    Run the report's studies and write ``<out_dir>/report.md``; return its path.

    ``laws``: also the servo laws side by side (:func:`.laws_report.specs`, 24 runs on Ray
    with the other studies); default: unless ``quick``. A run that two studies name (the
    same :func:`run_identity`) runs once (:func:`shared_runs`): the sweep's two runs at
    100 % are scenario 1's, the law studies' paper runs with ideal actuators the scenario
    studies'.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    laws = not quick if laws is None else laws
    specs, law_specs, records, model_only = _run_studies(
        out_dir, quick, laws, address, parallel, domains, retry_failed)
    scenarios = {name: records[name][0]['metrics'] for name in SCENARIO_STUDIES}
    run_dirs = {name: Path(records[name][0]['run_dir']).relative_to(out_dir)
                for name in SCENARIO_STUDIES}
    sweep_spec = next(spec for spec in specs if spec.name.startswith(SWEEP_STUDY))
    rows = sweep_rows(records[sweep_spec.name])
    sweep_figure(rows, out_dir / 'robustness.png')
    worst = max(rows, key=lambda r: r['final_position_error_m'])
    law_runs = laws_report.read_records(records, model_only.law_runs) if laws else []
    limited = limited_metrics(law_runs)
    (out_dir / 'report.json').write_text(json.dumps(
        {'scenarios': scenarios, 'limited': limited,
         'sweep': [{k: v for k, v in r.items() if k != 'metrics'} for r in rows]},
        indent=2) + '\n')
    s1, s2, s3 = (scenarios[n] for n in ('scenario1', 'scenario2', 'scenario3'))
    lines = [
        '# Reproduction of Li & Assadian, adaptive IBVS of a 6-DoF IRB 4600',
        '',
        "What this is: the paper's claims, scenarios and robustness sweep run through the "
        'ROS 2 graph (simulator, renderer, detector, controllers) and measured from each '
        "run's rosbag2 recording (`ros2 run ibvs_experiments ibvs analyse <bag>` reproduces "
        'every number of a graph run); the calibration and noise sweeps at the end come from '
        'the model-only loop (`ibvs_experiments.calibration_sweep`: no graph, no images). Each '
        'table names its source; every metric is defined in the glossary of docs/results.md. '
        "The paper's scenarios and sweep run with ideal actuators, the paper's "
        'tau_in = 0.01 s, omega_n = 10 rad/s, zeta = 1/sqrt(2); the claims table also gives '
        "each claim with the IRB 4600's limited actuators and "
        f"{laws_report.CASES['limited']['feedback_latency_s']:g} s latency (the law "
        "study's runs of the paper's law), where they were run. Defaults beyond the paper "
        '(docs/errata.md): the feedback evaluates C1 at the encoder angles (`linearise_at`, '
        'the paper: at F^-1(p_hat)), its trust region clips each decoupled channel on its '
        'own, and the robot stands on a 0.5 m riser (`mount_height_m`), so that a tool below '
        'its base plane is not hidden by the floor. Success, wherever the report says it: '
        f'within {SUCCESS.describe()} at the end (`ibvs_analysis.convergence.SUCCESS`). '
        'Machine timings are in a section of their own at the end (they measure the '
        'machine, not the loop).',
        '',
        "## The paper's claims next to our measurements",
        '',
        'Source: graph runs (bags). How each verdict is decided is in '
        '`ibvs_experiments.report.claims` (the paper gives words, not numbers, for some: '
        f'"small" is read as at most {SMALL_OVERSHOOT_M * 1e3:g} mm). Peak joint speed: as a '
        "multiple of the IRB 4600's rated speed of that joint (1 is the real arm's limit), "
        'torque as a multiple of the estimated limit (`ibvs_model.mass_model`).',
        '',
        '| claim (paper) | paper | measured here | actuators | verdict |',
        '|---|---|---|---|---|',
        *[f'| {c} | {paper} | {ours} | {actuators} | {verdict} |'
          for c, paper, ours, actuators, verdict in claims(s1, s2, s3, worst, limited)],
        '',
        '## Scenarios',
        '',
        "Source: each scenario's graph run (bag), ideal actuators. Metrics: docs/results.md, "
        'glossary.',
        '',
    ]
    lines += _scenario_lines(scenarios, run_dirs)
    lines += _sweep_lines(rows)
    lines += _studies_lines(specs + law_specs, specs, records, out_dir)
    lines += ['']
    if laws:
        lines += laws_report.section(law_runs, out_dir / 'laws', 'laws/')
        lines += laws_report.model_only_section(
            model_only.calibration(), model_only.noise(), out_dir / 'laws', 'laws/')
    lines += timings_section(scenarios)
    path = out_dir / 'report.md'
    path.write_text('\n'.join(lines))
    return path


def _scenario_lines(scenarios: Mapping[str, Mapping[str, Any]],
                    run_dirs: Mapping[str, Path]) -> list[str]:
    """Return the report's lines of each scenario: its metrics and its run's figures."""
    lines = []
    for name, metrics in scenarios.items():
        lines += [f'### {name}', '', '| metric | value |', '|---|---|']
        lines += [f'| {k} | {_value(v)} |' for k, v in metrics.items()
                  if k not in ('bag',) + TIMING_KEYS]
        lines += ['', f'![pose]({run_dirs[name]}/pose_vs_time.png)',
                  f'![errors]({run_dirs[name]}/error_vs_time.png)',
                  f'![joints]({run_dirs[name]}/joints.png)',
                  f'![trajectory]({run_dirs[name]}/trajectory_3d.png)',
                  f'![image plane]({run_dirs[name]}/image_plane.png)',
                  f'![features]({run_dirs[name]}/feature_timeline.png)', '']
    return lines


def _sweep_lines(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    """Return the report's section of the robustness sweep (Figure 13): table and verdict."""
    bound = PAPER_SHARE * min(r['metrics']['initial_position_error_m'] for r in rows)
    lines = ['## Robustness sweep (scenario 1, Figure 13)', '',
             'Source: graph runs (bags), ideal actuators.', '',
             '| link | factor | final position error [mm] | final axis error [deg] | '
             'lowest tool z [m] | success |',
             '|---|---|---|---|---|---|']
    lines += [f"| {r['link']} | {100 * r['scale']:.0f} % | "
              f'{1e3 * r["final_position_error_m"]:.4f} | '
              f"{r['metrics']['final_tool_axis_error_deg']:.4f} | "
              f"{r['metrics']['lowest_tool_z_m']:.3f} | "
              f"{'yes' if SUCCESS.final(r['metrics']) else 'no'} |" for r in rows]
    lines += ['', '![robustness](robustness.png)', '']
    within = all(r['final_position_error_m'] <= bound for r in rows)
    successes = sum(SUCCESS.final(r['metrics']) for r in rows)
    lines += [f"Every sweep point within the paper's 1 % of the distance to go "
              f"({1e3 * bound:.1f} mm): {'yes' if within else 'NO'}; within "
              f'{SUCCESS.describe()}: {successes} of {len(rows)}.', '']
    return lines


def _studies_lines(all_specs: Sequence[Any], specs: Sequence[Any],
                   records: Mapping[str, Sequence[Mapping[str, Any]]], out_dir: Path
                   ) -> list[str]:
    """Return the report's list of its studies (``all_specs``), the extra ones' figures."""
    lines = ['## Studies', '',
             'Each study of this report, with its table (CSV beside it) and figures; '
             '`ros2 run ibvs_experiments ibvs study <name>` runs one on its own. Source: '
             'graph runs (bags).', '']
    for spec in all_specs:
        same = sum('same_as' in r for r in records[spec.name])
        lines += [f'- [{spec.name}](studies/{spec.name}/table.md): {len(records[spec.name])} '
                  f'run(s)' + (f', {same} of them made by another study' if same else '')
                  + f'. {spec.description}']
    for name in EXTRA_STUDIES:
        spec = next(s for s in specs if s.name == name)
        lines += ['', f'### {name}', '', spec.description, '']
        lines += [f'![{p.stem}](studies/{name}/{p.name})'
                  for p in sorted((out_dir / 'studies' / name).glob('*.png'))]
    return lines


#: The paper's Figure 13 bound: the steady-state error under 1 % of the distance to go.
PAPER_SHARE = 0.01


def _value(v):
    """Return a metric's value as a table cell (floats and lists of floats to 6 digits)."""
    if isinstance(v, float):
        return f'{v:.6g}'
    if isinstance(v, list) and all(isinstance(x, float) for x in v):
        return '[' + ', '.join(f'{x:.6g}' for x in v) + ']'
    return str(v).replace('|', '/')


def timings_section(scenarios: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """
    Return the report's lines of machine timings: each scenario run's wall time and factor.

    Measured on the machine that made the report, under its load: they say how fast this
    machine simulated, not how the loop behaved (sim time is the loop's time). The columns
    of :data:`TIMING_KEYS` that some run has (the held factors: free-running runs only).
    ``make bench`` measures them properly (docs/speed.md).
    """
    keys = [k for k in TIMING_KEYS if any(m.get(k) is not None for m in scenarios.values())]
    lines = ['## Machine timings', '',
             'Wall time and real-time factor (sim seconds per wall second) of each scenario '
             'run on the machine that made this report, under its load: timings of the '
             'machine, not results of the loop (`make bench` and docs/speed.md measure them).',
             '']
    if not keys:
        return lines + ['No run recorded its wall time.', '']
    lines += ['| scenario | ' + ' | '.join(keys) + ' |', '|---|' + '---|' * len(keys)]
    lines += [f'| {name} | ' + ' | '.join(_value(m.get(k)) if m.get(k) is not None else '-'
                                          for k in keys) + ' |'
              for name, m in scenarios.items()]
    return lines + ['']
