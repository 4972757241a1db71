"""
Command line of the experiments: ``ros2 run ibvs_experiments ibvs <command>``.

Commands:

- ``run <scenario> [-o DIR] [--duration S] [--images] [-p name:=value ...]``: one run of a
  scenario (``scenario1``..``scenario3``, ``real_cell`` or a parameter file) through the
  node graph, into a folder of its own under ``results/runs`` named after the scenario, the
  ``-p`` values and ``--duration`` (:func:`run_folder`) unless ``-o`` names one;
  ``-p servo_law:=ibvs`` (or ``pbvs``) also sets ``feedforward_method:=hold`` unless given
  (those laws have no feedforward), ``servo_law:=switching`` sets ``feedforward_ratio:=2``
  (:func:`.runner.with_servo_law`);
  ``--images`` records the camera images, ``--overlays`` the feature node's overlay images,
  ``--video`` writes the run's film ``video.mp4`` (:mod:`ibvs_analysis.video`: its
  camera images rendered again from the recorded joint states unless recorded);
- ``analyse <bag> [-o DIR]``: metrics and figures again, from a recorded bag (exit code 2
  when there is none or it holds too little to analyse, 1 when the analysis fails);
- ``video <run dir> [-o FILE] [--time-map 0.25@1,1]``: the film (H.264 MP4) of a run;
- ``demo``: the paper's scenario 1 with ideal actuators into ``results/scenario1``, with
  its film ``results/scenario1/video.mp4``;
- ``study <spec> [-o DIR] [--address ADDR] [--parallel N] [--domains LOW-HIGH]
  [--stall-s S] [--retry-failed]``: every run of a study spec (a grid and/or seeded draws
  over parameters) as Ray tasks, cached;
- ``cell [--controller forward_command|joint_trajectory] [--camera-name zed]
  [--controller-name NAME] [--params-file FILE] [-p name:=value ...] [-o DIR]
  [--check-timeout S] [--teach DIR] [--dry-run]``: the controller side of a real cell
  (docs/real_cell.md): checks that the camera's and the arm's topics are there, starts the
  feature, feedback, feedforward and joint controller nodes with ``config/cell.yaml`` (no
  simulator), records a bag for ``ibvs analyse``, prints their status once a second (the
  image and pose errors among it); ``--teach`` publishes a taught pair and takes its
  target, ``--dry-run`` sends nothing to the arm; Ctrl-C stops them all
  (:mod:`ibvs_experiments.cell`);
- ``calibrate [--bag DIR] [-n N] [--seed S] [--poses FILE] [--draw-poses FILE]
  [-p name:=value ...] [-o FILE] [--force]``: the hand-eye calibration, the camera pose {C}
  in ``base_link`` from the tool's own spheres at N poses, by least squares on the
  reprojection error, written as the ``camera_pose`` parameter with its residual and
  uncertainty: in the offline simulator (the default, ``-p`` its parameters, e.g. a camera
  error to recover), from a cell's recording (``--bag``), or only the poses to visit
  (``--draw-poses``) (:mod:`ibvs_experiments.calibrate`, docs/real_cell.md);
- ``teach [-o DIR] [--teach-frames N] [--camera-name zed] [--timeout S] [--still-tol-deg D]``,
  ``teach --publish DIR``: the taught target, with the tool held at it: the mean of N
  consecutive stereo pairs from the camera's topics while the arm is still, written with
  the joints of /joint_states, the camera_info and the stamps, and the target (the forward
  kinematics of those joints) as a parameter file; or a recorded pair published latched
  for the feature node (:mod:`ibvs_experiments.teach`, docs/real_cell.md);
- ``report [--quick] [--no-laws] [--retry-failed]``: scenarios 1-3, the L2/L4 robustness
  sweep and each servo law on scenarios 1-3 with ideal and with limited actuators
  (:mod:`ibvs_experiments.laws_report`), as studies on Ray, into ``results/report.md``;
  ``--quick`` keeps the sweep's endpoints and skips the servo laws, ``--no-laws`` skips
  the servo laws only.
"""

import argparse
from collections.abc import Sequence
import hashlib
import math
import os
from pathlib import Path
import re
import sys
import tempfile
import time
from typing import Any

