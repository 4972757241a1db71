"""
Command line of the experiments: ``ros2 run ibvs_experiments ibvs <command>``.

Commands:

- ``run <scenario> [-o DIR] [--duration S] [--images] [-p name:=value ...]``: one run of a
  scenario (``scenario1``..``scenario3`` or a parameter file) through the node graph;
  ``-p servo_law:=ibvs`` (or ``pbvs``) also sets ``feedforward_method:=hold`` unless given
  (those laws have no feedforward), ``servo_law:=switching`` sets ``feedforward_ratio:=2``
  (:func:`ibvs_control.servo_laws.feedforward_overrides`);
  ``--overlays`` also records the feature node's overlay images, ``--video`` then writes
  ``video.mp4`` of them (:mod:`ibvs_experiments.video`);
- ``analyse <bag> [-o DIR]``: metrics and figures again, from a recorded bag;
- ``video <run dir> [-o FILE]``: the MP4 of a run recorded with ``--overlays``;
- ``demo``: the paper's scenario 1 with ideal actuators into ``results/scenario1``, then a
  short run of it with overlays and its video into ``results/scenario1_video``;
- ``study <spec> [-o DIR] [--address ADDR] [--parallel N] [--domains LOW-HIGH]``: every run
  of a study spec (a grid and/or seeded draws over parameters) as Ray tasks, cached;
- ``report [--quick]``: scenarios 1-3, the L2/L4 robustness sweep and each servo law on
  scenarios 1-3 with ideal and with limited actuators (:mod:`ibvs_experiments.laws_report`),
  as studies on Ray, into ``results/report.md``; ``--quick`` keeps the sweep's endpoints
  and skips the servo laws.
"""

import argparse
from collections.abc import Sequence
import json
import math
from pathlib import Path
import re
import sys
import tempfile
import time
from typing import Any

from ibvs_bringup import domains, graph_params, scenario
from ibvs_bringup.recorder import recover

from . import runner, study_spec

SUMMARY_KEYS = ('final_position_error_m', 'final_tool_axis_error_deg', 'settling_time_2pct_s',
                'time_to_1mm_s', 'max_overshoot_m', 'time_estimated_s', 'sim_duration_s',
                'wall_duration_s', 'real_time_factor')


def _print_summary(metrics, out=sys.stdout):
    for key in SUMMARY_KEYS:
        value = metrics.get(key)
        text = f'{value:.6g}' if isinstance(value, float) else str(value)
        print(f'  {key:28s} {text}', file=out)


def with_servo_law(overrides: dict[str, Any]) -> dict[str, Any]:
    """Return ``overrides`` with the feedforward parameters of its servo_law added."""
    law = overrides.get('servo_law')
    if law is None:
        return overrides
    # Here, not at the top: ibvs_control pulls in scipy.signal, seconds of start-up that a
    # run without servo_law does not need (issue 24).
    from ibvs_control.servo_laws import feedforward_overrides
    for key, value in feedforward_overrides(law).items():
        overrides.setdefault(key, value)
    return overrides


