"""
Servo laws side by side: each law on scenarios 1-3, two actuator cases, a table and figures.

The runs (:func:`plan`): every law of :data:`ibvs_control.servo_laws.SERVO_LAWS` on
scenarios 1-3, with the paper's ideal actuators and with the IRB 4600's limited actuators
plus 0.067 s between a camera frame and the command it causes (:data:`CASES`). Each run is an
ordinary ``ibvs run`` into its own folder, as studies on Ray with the report's others
(:func:`specs`) or one at a time (:func:`run_all`); this module only reads the folders back
(:func:`read_run`), so the runs may come from any scheduler.

Per run (:class:`LawRun`, the metrics of :mod:`ibvs_analysis.analysis` plus the joint speeds
of the bag): final position and tool-axis error, time to 1 mm (after which the tool stays
within 1 mm), overshoot past the target along the approach, peak joint speed (rad/s, and as
a multiple of the IRB 4600's rated speed qd_max: 1 is the real arm's limit), and converged:
the project's one success criterion, :data:`ibvs_analysis.convergence.SUCCESS` (1 mm and
0.5 deg at the end).

``python -m ibvs_experiments.laws_report DIR`` writes ``DIR/laws.md`` and per law one figure
of the tool's paths in 3-D and one of the features' paths in the images from the run folders
under ``DIR``; ``ibvs report --laws`` runs them. The figures of the model-only calibration and
noise sweeps (:mod:`ibvs_experiments.calibration_sweep`) are here too
(:func:`model_only_section`): ``ibvs_control`` draws nothing.
"""

import argparse
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
import json
from pathlib import Path
from typing import Any, TYPE_CHECKING

from ibvs_analysis import analysis
from ibvs_analysis.convergence import miss_reason, SUCCESS
from ibvs_control.servo_laws import SERVO_LAWS
from ibvs_model import IRB4600
import matplotlib

matplotlib.use('Agg')

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import ArrayLike, NDArray  # noqa: E402
import yaml  # noqa: E402

if TYPE_CHECKING:
    from ibvs_experiments.calibration_sweep import SweepRun
    from matplotlib.figure import Figure

    from .study_spec import Spec

SCENARIOS = ('scenario1', 'scenario2', 'scenario3')
#: Actuator cases: name -> parameter overrides. With 0.067 s latency the velocity laws'
#: lambda_0 is halved to 6 / s (ignored by the others): the loop then holds about 0.13 s of
#: delay (latency, camera period, inner loop), and at 12 / s (lambda times delay ~ 1.6) the
#: model-only loop oscillates and diverges from scenario 1; at 6 / s it converges.
CASES = {'ideal': {'actuators': 'ideal', 'feedback_latency_s': 0.0},
         'limited': {'actuators': 'limited', 'feedback_latency_s': 0.067, 'lambda_0': 6.0}}
#: The laws' line styles in the noise figure, in SERVO_LAWS order.
NOISE_STYLES = ('-', '--', '-.', ':')
#: Each case's line style in the law figures (another case: dotted).
CASE_STYLES = {'ideal': '-', 'limited': '--'}


@dataclass(frozen=True)
class LawRun:
    """One run read back: its law, case, scenario, metrics, joint speeds and tool path."""

    law: str
    case: str
    scenario: str
    metrics: dict
    peak_joint_speed: float
    peak_speed_ratio: float
    position: np.ndarray
    target: np.ndarray
    #: The features p_hat of each camera frame (N, 6): per marker (u_left, u_right, v), px.
    features: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    #: The target features p_bar (6,) (F at the target, nominal robot), or None.
    target_features: np.ndarray | None = None
    #: The images' (width, height), px, or None when the bag has no camera.
    image_size: tuple[int, int] | None = None

    @property
    def converged(self) -> bool:
        """Return True when the run ended within :data:`ibvs_analysis.convergence.SUCCESS`."""
        return SUCCESS.final(self.metrics)


def overrides_for(law: str, case: str) -> dict[str, Any]:
    """Return the parameter overrides of one run (:func:`.runner.with_servo_law`'s)."""
    from .runner import with_servo_law
    return with_servo_law({**CASES[case], 'servo_law': law})