from ibvs_analysis import analysis, results
from ibvs_bringup import domains, graph_params, scenario
from ibvs_bringup.recorder import BagUnreadable, recover
from ibvs_common import shared_params
from rosbags.rosbag2 import ReaderError

from . import cell, output_dir, runner, study_spec

#: Where ``ibvs run`` writes without ``-o``: a folder per command line (:func:`run_folder`),
#: apart from ``make demo``'s ``results/scenario1`` and the studies' ``results/studies``.
RUNS_DIR = Path('results') / 'runs'
#: Longest folder name :func:`run_folder` writes out in full (a file system allows 255 bytes).
RUN_NAME_MAX = 100

SUMMARY_KEYS = ('final_position_error_m', 'final_tool_axis_error_deg', 'settling_time_2pct_s',
                'time_to_1mm_s', 'max_overshoot_m', 'time_estimated_s',
                'peak_joint_speed_ratio', 'success', 'miss_reason', 'sim_duration_s',
                'wall_duration_s', 'real_time_factor')


def _print_summary(metrics, out=sys.stdout):
    for key in SUMMARY_KEYS:
        value = metrics.get(key)
        text = f'{value:.6g}' if isinstance(value, float) else str(value)
        print(f'  {key:28s} {text}', file=out)


def run_folder(scenario_name: str | Path, params: Sequence[str] = (),
               duration_s: float | None = None, root: Path = RUNS_DIR) -> Path:
    """
    Return the folder of ``ibvs run`` without ``-o``: named after what the command sets.

    Parameters
    ----------
    scenario_name : str or Path
        The scenario as given (``scenario2``, or a parameter file: its stem).
    params : sequence of str
        The ``-p name:=value`` texts; the last value of a name counts, names are sorted (the
        same run, the same folder), and each value is written as typed, less brackets,
        quotes and spaces, with ``_`` for any other character that a file name should not
        hold.
    duration_s : float, optional
        ``--duration``, written as ``<seconds>s`` last; none when not given.
    root : Path
        The parent folder.

    Returns
    -------
    Path
        ``root/<scenario>[_<name>=<value>...][_<duration>s]``, for example
        ``results/runs/scenario2_actuators=limited_feedback_latency_s=0.067`` and
        ``results/runs/scenario1_0.5s``. A name longer than :data:`RUN_NAME_MAX` keeps its
        first characters and ends with 8 hex digits of its SHA-1 (still one folder per
        command line).

    """
    values = {}
    for text in params:
        name, _, value = text.partition(':=')
        values[name.strip()] = value
    parts = [Path(str(scenario_name)).stem]
    for name in sorted(values):
        value = re.sub(r"[\[\]{}()'\"\s]", '', values[name])
        parts.append(f'{name}={value}')
    if duration_s is not None:
        parts.append(f'{duration_s:g}s')
    folder = re.sub(r'[^A-Za-z0-9._+,=-]', '_', '_'.join(parts))
    if len(folder) > RUN_NAME_MAX:
        digest = hashlib.sha1(folder.encode()).hexdigest()[:8]
        folder = f'{folder[:RUN_NAME_MAX - 9]}_{digest}'
    return root / folder


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
    if str(args.scenario) == Path(cell.CELL_CONFIG).stem:
        raise scenario.ScenarioError(
            f'{args.scenario} is the controller side of a real cell, no scenario: it starts no '
            'simulator (ibvs cell starts it against the real arm and camera)')
    overrides = dict(scenario.parse_override(p) for p in args.param)
    graph_params.check(overrides, '-p')
    # The simulator owns time: the scenario file's and the -p's use_sim_time must agree.
    scenario.check_clock({**scenario.load_parameters(args.scenario), **overrides},
                         simulated=True)
    overrides = runner.with_servo_law(overrides)
    # Every check before any node (runner.resolve): a refused run leaves no output directory.
    runner.resolve(args.scenario, overrides, args.duration)
    out = Path(args.out or run_folder(args.scenario, args.param, args.duration))
    try:
        out.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=out).close()  # an existing directory may be read-only
    except OSError as exc:
        print(f'error: cannot write the results to {out}: {exc.strerror}', file=sys.stderr)
        return 2
    print(f'running {args.scenario} -> {out}')

    def metrics_ready(metrics):
        # The metrics before the figures, which take matplotlib seconds more.
        print(f'wrote {out}/metrics.json' + (', drawing the figures' if args.figures else ''))
        _print_summary(metrics)
        sys.stdout.flush()

    try:
        result = runner.run_scenario(args.scenario, out, overrides, args.duration,
                                     record_images=args.images,
                                     stall_s=args.stall_s, record_overlays=args.overlays,
                                     figures=args.figures, on_metrics=metrics_ready)
    except (domains.DomainBusy, output_dir.OutputRefused) as exc:
        print(f'run not started: {exc}', file=sys.stderr)
        return 2
    except runner.NodeDied as exc:
        print(f'run failed: {exc}', file=sys.stderr)
        return runner.EXIT_NODE_DIED
    except runner.TeachFailed as exc:
        print(f'run failed: {exc}', file=sys.stderr)
        return runner.EXIT_TEACH_FAILED
    except runner.RunStalled as exc:
        print(f'run stalled: {exc}', file=sys.stderr)
        return 4
    print(f'wrote {"the figures in " + str(out) + " and " if args.figures else ""}the bag '
          f'{result.bag_path}')
    if result.interrupted:
        return 130  # SIGINT: the metrics are those of the part that ran
    if args.video:
        return cmd_video(argparse.Namespace(run_dir=out, out=None, time_map=None))
    return 0