def positive_seconds(text: str) -> float:
    """Return ``text`` as a number of seconds > 0 (argparse type of --duration, --stall-s)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'{text!r} is not a number') from None
    if not (value > 0.0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f'{text} must be a finite number of seconds > 0')
    return value


def cmd_run(args: argparse.Namespace) -> int:
    """Run one scenario and print its metrics."""
    domains.domain_id()  # a ROS_DOMAIN_ID ROS must not use stops the run before anything
    domains.pool()
    overrides = dict(scenario.parse_override(p) for p in args.param)
    graph_params.check(overrides, '-p')
    overrides = with_servo_law(overrides)
    scenario.load_parameters(args.scenario)  # a refused scenario leaves no output directory
    out = Path(args.out or Path('results') / Path(args.scenario).stem)
    try:
        out.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=out).close()  # an existing directory may be read-only
    except OSError as exc:
        print(f'error: cannot write the results to {out}: {exc.strerror}', file=sys.stderr)
        return 2
    print(f'running {args.scenario} -> {out}')

    def metrics_ready(metrics):
        # The metrics before the figures, which take matplotlib seconds more (issue 24).
        print(f'wrote {out}/metrics.json' + (', drawing the figures' if args.figures else ''))
        _print_summary(metrics)
        sys.stdout.flush()

    try:
        result = runner.run_scenario(args.scenario, out, overrides, args.duration,
                                     record_images=args.images, stall_s=args.stall_s,
                                     record_overlays=args.overlays or args.video,
                                     figures=args.figures, on_metrics=metrics_ready)
    except domains.DomainBusy as exc:
        print(f'run not started: {exc}', file=sys.stderr)
        return 2
    except runner.NodeDied as exc:
        print(f'run failed: {exc}', file=sys.stderr)
        return runner.EXIT_NODE_DIED
    except runner.RunStalled as exc:
        print(f'run stalled: {exc}', file=sys.stderr)
        return 4
    print(f'wrote {"the figures in " + str(out) + " and " if args.figures else ""}the bag '
          f'{result.bag_path}')
    if result.interrupted:
        return 130  # SIGINT: the metrics are those of the part that ran
    if args.video:
        return cmd_video(argparse.Namespace(run_dir=out, out=None))
    return 0


def cmd_video(args: argparse.Namespace) -> int:
    """Write the MP4 of a run recorded with --overlays: overlays beside a 3D view."""
    from . import video
    try:
        path, frames = video.write_video(args.run_dir, args.out)
    except video.NoOverlays as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    print(f'wrote {path} ({frames} frames)')
    return 0


def cmd_analyse(args: argparse.Namespace) -> int:
    """Recompute metrics and figures from a bag."""
    bag = Path(args.bag)
    out = Path(args.out) if args.out else bag.parent
    out.mkdir(parents=True, exist_ok=True)
    runner.clean_shm(print, 'earlier processes (e.g. a runner killed with SIGKILL)')
    if recover(bag):
        print(f'{bag} was not closed (its recorder was killed): recovered what it holds')
    metrics = runner.write_results(bag, out)
    print(f'wrote {out}/metrics.json and figures from {bag}')
    _print_summary(metrics)
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """Run the paper's scenario 1 (ideal actuators) into results/scenario1."""
    args.scenario = 'scenario1'
    args.out = args.out or 'results/scenario1'
    args.param = ['actuators:=ideal'] + list(args.param)
    code = cmd_run(args)
    if code or not args.video_duration:
        return code
    # The film in a run of its own: drawing and recording the overlays costs wall time,
    # which the timed run above does not pay.
    return cmd_run(argparse.Namespace(**{**vars(args), 'out': args.out + '_video',
                                         'duration': args.video_duration, 'video': True}))


def cmd_study(args: argparse.Namespace) -> int:
    """Run a study spec's runs on Ray (local or --address), then its table and figures."""
    from . import study
    spec = study_spec.load(study.study_path(args.spec))
    study.check_spec(spec)  # before the output directory and Ray
    out = Path(args.out or Path('results') / 'studies')
    start = time.monotonic()
    records = study.run_studies([spec], out, address=args.address, parallel=args.parallel,
                                domains=study.parse_domains(args.domains),
                                stall_s=args.stall_s, retry_failed=args.retry_failed)
    failed = sum(r['status'] != 'ok' for r in records[spec.name])
    print(f'wrote {out / spec.name}/table.md, table.csv and figures; {failed} failed run(s); '
          f'{time.monotonic() - start:.0f} s of wall time')
    if failed:
        print(f'error: {failed} run(s) of {spec.name} failed (see the run.json of each)',
              file=sys.stderr)
        return 1
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    """Run the reproduction: scenarios 1-3 and the robustness sweep, then the report."""
    from . import report, study
    start = time.monotonic()
    try:
        path = report.build_report(Path(args.out), quick=args.quick, address=args.address,
                                   parallel=args.parallel,
                                   domains=study.parse_domains(args.domains),
                                   laws=False if args.no_laws else None,
                                   retry_failed=args.retry_failed)
    except report.ReportRunsFailed as exc:
        print(f'error: {exc}\nno report written; the runs that finished stay cached, and '
              '`ibvs report --retry-failed` runs the failed ones again', file=sys.stderr)
        return 1
    print(f'wrote {path}')
    minutes, seconds = divmod(time.monotonic() - start, 60.0)
    print(f'report took {int(minutes)} min {seconds:.0f} s of wall time')
    return 0


def _study_defaults():
    from . import study
    return {'domains': study.DOMAIN_IDS, 'parallel': study.default_parallel()}