def plan(out_dir: str | Path, laws: Iterable[str] = SERVO_LAWS,
         cases: Iterable[str] = tuple(CASES), scenarios: Iterable[str] = SCENARIOS
         ) -> list[tuple[str, Path, dict[str, Any]]]:
    """Return (scenario, run folder, overrides) of every run, ideal actuators first."""
    return [(name, Path(out_dir) / case / law / name, overrides_for(law, case))
            for case in cases for law in laws for name in scenarios]


#: Sim time of a law study's run, per case (s): the velocity laws need about 1.5 s to
#: 1 mm with ideal actuators and up to 3 s with limited ones (graph, this release).
DURATIONS_S = {'ideal': 3.0, 'limited': 5.0}
#: Study names: ``laws_<case>_<scenario>``.
STUDY_PREFIX = 'laws'


def specs(laws: Iterable[str] = SERVO_LAWS, cases: Iterable[str] = tuple(CASES),
          scenarios: Iterable[str] = SCENARIOS) -> 'list[Spec]':
    """
    Return the law comparison as studies (:class:`.study_spec.Spec`), one per case and scenario.

    Each study's grid is one point per law (its overrides, :func:`overrides_for`), so the
    runs go to Ray with the report's other studies (:func:`.study.run_studies`).
    """
    from .study_spec import Spec
    return [Spec(name=f'{STUDY_PREFIX}_{case}_{name}', scenario=name,
                 duration_s=DURATIONS_S[case],
                 grid=tuple({k: [v] for k, v in overrides_for(law, case).items()}
                            for law in laws),
                 description=f'each servo law on {name}, {case} actuators')
            for case in cases for name in scenarios]


def is_law_study(name: str) -> bool:
    """Return whether ``name`` is one of :func:`specs`' studies (``laws_<case>_<scenario>``)."""
    return name.startswith(STUDY_PREFIX + '_')


def read_records(records: Mapping[str, Sequence[Mapping[str, Any]]],
                 known: Mapping[str, 'LawRun'] | None = None) -> list['LawRun']:
    """
    Return the :class:`LawRun` of the law studies' records (``run_studies``'s answer).

    ``known``: runs read already, by run folder (as the records name it); the others are
    read here.
    """
    known = known or {}
    runs = [known.get(record['run_dir']) or read_run(record['run_dir'])
            for name, rs in records.items() if is_law_study(name)
            for record in rs if record['status'] == 'ok']
    return _ordered(runs)


def run_all(out_dir: str | Path, progress: Callable[[str], None] = print,
            **selection: Any) -> list['LawRun']:
    """Run :func:`plan` one run at a time (``runner.run_scenario``); return :func:`read_all`."""
    from . import runner
    for name, run_dir, overrides in plan(out_dir, **selection):
        progress(f'running {name} {overrides} -> {run_dir}')
        runner.run_scenario(name, run_dir, overrides, progress=progress)
    return read_all(out_dir)


def joint_speeds(bag_path: str | Path) -> NDArray[np.float64]:
    """Return the measured joint speeds (N, 6) of a run's joint states (rad/s; load_joints)."""
    return analysis.load_joints(bag_path)[2]


def case_of(params: Mapping[str, Any]) -> str:
    """Return the case name of a run's parameters ('ideal', 'limited' or a description)."""
    for name, values in CASES.items():
        if all(params.get(k) == v for k, v in values.items()):
            return name
    return f"{params.get('actuators')}, {params.get('feedback_latency_s', 0.0)} s latency"


