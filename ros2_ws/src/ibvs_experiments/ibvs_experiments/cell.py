"""
``ibvs cell``: the controller side of a real cell, without the simulator.

On a cell the arm is abb_ros2's ros2_control driver (EGM) and the camera is Stereolabs'
zed-ros2-wrapper; this command starts the four nodes that turn the camera's frames into
joint references (feature, adaptive feedback, feedforward and joint controller), each in a
process of its own as ``ros2 run`` starts it (:class:`ibvs_bringup.supervision.NodeProcess`),
with ``config/cell.yaml`` (real_cell.yaml less the simulator's keys, on the wall clock) and
the remappings to the driver's and the wrapper's names (:func:`remaps`: no code change in a
node). docs/real_cell.md is the manual; this module docstring is the contract.

1. **Parameters** (:func:`cell_parameters`): the file, the ``-p`` overrides, then the
   controller's ``position_command_type``; every name must be declared by one of the four
   nodes (a simulator's key would be ignored by all of them: refused, named) and in range.
2. **The cell's topics** (:func:`expectations`, :func:`problems`), before any node starts:
   each topic the nodes read has a publisher of the right type whose QoS our subscription
   matches (the rectified images and their camera_info, /joint_states; /stereo/pose while
   ``camera_pose`` is zeros; the taught pair while ``target_features_source`` is
   ``taught``), and the command topic has a subscriber (the position controller; not in a
   dry run, which commands nobody), within
   ``check_timeout_s`` (10 s; discovery takes a second or two). What is missing is named
   with what to look at, e.g. zed-ros2-wrapper's ``video.publish_left_right``, false by
   default (master 33dfefa ``zed_wrapper/config/common_stereo.yaml`` L54; the wrapper
   reads it at ``zed_components/src/zed_camera/src/zed_camera_component_main.cpp`` L904 and
   creates the left and right publishers only when it is true,
   ``zed_camera_component_video_depth.cpp`` L258-261 and L391-395); then the command exits
   with :data:`EXIT_CHECK_FAILED` and nothing has started. Then one left and one right
   camera_info (:func:`wait_for_camera_info`) must be a rectified pair at one of the ZED 2's
   native sizes (:func:`ibvs_bringup.cell_camera.camera_problems`: a downscaled 640 x
   360, the wrapper's ``general.pub_resolution: 'CUSTOM'``, is refused naming it; a camera
   that sends none within :data:`CAMERA_INFO_TIMEOUT_S` is named in a warning, not refused).
   With a teach (``--teach DIR``, :mod:`.teach`) this process publishes its pair latched
   before the check (which then finds it), takes its target (the cli sets it), and
   refuses another publisher of the pair (:func:`foreign_publishers`: a simulator that
   teaches for itself).
3. **Run**: the recorder of ``ibvs run`` (:class:`ibvs_bringup.recorder.Recorder`) opens
   ``bag/`` in the session's folder, with the parameters, the teach record and, at the end,
   the session (exit codes, dry run) in its metadata, /joint_states included, on the wall
   clock without sim time; ``ibvs analyse DIR/bag`` reads it (:mod:`ibvs_analysis.analysis`:
   a cell's tool poses are the kinematics of /joint_states where the simulator's truth is not
   there). Then the four processes start; a status line once a second
   (:class:`ibvs_analysis.cell_status.StatusBoard`): DRY RUN first in a dry run (the joint
   controller's ``dry_run``: its references on :func:`dry_run_topic`, none on the command
   topic), the joint controller's ``/ibvs/servo_status`` code and name
   (:class:`ibvs_common.servo_codes.ServoStatus`), the second publishers a node names on
   /diagnostics (``second_publishers``: :class:`ibvs_common.kit.PublisherWatch`, which every
   node runs), the image error (:meth:`StatusBoard.image_error`: |s - s*| of the features the
   loop used, /ibvs/features, against the taught target's, /ibvs/target_features; without a
   taught target the feedback node's own ``image_error_norm_px`` on /diagnostics) and the
   model's pose error (:class:`PoseError`: the nominal kinematics of the newest /joint_states
   against the target), the camera's stamp offset once the feature node has estimated one
   (its ``stamp_offset_ms`` and ``stamp_offset_sd_ms`` on /diagnostics, and its state when it
   holds: pass it as ``stamp_offset_initial_s`` next time), the frames used (its
   ``/ibvs/frame_latency``, one per frame a command used) and the last error any node
   reported there (a WARN or ERROR status, or a rejected input). A new servo status or second
   publisher prints a line at once, without waiting for the second. A node that exits ends
   the session (:data:`EXIT_NODE_DIED`), the others stopped.
4. **Stop**: one SIGINT (Ctrl-C; taken between two spins of the launcher's supervising
   loop, :func:`ibvs_bringup.launcher.supervise`, as ``ibvs run`` takes it, so that it
   never lands inside the recorder's message) stops every process together
   (:func:`ibvs_bringup.supervision.stop_all`: SIGINT, then SIGTERM, then SIGKILL of each
   process group; each also dies with this process, PR_SET_PDEATHSIG; the recorder takes
   their last messages meanwhile), then the bag is closed; exit code 0.

The ROS domain is the cell's: ``ROS_DOMAIN_ID``, else ROS's default 0 (never a free one of
the pool: the driver and the camera are on the cell's), and this process holds that
domain's lock (:mod:`ibvs_bringup.domains`) so that no ``ibvs run`` on this machine starts
a simulator there.

The session's life (its domain, its rclpy, the supervising loop, the exit codes) is the
launcher's (:mod:`ibvs_bringup.launcher`); the checks of steps 1 and 2 are
:mod:`ibvs_bringup.cell_checks`', whose names are importable from here too.
"""