def plain_text(doc: str) -> str:
    """Return a docstring as a terminal shows it: reST roles and literals as plain text."""
    return re.sub(r':\w+:`~?([^`]+)`', r'\1', doc).replace('``', "'")


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line and run the command."""
    try:
        study_defaults = _study_defaults()
    except domains.DomainError as exc:  # a broken IBVS_ROS_DOMAINS: no command can run
        print(f'error: {exc}', file=sys.stderr)
        return 2
    parser = argparse.ArgumentParser(prog='ibvs', description=plain_text(__doc__),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='command', required=True)
    for name, func in (('run', cmd_run), ('demo', cmd_demo)):
        p = sub.add_parser(name, help=func.__doc__)
        if name == 'run':
            p.add_argument('scenario', help='scenario1..3 or a parameter file')
        p.add_argument('--no-figures', dest='figures', action='store_false',
                       help='write the bag and metrics.json only (ibvs analyse draws the '
                       'figures from the bag later)')
        p.add_argument('-o', '--out', help='output directory (default results/<scenario>)')
        p.add_argument('--duration', type=positive_seconds, help='sim time limit, s (> 0)')
        p.add_argument('--images', action='store_true', help='also record raw images')
        p.add_argument('--stall-s', type=positive_seconds, default=runner.STALL_S,
                       help='wall seconds without sim-time progress that end the run as '
                       'stalled (exit code 4; default %(default)s)')
        p.add_argument('-p', '--param', action='append', default=[],
                       help='override a parameter: name:=value (repeatable)')
        p.add_argument('--overlays', action='store_true',
                       help='also record the overlay images /ibvs/debug/{left,right}/image')
        p.add_argument('--video', action='store_true',
                       help='record the overlays and write video.mp4 (ibvs video)')
        if name == 'demo':
            p.add_argument('--video-duration', type=float, default=0.5,
                           help='sim seconds of the demo film, in a run of its own into '
                           '<out>_video (0: none; default %(default)s)')
        p.set_defaults(func=func)
    p = sub.add_parser('video', help=cmd_video.__doc__)
    p.add_argument('run_dir', help='a run directory (with bag/) recorded with --overlays')
    p.add_argument('-o', '--out', help='the MP4 file (default RUN_DIR/video.mp4)')
    p.set_defaults(func=cmd_video)
    p = sub.add_parser('analyse', help=cmd_analyse.__doc__)
    p.add_argument('bag', help='bag directory of a run')
    p.add_argument('-o', '--out', help='output directory (default: next to the bag)')
    p.set_defaults(func=cmd_analyse)
    p = sub.add_parser('study', help=cmd_study.__doc__)
    p.add_argument('spec', help='a study spec file, or the name of an installed one')
    p.add_argument('-o', '--out', help='parent of the study directory (default results/studies)')
    p.add_argument('--stall-s', type=float, default=runner.STALL_S,
                   help='wall seconds without sim-time progress that fail a run')
    p.add_argument('--retry-failed', action='store_true',
                   help='run again the runs recorded as failed')
    p.set_defaults(func=cmd_study)
    p = sub.add_parser('report', help=cmd_report.__doc__)
    p.add_argument('-o', '--out', default='results', help='results directory')
    p.add_argument('--quick', action='store_true',
                   help='sweep endpoints only, and no servo-law comparison')
    p.add_argument('--no-laws', action='store_true',
                   help="the paper's reproduction alone: the whole sweep, no servo-law "
                   'comparison')
    p.add_argument('--retry-failed', action='store_true',
                   help='run again the runs recorded as failed (a failed run stays cached '
                   'as failed otherwise)')
    p.set_defaults(func=cmd_report)
    for name in ('study', 'report'):
        p = sub.choices[name]
        p.add_argument('--address', help='an existing Ray cluster (ray start --head prints it); '
                       'default: a local Ray started for this command')
        p.add_argument('--domains', default='-'.join(map(str, study_defaults['domains'])),
                       help='pool of ROS_DOMAIN_IDs for the runs, LOW-HIGH (default '
                       '%(default)s)')
        p.add_argument('--parallel', type=int,
                       help='runs at once on the local Ray (default: one per core, '
                       f"{study_defaults['parallel']} here)")
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (scenario.ScenarioError, study_spec.StudyError, FileNotFoundError,
            TimeoutError, domains.DomainError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


def metrics_json(path: str | Path) -> Any:
    """Return the metrics dict stored at ``path``."""
    return json.loads(Path(path).read_text())


if __name__ == '__main__':
    sys.exit(main())