def summarise(params: Mapping[str, Any], metrics: Mapping[str, Any], qdot: ArrayLike,
              position: ArrayLike, target: ArrayLike, qd_max: ArrayLike = IRB4600.qd_max,
              features: ArrayLike | None = None, target_features: ArrayLike | None = None,
              image_size: tuple[int, int] | None = None) -> 'LawRun':
    """
    Return the :class:`LawRun` of a run's parameters, metrics, joint speeds and path.

    ``features``, ``target_features``, ``image_size``: the run's image-plane features
    (N, 6), p_bar (6,) and the images' (width, height), for :func:`image_figure`.
    """
    speed = np.abs(np.asarray(qdot, dtype=float))
    return LawRun(law=params.get('servo_law', SERVO_LAWS[0]), case=case_of(params),
                  scenario=str(params.get('scenario_name', metrics.get('scenario'))),
                  metrics=metrics, peak_joint_speed=float(speed.max(initial=0.0)),
                  peak_speed_ratio=float((speed / np.asarray(qd_max)).max(initial=0.0)),
                  position=np.asarray(position, dtype=float),
                  target=np.asarray(target, dtype=float)[:3, 3],
                  features=np.zeros((0, 6)) if features is None
                  else np.asarray(features, dtype=float).reshape(-1, 6),
                  target_features=None if target_features is None
                  else np.asarray(target_features, dtype=float),
                  image_size=image_size)


def read_run(run_dir: str | Path) -> 'LawRun':
    """Return the :class:`LawRun` of a folder written by ``runner.run_scenario``."""
    run_dir = Path(run_dir)
    data, metrics = analysis.analyse_bag(run_dir / 'bag')
    params = dict(data.params)
    if (run_dir / 'params.yaml').exists():
        loaded = yaml.safe_load((run_dir / 'params.yaml').read_text()) or {}
        params = {**loaded.get('/**', {}).get('ros__parameters', {}), **params}
    params.setdefault('scenario_name', f"scenario{params['scenario']}" if 'scenario' in params
                      else run_dir.name)
    from ibvs_analysis.results import target_features
    size = None if data.camera is None else (data.camera.intrinsics.width,
                                             data.camera.intrinsics.height)
    return summarise(params, metrics, joint_speeds(run_dir / 'bag'), data.position,
                     data.target, features=data.features, target_features=target_features(data),
                     image_size=size)


def read_all(out_dir: str | Path) -> list['LawRun']:
    """Return the :class:`LawRun` of every run folder (one with a ``bag``) under out_dir."""
    return _ordered([read_run(bag.parent) for bag in sorted(Path(out_dir).rglob('bag'))
                     if (bag / 'metadata.yaml').exists()])


def _ordered(runs):
    """Return ``runs`` by case (ideal first), scenario and law (registry order)."""
    order = {law: i for i, law in enumerate(SERVO_LAWS)}
    return sorted(runs, key=lambda r: (list(CASES).index(r.case) if r.case in CASES else 9,
                                       r.scenario, order.get(r.law, 9)))


def _miss_kind(metrics):
    """Return the first words of :func:`ibvs_analysis.convergence.miss_reason` ('stalled', ...)."""
    reason = miss_reason(metrics) or ''
    return reason.split(':')[0].split(' (')[0].split(';')[0]


def _mm(value, digits=2):
    return 'not reached' if value is None else f'{1e3 * value:.{digits}f}'


def table(runs: Sequence['LawRun']) -> list[str]:
    """Return the markdown lines of the table: one row per run."""
    lines = ['| actuators | scenario | law | final position [mm] | final axis [deg] | '
             'time to 1 mm [s] | overshoot [mm] | peak joint speed [rad/s] (multiple of '
             'rated) | converged |',
             '|---|---|---|---|---|---|---|---|---|']
    for r in runs:
        m = r.metrics
        t1 = m.get('time_to_1mm_s')
        lines.append(
            f'| {r.case} | {r.scenario} | {r.law} | {_mm(m["final_position_error_m"])} | '
            f'{m["final_tool_axis_error_deg"]:.3f} | '
            f'{"not reached" if t1 is None else f"{t1:.3f}"} | '
            f'{_mm(m["max_overshoot_m"], 1)} | {r.peak_joint_speed:.3g} '
            f'({r.peak_speed_ratio:.2f}x) | '
            f'{"yes" if r.converged else "no: " + _miss_kind(m)} |')
    return lines