from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
import sys
import time
from typing import Any, TYPE_CHECKING

from ibvs_analysis.cell_status import PoseError, StatusBoard  # noqa: F401 (re-exported)
from ibvs_bringup import launcher, scenario
from ibvs_bringup.cell_checks import (  # noqa: F401 (re-exported: the names of ibvs cell's checks)
    CAMERA_INFO_TIMEOUT_S, camera_topics, CELL_CONFIG, CELL_NODES, cell_parameters, CellError,
    check_seconds, CHECK_TIMEOUT_S, command_topic, config_path, Controller, CONTROLLERS,
    declared_by, DEFAULT_CAMERA, dry_run_topic, Endpoint, endpoints_of, Expectation,
    expectations, foreign_publishers, mismatch, problems, remap_args, remaps, simulator_only,
    TEACH_TOPICS, wait_for_camera_info, wait_for_topics, ZED_LEFT_RIGHT, ZED_NODE)
from ibvs_bringup.graph import GRAPH
from ibvs_bringup.launcher import EXIT_CHECK_FAILED, EXIT_NODE_DIED  # noqa: F401 (re-exported)
from ibvs_common import contract
from ibvs_common.shared_params import target_from_parameters

if TYPE_CHECKING:
    from .teach import Recorded

#: Wall time (s) between two status lines.
STATUS_PERIOD_S = 1.0
#: Wall time (s) the session spins between two looks of its supervising loop (node exits,
#: news, the status line's second).
POLL_S = 0.05
#: Where ``ibvs cell`` writes its parameters and the nodes' logs without ``-o``.
CELL_DIR = Path('results') / 'cell'
#: What a session replaces of a previous one in its folder, by name, once its check passed
#: (as ``ibvs run`` does): the bag and the metrics ``ibvs analyse`` wrote beside it.
SESSION_RESULTS = ('bag', 'metrics.json')


@contextmanager
def _session_folder(out_dir: Path, procs: Sequence[Any]) -> Iterator[tuple[Path, Any]]:
    """
    Hold a session's folder (:func:`.output_dir.claim`); yield its params.yaml and the claim.

    Claimed once the cell's domain is held, so that a refused start (its domain busy, the
    folder refused) makes no folder; one this start made is removed again, with the
    ``params.yaml``, the empty ``logs/`` and the marker it wrote there, when no node
    started (``procs``, the list the nodes' processes are appended to, still empty: the
    check failed, or SIGINT came during it).
    """
    from . import output_dir
    claimed = output_dir.claim(out_dir)
    try:
        (out_dir / 'logs').mkdir(exist_ok=True)
        yield out_dir / 'params.yaml', claimed
    finally:
        claimed.release(None if procs else ('params.yaml', 'logs'))