def cmd_cell(args: argparse.Namespace) -> int:
    """Start the controller side of a real cell (no simulator); Ctrl-C stops it."""
    # The cell's domain is ROS_DOMAIN_ID, unset ROS's default 0 (cell.run_cell), never a free
    # one of the pool: the refusals say so (domains' own hints are an ibvs run's).
    cell_domain = ("ibvs cell runs on the cell's ROS domain, ROS_DOMAIN_ID (unset: ROS's "
                   'default 0), never a free one')
    try:
        domains.domain_id()
    except domains.DomainError:
        low, high = domains.SAFE_RANGE
        print(f'error: ROS_DOMAIN_ID={os.environ.get(domains.DOMAIN_ENV)!r} is not a ROS '
              f"domain: set it to the cell's, a decimal number from {low} to {high}; "
              + cell_domain, file=sys.stderr)
        return 2
    from . import teach
    overrides = dict(scenario.parse_override(p) for p in args.param)
    taught = None
    try:
        if args.params_file:  # named as what it is: the cell's parameter file
            scenario.load_parameters(args.params_file, what='parameter file')
        if args.teach:  # the target is the teach's: one pose, by construction
            taught = teach.load(args.teach)
            given = sorted(set(overrides) & {'target_position', 'target_rotation'})
            if given:
                raise cell.CellError(f'-p {", ".join(given)} with --teach: the target is the '
                                     f"teach's ({Path(args.teach) / teach.TARGET_FILE}); "
                                     'leave it out')
            overrides.update(teach.target_overrides(taught.record))
        if args.dry_run:
            overrides['dry_run'] = True
        params = cell.cell_parameters(args.params_file, overrides, args.controller)
        if taught is not None and not shared_params.taught(params):
            raise cell.CellError('--teach with target_features_source '
                                 f"{params.get('target_features_source')!r}: the pair would not "
                                 'be used; leave out --teach or set target_features_source:='
                                 'taught')
        # The names first: a bad camera or controller name is refused before anything.
        cell.remaps(args.controller, args.camera_name, args.controller_name)
    except (cell.CellError, teach.TeachError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    out = Path(args.out) if args.out else output_dir.session_dir(cell.CELL_DIR)
    if taught is not None:
        print(f'--teach {args.teach}: target_position {params["target_position"]}, '
              f'target_rotation {params["target_rotation"]} (its {teach.TARGET_FILE}: the '
              'forward kinematics of the joints taught)')
    try:
        return cell.run_cell(params, out, args.controller, args.camera_name,
                             args.controller_name, args.check_timeout,
                             live=sys.stdout.isatty(), teach=taught)
    except output_dir.OutputRefused as exc:
        print(f'cell not started: {exc}', file=sys.stderr)
        return 2
    except domains.DomainBusy:
        print(f'cell not started: ROS domain {domains.domain_id()} is used by another run on '
              f'this machine; {cell_domain}: stop that run, or set ROS_DOMAIN_ID to the '
              "cell's", file=sys.stderr)
        return 2


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Hand-eye calibration: the camera pose {C} in base_link from the tool's spheres."""
    from . import calibrate
    return calibrate.main(args)


def cmd_teach(args: argparse.Namespace) -> int:
    """Teach the target: record the still tool's stereo pair and joints, or publish one."""
    from . import teach
    return teach.main(args)


def cmd_video(args: argparse.Namespace) -> int:
    """Write the film of a run: both cameras (recorded or rendered again) beside a 3D view."""
    from ibvs_analysis import video
    try:
        time_map = video.TimeMap.parse(args.time_map) if args.time_map else \
            video.DEFAULT_TIME_MAP
        path, frames = video.write_video(args.run_dir, args.out, time_map)
    except (video.NoImages, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    print(f'wrote {path} ({frames} film frames, {frames / video.FPS:.1f} s: '
          f'{time_map.describe()})')
    return 0


def cmd_analyse(args: argparse.Namespace) -> int:
    """Recompute metrics and figures from a bag."""
    bag = Path(args.bag)
    if not bag.exists():  # before any folder is made for its results
        raise FileNotFoundError(f'no bag at {bag}')
    out = Path(args.out) if args.out else bag.parent
    out.mkdir(parents=True, exist_ok=True)
    runner.clean_shm(print, 'earlier processes (e.g. a runner killed with SIGKILL)')
    try:
        if recover(bag):
            print(f'{bag} was not closed (its recorder was killed): recovered what it holds')
        metrics = results.write_results(bag, out)
    except (BagUnreadable, analysis.NotAnalysable, ReaderError) as exc:
        print(f'error: nothing to analyse: {exc}', file=sys.stderr)
        return 2
    except Exception as exc:  # noqa: B902 (a message, no traceback: exit code 1)
        print(f'error: the analysis of {bag} failed: {type(exc).__name__}: {exc}',
              file=sys.stderr)
        return 1
    print(f'wrote {out}/metrics.json and figures from {bag}')
    _print_summary(metrics)
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """Run the paper's scenario 1 (ideal actuators) into results/scenario1, with its film."""
    args.scenario = 'scenario1'
    args.out = args.out or 'results/scenario1'
    args.param = ['actuators:=ideal'] + list(args.param)
    # The film of this run, from its own bag (its camera images rendered again from its
    # joint states after the run: recording them would slow the run).
    args.video = args.video or not args.no_video
    return cmd_run(args)


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


def cmd_vsbench(args: argparse.Namespace) -> int:
    """Run the workspace benchmark (make vsbench; ibvs vsbench --help for its options)."""
    from . import vsbench
    return vsbench.main(args.vsbench_args)


def _study_defaults():
    from . import study
    return {'domains': study.DOMAIN_IDS, 'parallel': study.default_parallel()}


def plain_text(doc: str) -> str:
    """Return a docstring as a terminal shows it: reST roles and literals as plain text."""
    return re.sub(r':\w+:`~?([^`]+)`', r'\1', doc).replace('``', "'")


def _run_parsers(sub: Any) -> None:
    """Add ``ibvs run`` and ``ibvs demo`` to the subcommands ``sub``."""
    for name, func in (('run', cmd_run), ('demo', cmd_demo)):
        p = sub.add_parser(name, help=func.__doc__)
        if name == 'run':
            p.add_argument('scenario', help='scenario1, scenario2, scenario3, real_cell (a '
                           'real cell simulated: the arm and the camera driven as a real '
                           'IRB 4600 and ZED 2 are, docs/real_cell.md) or a parameter file')
        p.add_argument('--no-figures', dest='figures', action='store_false',
                       help='write the bag and metrics.json only (ibvs analyse draws the '
                       'figures from the bag later)')
        p.add_argument('-o', '--out', help='output directory (default: ' + (
            'a folder of its own under results/runs named after the scenario, the -p values '
            'and --duration, e.g. results/runs/scenario1_0.5s)' if name == 'run'
            else 'results/scenario1)'))
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
                       help='write the film video.mp4 (ibvs video; the camera images '
                       "rendered again from the run's joint states unless --images)")
        if name == 'demo':
            p.add_argument('--no-video', action='store_true',
                           help='no film (the demo writes <out>/video.mp4 by default)')
        p.set_defaults(func=func)


def _cell_parser(sub: Any) -> None:
    """Add ``ibvs cell`` to the subcommands ``sub``."""
    p = sub.add_parser('cell', help=cmd_cell.__doc__)
    p.add_argument('--controller', choices=tuple(cell.CONTROLLERS), default='forward_command',
                   help="the arm's position controller: forward_command (abb_ros2's "
                   'forward_command_controller_position, std_msgs/Float64MultiArray) or '
                   'joint_trajectory (its joint_trajectory_controller); default %(default)s')
    p.add_argument('--controller-name', help="the controller's name if not abb_ros2's "
                   '(forward_command_controller_position, joint_trajectory_controller)')
    p.add_argument('--camera-name', default=cell.DEFAULT_CAMERA,
                   help="the ZED wrapper's camera_name (its topics /<name>/zed_node/...; "
                   'default %(default)s)')
    p.add_argument('--params-file', help="the nodes' parameters (default: the installed "
                   'config/cell.yaml; a copy with camera_pose calibrated, for instance)')
    p.add_argument('-p', '--param', action='append', default=[],
                   help='override a parameter: name:=value (repeatable)')
    p.add_argument('-o', '--out', help="folder for params.yaml and the nodes' logs "
                   '(default results/cell/<date-time>)')
    p.add_argument('--check-timeout', type=cell.check_seconds, default=cell.CHECK_TIMEOUT_S,
                   help="wall seconds the cell's topics have to appear before the nodes "
                   'start (default %(default)s; exit code 5 if they do not)')
    p.add_argument('--teach', metavar='DIR', help='a teach folder (ibvs teach -o DIR): its '
                   'pair published latched from this process for the feature node, its '
                   'target (the forward kinematics of the joints taught) as the target')
    p.add_argument('--dry-run', action='store_true',
                   help="the joint controller's dry_run: the references computed and "
                   'published on /ibvs/dry_run/commands (joint_trajectory: '
                   '/ibvs/dry_run/joint_trajectory), nothing on the command topic; the arm '
                   'stays where it is and no controller need be there')
    p.set_defaults(func=cmd_cell)


def _calibrate_parser(sub: Any) -> None:
    """Add ``ibvs calibrate`` to the subcommands ``sub``."""
    from ibvs_model import handeye

    from . import calibrate  # its defaults (no ROS, no seconds of start-up)
    p = sub.add_parser('calibrate', help=cmd_calibrate.__doc__)
    p.add_argument('--bag', help='a recording of the arm held still at each pose while the '
                   'feature node ran (/joint_states, /ibvs/features, /ibvs/feature_status, '
                   'camera_info); default: the offline simulator')
    p.add_argument('-n', '--count', type=int, default=handeye.DEFAULT_POSES,
                   help='poses to draw in view of the nominal camera (default %(default)s)')
    p.add_argument('--seed', type=int, default=0, help='seed of the drawn poses (default '
                   '%(default)s)')
    p.add_argument('--poses', help='a poses file (joints_deg: six joint angles in degrees '
                   'a pose) instead of drawn poses')
    p.add_argument('--draw-poses', metavar='FILE', help='only write the drawn poses to FILE '
                   '(to jog a cell through, or for --poses)')
    p.add_argument('-p', '--param', action='append', default=[],
                   help="the simulator's parameters (name:=value, repeatable; e.g. "
                   'camera_pose_error_xyz_m:=[0.006,-0.008,0]); camera_pose: the nominal camera '
                   '(default: the /stereo/pose the simulator, or the bag, has)')
    p.add_argument('--still-tol-deg', type=float,
                   default=math.degrees(handeye.STILL_TOL_RAD),
                   help='with --bag: how far a joint may move while the arm counts as still '
                   '(default %(default).2g deg)')
    p.add_argument('-o', '--out', default=str(calibrate.DEFAULT_OUT),
                   help='the parameter file of the result (default %(default)s)')
    p.add_argument('--force', action='store_true',
                   help='replace an output file that ibvs calibrate did not write')
    p.set_defaults(func=cmd_calibrate)


def _teach_parser(sub: Any) -> None:
    """Add ``ibvs teach`` to the subcommands ``sub``."""
    from ibvs_model import handeye

    from . import teach
    p = sub.add_parser('teach', help=cmd_teach.__doc__)
    p.add_argument('-o', '--out', help='the teach folder: left.png, right.png, teach.yaml, '
                   'target.yaml (default results/teach/<date-time>; a folder of other files '
                   'is refused)')
    p.add_argument('--teach-frames', type=int, default=teach.DEFAULT_FRAMES,
                   help='consecutive stereo pairs of the still tool to average, pixel by '
                   'pixel (teach_frames, 1 to 100; default %(default)s)')
    p.add_argument('--camera-name', default=cell.DEFAULT_CAMERA,
                   help="the ZED wrapper's camera_name (its topics /<name>/zed_node/...; "
                   'default %(default)s)')
    p.add_argument('--timeout', type=positive_seconds, default=teach.TIMEOUT_S,
                   help='wall seconds the frames have to come (default %(default)s; exit code '
                   f'{teach.EXIT_NO_FRAMES} if they do not)')
    p.add_argument('--still-tol-deg', type=float,
                   default=math.degrees(handeye.STILL_TOL_RAD),
                   help='how far a joint may move over the frames while the arm counts as '
                   'still (default %(default).2g deg; a larger move takes them again)')
    p.add_argument('--publish', metavar='DIR', help='publish the pair of a teach folder '
                   'latched on /stereo/teach/{left,right}/image_raw until Ctrl-C, for a graph '
                   'started by hand (ibvs cell --teach DIR publishes it itself)')
    p.set_defaults(func=cmd_teach)


def _other_parsers(sub: Any, study_defaults: dict[str, Any]) -> None:
    """Add ``ibvs video``, ``analyse``, ``study``, ``report`` and ``vsbench`` to ``sub``."""
    p = sub.add_parser('video', help=cmd_video.__doc__)
    p.add_argument('run_dir', help='a run directory (with bag/)')
    p.add_argument('-o', '--out', help='the MP4 file (default RUN_DIR/video.mp4)')
    p.add_argument('--time-map', help='film speed over sim time, SPEED@UNTIL_S,...,SPEED '
                   '(default 0.25@1,1: a quarter of real time for the first second, then '
                   'real time)')
    p.set_defaults(func=cmd_video)
    p = sub.add_parser('analyse', help=cmd_analyse.__doc__)
    p.add_argument('bag', help='bag directory of a run')
    p.add_argument('-o', '--out', help='output directory (default: next to the bag)')
    p.set_defaults(func=cmd_analyse)
    p = sub.add_parser('study', help=cmd_study.__doc__)
    p.add_argument('spec', help='a study spec file, or the name of an installed one')
    p.add_argument('-o', '--out', help='parent of the study directory (default results/studies)')
    p.add_argument('--stall-s', type=positive_seconds, default=runner.STALL_S,
                   help='wall seconds without sim-time progress that fail a run (default '
                   '%(default)s)')
    p.add_argument('--retry-failed', action='store_true',
                   help='run again the runs recorded as failed (a failed run stays cached '
                   'as failed otherwise)')
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
    # listed here; its options are vsbench's own (main hands them over before parsing)
    p = sub.add_parser('vsbench', help=cmd_vsbench.__doc__, add_help=False)
    p.set_defaults(func=cmd_vsbench, vsbench_args=[])
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


def command_parser(study_defaults: dict[str, Any]) -> argparse.ArgumentParser:
    """Return the ``ibvs`` command line's parser (``study_defaults``: :func:`_study_defaults`)."""
    parser = argparse.ArgumentParser(prog='ibvs', description=plain_text(__doc__),
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='command', required=True)
    _run_parsers(sub)
    _cell_parser(sub)
    _calibrate_parser(sub)
    _teach_parser(sub)
    _other_parsers(sub, study_defaults)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the command line and run the command."""
    try:
        study_defaults = _study_defaults()
    except domains.DomainError as exc:  # a broken IBVS_ROS_DOMAINS: no command can run
        print(f'error: {exc}', file=sys.stderr)
        return 2
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ['vsbench']:
        args = argparse.Namespace(func=cmd_vsbench, vsbench_args=argv[1:])
    else:
        args = command_parser(study_defaults).parse_args(argv)
    try:
        return args.func(args)
    except (scenario.ScenarioError, study_spec.StudyError, FileNotFoundError,
            TimeoutError, domains.DomainError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130


if __name__ == '__main__':
    sys.exit(main())