def path_figure(runs: Sequence['LawRun'], law: str, path: str | Path) -> None:
    """Plot the tool's path of each run of ``law`` (one colour per scenario) to ``path``."""
    fig = plt.figure(figsize=(7, 6))
    ax = fig.add_subplot(projection='3d')
    for i, name in enumerate(SCENARIOS):
        for r in (r for r in runs if r.law == law and r.scenario == name):
            p = r.position
            ax.plot(p[:, 0], p[:, 1], p[:, 2], CASE_STYLES.get(r.case, ':'), color=f'C{i}',
                    label=f'{name}, {r.case}')
            ax.scatter(*p[0], color=f'C{i}', marker='o')
    targets = {tuple(r.target) for r in runs if r.law == law}
    for target in targets:
        ax.scatter(*target, color='k', marker='x', s=60)
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.set_zlabel('z [m]')
    ax.set_title(f'tool path, servo_law = {law} (o start, x target)')
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def image_figure(runs: Sequence['LawRun'], law: str, path: str | Path) -> 'Figure':
    """
    Plot the image-plane paths of ``law``'s runs: a row per scenario, left and right image.

    Each marker's measured or estimated features p_hat (colour per marker, as
    :data:`ibvs_analysis.plots.MARKER_COLOURS`; line style per case), its start (o) and its
    target p_bar (*), and the image border; estimated features out of view are drawn too
    (Corke's and ViSP's IBVS examples plot the same: the feature paths in the image).
    Returns the figure, saved and closed.
    """
    from ibvs_analysis.plots import MARKER_COLOURS
    names = [name for name in SCENARIOS
             if any(r.law == law and r.scenario == name for r in runs)]
    fig, axes = plt.subplots(max(len(names), 1), 2, figsize=(12, 3.8 * max(len(names), 1)),
                             squeeze=False)
    for row, name in enumerate(names):
        sel = [r for r in runs if r.law == law and r.scenario == name]
        for side in (0, 1):
            ax = axes[row, side]
            size = next((r.image_size for r in sel if r.image_size is not None), None)
            if size is not None:
                ax.add_patch(plt.Rectangle((-0.5, -0.5), *size, fill=False, color='grey',
                                           label='image border'))
            for r in sel:
                for marker, colour in enumerate(MARKER_COLOURS):
                    u, v = r.features[:, 3 * marker + side], r.features[:, 3 * marker + 2]
                    ax.plot(u, v, CASE_STYLES.get(r.case, ':'), color=colour, lw=1,
                            label=f'marker {marker + 1}, {r.case}')
                    if len(u):
                        ax.scatter(u[0], v[0], s=25, color=colour, marker='o')
                    if r.target_features is not None:
                        ax.scatter(r.target_features[3 * marker + side],
                                   r.target_features[3 * marker + 2], s=120, marker='*',
                                   color=colour, edgecolor='black', zorder=3)
            ax.autoscale_view()
            ax.invert_yaxis()
            ax.set_aspect('equal', adjustable='datalim')
            ax.set_xlabel('u [px]')
            ax.set_ylabel('v [px]')
            ax.set_title(f"{name}, {'left' if side == 0 else 'right'} image", fontsize=10)
            ax.grid(alpha=0.3)
        axes[row, 1].legend(fontsize=7, loc='center left', bbox_to_anchor=(1.02, 0.5))
    fig.suptitle(f'image-plane feature paths, servo_law = {law} (o start, * target)')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return fig


def _one_error_at_a_time(runs):
    """Return the runs with no focal error by camera position error, and the reverse."""
    position = sorted((r for r in runs if r.focal_error == 0.0),
                      key=lambda r: r.position_error_m)
    focal = sorted((r for r in runs if r.position_error_m == 0.0), key=lambda r: r.focal_error)
    return position, focal