def run_cell(params: Mapping[str, Any], out_dir: str | Path, controller: str = 'forward_command',
             camera_name: str = DEFAULT_CAMERA, controller_name: str | None = None,
             check_timeout_s: float = CHECK_TIMEOUT_S,
             print_line: Callable[[str], None] = print, live: bool = False,
             teach: 'Recorded | None' = None) -> int:
    """
    Check the cell's topics, start the four nodes, show their status until SIGINT; stop.

    ``params``: :func:`cell_parameters`'s (``dry_run`` true: :func:`expectations` wants no
    command subscriber, the status line says DRY RUN). ``teach``: a recorded teach
    (:class:`.teach.Recorded`) whose pair this process publishes latched (module docstring,
    step 2).
    Returns the exit code: 0 after SIGINT with every process stopped,
    :data:`EXIT_CHECK_FAILED` when the check fails (nothing started),
    :data:`EXIT_NODE_DIED` when a node exits, 130 after a SIGINT during the check
    (nothing started). ``live``: rewrite one status line in place (a terminal) instead of a
    line each second. Raises :class:`ibvs_bringup.domains.DomainBusy` when another run
    holds the cell's domain.

    The launcher holds the cell's domain (ROS's default 0 unless ``ROS_DOMAIN_ID`` says
    another, :func:`ibvs_bringup.launcher.held_domain`), gives the session its rclpy
    (:func:`ibvs_bringup.launcher.ros_session`) and runs its supervising loop
    (:func:`ibvs_bringup.launcher.supervise`) with the status line's tick
    (:func:`_status_tick`).
    """
    from ibvs_bringup.job_control import interruptible
    from ibvs_bringup.supervision import stop_all
    from rclpy.executors import SingleThreadedExecutor
    import yaml

    from ibvs_analysis import analysis

    out_dir = Path(out_dir)
    node_remaps = remaps(controller, camera_name, controller_name)
    expected = expectations(params, controller, camera_name, controller_name)
    procs = []
    recorder = None
    info = {'session': 'ibvs cell', 'interrupted': False, 'dry_run': bool(params.get(
        'dry_run', False)), 'controller': controller, 'camera_name': camera_name}
    with interruptible(deferred=True) as stop, launcher.held_domain(default=0) as domain, \
            _session_folder(out_dir, procs) as (params_file, claimed), \
            launcher.ros_session('ibvs_cell', executor=SingleThreadedExecutor) as ros:
        stopped = stop.is_set if stop is not None else (lambda: False)
        params_file = scenario.write_parameters(dict(params), params_file)
        started = time.monotonic()
        try:
            found = _checked(ros, expected, camera_name, check_timeout_s, teach, domain,
                             print_line, stopped)
            if found:
                for text in found:
                    print(f'error: {text}', file=sys.stderr)
                print(f'error: the cell is not ready ({len(found)} problem(s)); no node '
                      'started', file=sys.stderr)
                return EXIT_CHECK_FAILED
            command = command_topic(controller, controller_name)
            others = ros.node.get_publishers_info_by_topic(command)
            if others:
                print_line(f'warning: {command} already has publisher(s) '
                           f'{", ".join(i.node_name for i in others)}: they command the '
                           'same controller')
            board = _status_board(ros.node, info['dry_run'])
            claimed.remove(SESSION_RESULTS)  # a previous session's, by name
            recorder = ros.add(_recorder(ros, out_dir / 'bag', params, teach))
            _start_nodes(procs, params_file, out_dir / 'logs', node_remaps)
            print_line(f'started {", ".join(f"{p.name} (pid {p.proc.pid})" for p in procs)}; '
                       + (f'DRY RUN: references on {dry_run_topic(controller)}, nothing to the '
                          'arm; ' if info['dry_run'] else f'commands on {command}; ')
                       + f'logs in {out_dir / "logs"}, the bag in {out_dir / "bag"}; Ctrl-C '
                       'stops them all')
            tick = _status_tick(board, procs, recorder, PoseError(target_from_parameters(params)),
                                print_line, live)
            return launcher.supervise(ros.executor, tick, stop, POLL_S)
        except KeyboardInterrupt:
            if live:
                print_line('')
            if not procs:  # during the check: nothing to stop, and the session never ran
                print_line('SIGINT during the check: no node started')
                return 130
            print_line(f'SIGINT: stopping {", ".join(p.name for p in procs)}')
            codes = stop_all(procs, executor=ros.executor)
            info['exit_codes'] = codes
            procs = []
            print_line('stopped: ' + ', '.join(f'{n} exit {c}' for n, c in codes.items()))
            return 0
        finally:
            if procs:
                info['exit_codes'] = stop_all(procs, executor=ros.executor)
            if recorder is not None:
                info['wall_duration_s'] = time.monotonic() - started
                recorder.set_custom_data(analysis.RUN_KEY, yaml.safe_dump(info))
                recorder.close()
                print_line(f'wrote the bag {out_dir / "bag"} (ibvs analyse {out_dir / "bag"}: '
                           'its metrics and figures)')


def _checked(ros: 'launcher.RosSession', expected: Sequence[Any], camera_name: str,
             check_timeout_s: float, teach: 'Recorded | None', domain: int,
             print_line: Callable[[str], None], stopped: Callable[[], bool]) -> list[str]:
    """Check the cell's topics and camera (module docstring, step 2); return the problems."""
    node = ros.node
    if teach is not None:  # ours before the check: the check then finds it
        teach_pubs = teach.publish(node)
        print_line(f'publishing the taught pair of {teach.folder} latched on '
                   f'{teach_pubs[0].topic_name} and {teach_pubs[1].topic_name}')
    print_line(f"ibvs cell: ROS_DOMAIN_ID {domain}; checking the cell's topics (up to "
               f'{check_timeout_s:g} s): ' + ', '.join(e.topic for e in expected))
    found = wait_for_topics(node, expected, check_timeout_s, stopped=stopped)
    if teach is not None:
        found += foreign_publishers(node, TEACH_TOPICS, (
            'ibvs cell --teach publishes the taught pair itself: stop the other '
            'publisher (a simulator standing in for the cell: -p '
            'target_features_source:=model), or leave out --teach'))
    if not found:
        found, camera_line = wait_for_camera_info(
            node, camera_name, CAMERA_INFO_TIMEOUT_S,
            lambda s: ros.executor.spin_once(timeout_sec=s), stopped=stopped)
        print_line(camera_line)
    return found