def calibration_figure(runs: 'Sequence[SweepRun]', path: str | Path) -> 'Figure':
    """
    Plot the calibration sweep (:func:`ibvs_experiments.calibration_sweep.sweep`) to ``path``.

    Columns: against the camera position error (mm, no focal error) and against the focal
    length error (%, no position error); rows: the true flange's final position error
    (mm) and final tool-axis error (deg), each with the success criterion's tolerance
    (:data:`ibvs_analysis.convergence.SUCCESS`, dotted), and the time to 1 mm (s; x at the top
    of the panel: not within 1 mm at the end). One colour and marker per law, one line style per
    target source (model solid, taught dashed). Points with both errors are not drawn.
    Returns the figure, saved and closed.
    """
    laws = list(dict.fromkeys(r.law for r in runs))
    targets = list(dict.fromkeys(r.target for r in runs))
    styles = dict(zip(targets, ('-', '--', ':', '-.')))
    markers = dict(zip(laws, 'osD^v<>'))
    # Each row: label, value, and the SUCCESS tolerance drawn (the axis always shows it,
    # so that a numerical floor of 1e-7 deg is not drawn as a spread).
    rows = (('final position error [mm]', lambda r: 1e3 * r.final_position_error_m,
             1e3 * SUCCESS.position_m),
            ('final tool-axis error [deg]', lambda r: r.final_axis_error_deg,
             SUCCESS.axis_deg),
            ('time to 1 mm [s]', lambda r: r.time_to_1mm_s, None))
    columns = (('camera position error [mm]', lambda r: 1e3 * r.position_error_m),
               ('focal length error [%]', lambda r: 100 * r.focal_error))
    fig, axes = plt.subplots(len(rows), len(columns), figsize=(12, 10), sharex='col',
                             squeeze=False)
    for col, ((xlabel, x), sel) in enumerate(zip(columns, _one_error_at_a_time(runs))):
        for row, (ylabel, y, tolerance) in enumerate(rows):
            ax = axes[row, col]
            for i, law in enumerate(laws):
                for target in targets:
                    line = [r for r in sel if r.law == law and r.target == target]
                    xs = np.array([x(r) for r in line])
                    ys = np.array([y(r) for r in line], dtype=float)
                    ax.plot(xs, ys, styles[target], marker=markers[law], color=f'C{i}',
                            ms=5, alpha=0.8, label=f'{law}, {target} target')
                    missing = ~np.isfinite(ys)
                    if missing.any():
                        ax.scatter(xs[missing], np.ones(missing.sum()), marker='x',
                                   color=f'C{i}', transform=ax.get_xaxis_transform(),
                                   clip_on=False)
            if tolerance is not None:
                ax.axhline(tolerance, color='grey', ls=':', lw=1, label='success within')
                ax.set_ylim(bottom=0.0, top=max(ax.get_ylim()[1], 1.5 * tolerance))
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
            if row == len(rows) - 1:
                ax.set_xlabel(xlabel)
    axes[0, -1].legend(fontsize=7, loc='upper left')
    fig.suptitle('calibration error, model-only loop from scenario 1 (x: not within 1 mm '
                 'at the end)')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return fig


def noise_figure(results: Mapping[tuple[str, float], tuple[float, float]],
                 path: str | Path) -> 'Figure':
    """
    Plot the noise sweep (:func:`ibvs_experiments.calibration_sweep.noise_sweep`) to ``path``.

    RMS position error (mm) and RMS tool-axis error (deg) of the true flange over the
    sweep's last ``TAIL_S`` against the features' noise (px), one line per law.
    Returns the figure, saved and closed.
    """
    noise = sorted({sigma for _, sigma in results})
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2))
    # Laws that end alike (paper and switching) would hide each other: each has its own
    # marker and line style, and the first drawn is the largest.
    for i, law in enumerate(dict.fromkeys(law for law, _ in results)):
        for ax, scale, which in ((axes[0], 1e3, 0), (axes[1], 1.0, 1)):
            ax.plot(noise, [scale * results[law, sigma][which] for sigma in noise],
                    NOISE_STYLES[i % len(NOISE_STYLES)], marker='osD^v<>'[i % 7],
                    ms=11 - 2 * (i % 4), mfc='none' if i % 2 == 0 else f'C{i}',
                    color=f'C{i}', lw=1.5, label=law, zorder=2 + i)
    for ax, label in zip(axes, ('RMS position error [mm]', 'RMS tool-axis error [deg]')):
        ax.set_xlabel('feature noise, standard deviation [px]')
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend()
    from ibvs_experiments.calibration_sweep import TAIL_S
    fig.suptitle('feature noise, model-only loop from scenario 1 (RMS over the last '
                 f'{TAIL_S:g} s)')
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return fig


def section(runs: Sequence['LawRun'], out_dir: str | Path, figure_prefix: str = ''
            ) -> list[str]:
    """
    Write each law's figures into ``out_dir``; return the report's markdown lines.

    The table (:func:`table`), then per law the tool paths in 3-D (:func:`path_figure`,
    ``law_path_<law>.png``) and the image-plane feature paths (:func:`image_figure`,
    ``law_image_<law>.png``).

    ``figure_prefix``: the figures' folder as the markdown file that holds the lines sees it.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    lines = ['## Servo laws side by side', '',
             f'Ideal actuators (the paper), and limited actuators with '
             f"{CASES['limited']['feedback_latency_s']} s latency (there lambda_0 "
             f"{CASES['limited']['lambda_0']:g} / s for ibvs and pbvs). Source: each run's "
             'bag (graph runs of the law studies, `studies/laws_*`). Converged: the success '
             f'criterion, within {SUCCESS.describe()} at the end '
             '(`ibvs_analysis.convergence.SUCCESS`); a miss names its kind (timed out, '
             'stalled, features lost). Peak joint speed: the largest |qdot| over joints and '
             "time, and as a multiple of the IRB 4600's rated speed of that joint (1: the "
             "real arm's limit; ideal actuators are not held to it).", '']
    lines += table(runs) + ['']
    for law in dict.fromkeys(r.law for r in runs):
        name = f'law_path_{law}.png'
        path_figure(runs, law, out_dir / name)
        lines += [f'![{law}]({figure_prefix}{name})', '']
    lines += ["Each law's features in the left and right image (measured, or estimated out of "
              'view), per scenario:', '']
    for law in dict.fromkeys(r.law for r in runs):
        name = f'law_image_{law}.png'
        image_figure(runs, law, out_dir / name)
        lines += [f'![{law} image paths]({figure_prefix}{name})', '']
    return lines


def model_only_section(calibration: 'Sequence[SweepRun]',
                       noise: Mapping[tuple[str, float], tuple[float, float]],
                       out_dir: str | Path, figure_prefix: str = '') -> list[str]:
    """
    Return the report's lines of the model-only sweeps; write their figures into ``out_dir``.

    ``calibration``: :func:`ibvs_experiments.calibration_sweep.sweep`'s runs; ``noise``:
    :func:`~ibvs_experiments.calibration_sweep.noise_sweep`'s results. Each is computed once
    by the caller and gives both its table and its figure (``calibration.png``,
    ``noise.png``); ``figure_prefix`` as for :func:`section`.
    """
    from ibvs_experiments import calibration_sweep
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    calibration_figure(calibration, out_dir / 'calibration.png')
    noise_figure(noise, out_dir / 'noise.png')
    return ['### Calibration error (model-only loop, scenario 1)', '',
            calibration_sweep.__doc__.strip().split('\n\n')[1].replace('\n', ' '), '',
            'Final position / tool-axis error of the true flange after '
            f'{calibration_sweep.DURATION_S:g} s:', '',
            *calibration_sweep.table(calibration), '',
            f'![calibration error]({figure_prefix}calibration.png)', '',
            '### Feature noise (model-only loop, scenario 1)', '',
            'Gaussian noise on every measured feature (px, a stand-in for the '
            "detector's error, not rendered image noise); RMS position / tool-axis "
            f'error over the last {calibration_sweep.TAIL_S:g} s:', '',
            *calibration_sweep.noise_table(noise), '',
            f'![feature noise]({figure_prefix}noise.png)', '']


def main(argv: Sequence[str] | None = None) -> int:
    """Write DIR/laws.md and the path figures from the run folders under DIR."""
    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument('dir', help='folder holding the run folders (any depth)')
    args = parser.parse_args(argv)
    runs = read_all(args.dir)
    lines = section(runs, args.dir)
    (Path(args.dir) / 'laws.md').write_text('\n'.join(lines) + '\n')
    (Path(args.dir) / 'laws.json').write_text(json.dumps(
        [{'law': r.law, 'case': r.case, 'scenario': r.scenario, 'converged': r.converged,
          'peak_joint_speed_rad_s': r.peak_joint_speed,
          'peak_speed_ratio': r.peak_speed_ratio, **r.metrics} for r in runs],
        indent=2) + '\n')
    print('\n'.join(lines))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