def _recorder(ros: 'launcher.RosSession', bag: Path, params: Mapping[str, Any],
              teach: 'Recorded | None') -> Any:
    """
    Return the session's recorder into ``bag``, with the parameters and the teach record.

    The bag (module docstring, step 3): the nodes' topics from before they start;
    /joint_states too (a cell's tool poses), on the wall clock without sim time.
    """
    from ibvs_bringup.recorder import Recorder
    import yaml

    from ibvs_analysis import analysis

    custom = {analysis.PARAMS_KEY: yaml.safe_dump(dict(params))}
    if teach is not None:
        custom[analysis.TEACH_KEY] = yaml.safe_dump(dict(teach.record))
    return Recorder(bag, include_per_step=True, custom_data=custom, context=ros.context,
                    wall_clock=not params.get('use_sim_time', False))


def _status_board(node: Any, dry_run: bool) -> 'StatusBoard':
    """Return a :class:`StatusBoard` fed by ``node``'s subscriptions (module docstring, step 3)."""
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import PolygonStamped
    from ibvs_common.conversions import stamp_ns
    from sensor_msgs.msg import TimeReference
    from std_msgs.msg import Int8

    board = StatusBoard(dry_run=dry_run)
    node.create_subscription(Int8, contract.SERVO_STATUS, lambda m: board.servo(m.data),
                             contract.LATCHED)
    node.create_subscription(TimeReference, contract.FRAME_LATENCY,
                             lambda m: board.frame_used(stamp_ns(m.time_ref)),
                             contract.RELIABLE)

    def on_diagnostics(msg):
        for s in msg.status:
            level = s.level[0] if isinstance(s.level, bytes) else int(s.level)
            board.diagnostics(s.name, level, s.message, {kv.key: kv.value for kv in s.values})

    node.create_subscription(DiagnosticArray, contract.DIAGNOSTICS, on_diagnostics, 10)
    for topic, qos, attr in ((contract.FEATURES, contract.RELIABLE, 'features_px'),
                             (contract.TARGET_FEATURES, contract.LATCHED, 'target_px')):
        node.create_subscription(PolygonStamped, topic, lambda m, a=attr: board.take(a, m), qos)
    return board


def _start_nodes(procs: list, params_file: Path, log_dir: Path,
                 node_remaps: Mapping[str, Mapping[str, str]]) -> None:
    """Start the cell's nodes (:data:`CELL_NODES`), a process each, appended to ``procs``."""
    from ibvs_bringup.supervision import NodeProcess

    for name in CELL_NODES:
        spec = GRAPH.node(name)
        procs.append(NodeProcess(spec.package, name, params_file, log_dir,
                                 remap_args(node_remaps.get(name, {}))))


def _status_tick(board: 'StatusBoard', procs: Sequence[Any], recorder: Any,
                 pose_of: PoseError, print_line: Callable[[str], None],
                 live: bool) -> Callable[[], int | None]:
    """
    Return the session's look at the cell, once a tick of the launcher's supervising loop.

    A node that exits ends the session (:data:`EXIT_NODE_DIED`, said on stderr); news
    (:meth:`StatusBoard.take_news`) or the status line's second prints the status line.
    """
    from ibvs_bringup.supervision import NodeDied

    next_line = time.monotonic()

    def tick():
        nonlocal next_line
        dead = next((p for p in procs if p.poll() is not None), None)
        if dead is not None:
            if live:
                print_line('')
            print(f'error: {NodeDied(dead.name, dead.poll(), dead.log_path)}; stopping the '
                  'others', file=sys.stderr)
            return EXIT_NODE_DIED
        news = board.take_news()
        if news or time.monotonic() >= next_line:
            if time.monotonic() >= next_line:
                next_line += STATUS_PERIOD_S
            board.pose_error(*pose_of(recorder.latest.get(contract.JOINT_STATES)))
            if live:
                sys.stdout.write('\r\033[K' + board.line())
                sys.stdout.flush()
            else:
                print_line(board.line())
                sys.stdout.flush()  # to a file or a pipe (tee) as soon as to a tty
        return None

    return tick
