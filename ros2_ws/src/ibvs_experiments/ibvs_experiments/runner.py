"""
Run one scenario through the node graph: start the nodes, record, watch, stop, analyse.

Each process is started exactly as ``ros2 run <package> <executable> --ros-args
--params-file <params.yaml>`` would start it: with ``ros2 run`` itself when the CLI is
installed, otherwise with the same installed executable that ``ros2 run`` would resolve
(``<prefix>/lib/<package>/<executable>`` from the ament index), in the processes of the
graph's description (:mod:`ibvs_bringup.graph`): every node has a process of its own but the
joint controller, which runs in the simulator's (:mod:`ibvs_bringup.compose`);
:mod:`ibvs_bringup.supervision` starts and stops them. The runner records the run, prints
progress, stops when the sim time limit is reached or the tool has converged, and stops
every process cleanly (SIGINT, then SIGTERM, then SIGKILL). If a node dies, the run stops
and :class:`NodeDied` names it and its exit code; no process is left behind in any case
(children also get SIGKILL if the runner dies). The Fast DDS shared memory that a killed
process leaves in /dev/shm is removed, and the runner says so (:mod:`.shm`): at the end of a
run what its dead processes left, at the start what earlier dead processes left.

No silent hang: a configuration that cannot advance sim time is refused before any node
starts (:func:`scenario.check_progress`), and a run whose sim time stops advancing for
``stall_s`` of wall time ends with :class:`RunStalled`, which quotes what each node last
said it waits for (its once-a-second "waiting ..." log line and the ``waiting_for`` values
it publishes on /diagnostics).
"""

from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
import json
import os
from pathlib import Path
import re
import signal
import threading
import time
from typing import Any, TYPE_CHECKING

from diagnostic_msgs.msg import DiagnosticArray
from ibvs_bringup import domains, graph_params, scenario, shm
from ibvs_bringup.graph import (GRAPH, Graph, process_plan, uses_frame_states, uses_zed_names,
                                ZED_TOPICS)
from ibvs_bringup.recorder import Recorder, recover
from ibvs_bringup.supervision import expected_readers, NodeDied, NodeProcess, stop_all
from ibvs_common import contract, dds
from ibvs_common.conversions import pose_matrix
from ibvs_common.node_main import make_executor, StopRequest, WATCHDOG
from ibvs_common.shared_params import target_from_parameters
from ibvs_common.timing import ns_to_seconds
from ibvs_model import CameraRobotModel, inverse_kinematics, IRB4600
from nav_msgs.msg import Path as PathMsg
import numpy as np
from numpy.typing import NDArray
import rclpy
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
import yaml

from . import analysis, convergence, output_dir

if TYPE_CHECKING:
    from rclpy.executors import Executor
    from rclpy.node import Node


#: Default wall time without sim-time progress after which a run is declared stalled (s).
#: Long enough for the slowest single step seen on a loaded 2-core machine (the
#: feedforward's trajectory at t = 0 took 11 s with a load average of 17); the runner then
#: names who waits for what.
STALL_S = 60.0
#: Default wall time from the last node's launch to the simulator's first step (s):
#: start-up (PyBullet, EGL, discovery) takes seconds, more on a loaded machine.
START_TIMEOUT_S = 120.0
#: Wall time between two looks of the runner at the run (progress, stall, end, node exits).
POLL_S = 0.02
#: Wall time between two progress lines of :func:`watch` (one only once sim time moved).
PROGRESS_S = 2.0
#: What the stall report says of a node that reported no wait: busy, frozen, or a node that
#: does not report its waits.
SILENT = 'said nothing about waiting (no "waiting" log line, no /diagnostics waiting_for)'
#: Wall time (s) without a /diagnostics from a node after which its heartbeat counts as
#: stopped: every node publishes its status once a second on a steady clock, also while it
#: waits (ibvs_common.diagnostics), so only a frozen or hung node falls silent that long.
HEARTBEAT_S = 3.0
#: A node's log line saying what it waits for: ``[LEVEL] [<epoch s>] [<node>]: waiting ...``.
_WAITING_LINE = re.compile(r'^\[\w+\] \[(\d+(?:\.\d+)?)\] \[([^\]]+)\]: (waiting .*)$')


#: What a run into a previous run's folder removes of it first (:func:`prepare`): the
#: entries it writes anew whole; the rest it writes (params.yaml, logs/<process>.log, the
#: figures) it overwrites.
REPLACED = ('bag', 'metrics.json')

#: ``ibvs run``'s exit code when a node process died during the run (:class:`NodeDied`);
#: 2 is a refused configuration, 4 a stall (cli.cmd_run).
EXIT_NODE_DIED = 3
#: ``ibvs run``'s exit code when the taught target could not be measured (:class:`TeachFailed`;
#: 5 is ``ibvs cell``'s, its topics missing).
EXIT_TEACH_FAILED = 6


class TeachFailed(RuntimeError):
    """
    The feature node measured no target features on the teach pair: no frame can be answered.

    With ``target_features_source: taught`` the simulator renders the tool at the target
    once, before the run, and the feature node measures p_bar on that pair; when it cannot
    (a marker hidden or cut at the target) it says so on /diagnostics
    (``contract.TEACH_FAILED``), and :func:`watch` ends the run at once instead of waiting
    for the stall bound. ``node``: who said it; ``why``: its words.
    """

    def __init__(self, node: str, why: str, sim_s: float) -> None:
        """Keep who said it and why; the message says what to change."""
        super().__init__(
            f'teach failed at sim time {sim_s:.3f} s: {node} measured no target features on '
            f'the teach pair ({why}), and every frame would wait for them. The markers must '
            'be seen whole at the target: another target or camera pose, or '
            'target_features_source:=model')
        self.node = node
        self.why = why
        self.sim_s = sim_s


class RunStalled(RuntimeError):
    """
    Sim time stopped advancing; ``waits`` maps each node to what it said it waits for.

    ``causes``: what holds the run, named first: a process that is stopped, a node busy in
    one callback (its process's :class:`ibvs_common.node_main.Watchdog`). ``silent`` names
    the other nodes whose /diagnostics heartbeat stopped (:meth:`Monitor.silent`): frozen or
    hung, with no more said of them.
    """

    def __init__(self, what: str, sim_s: float, waits: Mapping[str, str],
                 silent: Sequence[str] = (), causes: Sequence[str] = ()) -> None:
        """Keep the sim time reached and each node's wait; the message lists them."""
        lines = [f'  {node}: {text}' for node, text in waits.items()]
        head = f'; cause: {"; ".join(causes)}' if causes else ''
        head += (f'; heartbeat stopped: {", ".join(silent)} (no /diagnostics for more than '
                 f'{HEARTBEAT_S:g} s: frozen or hung)' if silent else '')
        super().__init__(f'{what} at sim time {sim_s:.3f} s{head}; what each node waits '
                         'for:\n' + '\n'.join(lines))
        self.sim_s = sim_s
        self.waits = waits
        self.silent = tuple(silent)
        self.causes = tuple(causes)


def last_waiting_line(log_path: str | Path, since_epoch_s: float,
                      node: str | None = None) -> str | None:
    """
    Return the last "waiting ..." line a node logged at or after ``since_epoch_s``, or None.

    ``node``: only the lines of that node's logger (a process that holds several nodes).

    Every node of the graph logs what it waits for once a second while it makes no progress
    (``sim_node``, ``joint_controller_node``; DESIGN section 4): a line from within the
    stall window is what the node waits for now.
    """
    try:
        text = Path(log_path).read_text(errors='replace')
    except FileNotFoundError:
        return None
    found = None
    for line in text.splitlines():
        match = _WAITING_LINE.match(line.strip())
        if match and float(match.group(1)) >= since_epoch_s and \
                node in (None, match.group(2)):
            found = match.group(3)
    return found


@dataclass
class RunResult:
    """What a run produced: where, its metrics, and whether it converged."""

    out_dir: Path
    bag_path: Path
    metrics: dict
    converged: bool
    #: The recorder's own cost: ibvs_common.profiling.Stopwatch values (``make bench``).
    recording: dict = None
    #: Whether SIGINT ended the run early (the metrics are those of what was recorded).
    interrupted: bool = False


class Monitor:
    """
    Sim time and tool pose of the running graph, for progress, convergence and stalls.

    Read from what the recorder (same process) receives: no subscription of its own to the
    per-step topics, so the graph does not deliver each step twice to this process, and the
    newest tool pose is decoded only when :meth:`poll` is called (every ``POLL_S`` of wall
    time), not at each step.
    """

    def __init__(self, node: 'Node', recorder: Recorder, target: NDArray[np.float64],
                 clock: Callable[[], float] = time.monotonic) -> None:
        """Follow ``recorder``'s /clock and /ibvs/tool_path; /diagnostics on ``node``."""
        self._clock = clock
        #: Wall time (``clock``) of the latest /diagnostics of each node, by node name.
        self.heard = {}
        self.target = target
        self._recorder = recorder
        self._pose_raw = None
        self.sim_ns = 0
        self.error_m = float('nan')
        self.axis_deg = float('nan')
        self.within_since_ns = None
        #: Wall time (time.monotonic) at which the first /clock was seen: the run's start.
        self.started_wall = None
        #: Latest /diagnostics status values of each node, by node name.
        self.diagnostics = {}
        #: What the watchdog of a node's process last said of it (the callback it is busy
        #: in, ibvs_common.node_main.Watchdog) and when (``clock``), by node name.
        self.busy = {}
        node.create_subscription(DiagnosticArray, contract.DIAGNOSTICS, self._on_diagnostics,
                                 10)

    def poll(self) -> None:
        """Take the newest sim time and tool pose the recorder has received."""
        recorder = self._recorder
        if self.started_wall is None and recorder.counts.get(contract.CLOCK):
            self.started_wall = time.monotonic()
        self.sim_ns = max(self.sim_ns, recorder.clock_ns)
        raw = recorder.latest.get(contract.TOOL_PATH)
        if raw is None or raw is self._pose_raw:
            return
        self._pose_raw = raw
        poses = deserialize_message(raw, PathMsg).poses
        if poses:
            tf = pose_matrix(poses[-1].pose)
            self.error_m = float(np.linalg.norm(tf[:3, 3] - self.target[:3, 3]))
            self.axis_deg = float(analysis.axis_angle_deg(tf[None, :3, :3],
                                                          self.target[:3, :3])[0])

    def _on_diagnostics(self, msg):
        for status in msg.status:
            node, _, what = status.name.partition(': ')
            if what == WATCHDOG:  # not the node's heartbeat: its process's watchdog
                self.busy[node] = (status.message, self._clock())
                continue
            self.diagnostics[node] = {kv.key: kv.value for kv in status.values}
            self.heard[node] = self._clock()

    def teach_failed(self) -> tuple[str, str] | None:
        """Return (node, why) of a node whose /diagnostics says its teach failed, or None."""
        for node, values in self.diagnostics.items():
            if values.get(contract.TEACH_FAILED):
                return node, values[contract.TEACH_FAILED]
        return None

    def restart_clocks(self) -> None:
        """
        Count every node heard now: the runner itself could not listen for a while.

        A runner stopped (Ctrl-Z, SIGSTOP, a debugger) or starved longer than
        :data:`HEARTBEAT_S` heard nobody meanwhile, also nodes that went on publishing:
        their silence is the runner's (:func:`watch` calls this then), not theirs.
        """
        now = self._clock()
        for node in self.heard:
            self.heard[node] = now

    def busy_now(self) -> dict[str, str]:
        """Return what the watchdogs said of busy nodes in the last :data:`HEARTBEAT_S`."""
        now = self._clock()
        return {n: text for n, (text, when) in self.busy.items() if now - when <= HEARTBEAT_S}

    def silent(self, nodes: Iterable[str]) -> list[str]:
        """Return those of ``nodes`` whose heartbeat stopped (none for :data:`HEARTBEAT_S`)."""
        now = self._clock()
        return [n for n in nodes if n in self.heard and now - self.heard[n] > HEARTBEAT_S]

    def stalled_sim_s(self) -> float:
        """Return the sim time of the stall: the simulator's own status if newer than /clock."""
        sim = self.diagnostics.get('sim_node', {}).get('sim_time_s')
        try:
            return max(ns_to_seconds(self.sim_ns), float(sim))
        except (TypeError, ValueError):
            return ns_to_seconds(self.sim_ns)

    def waits(self, procs: Sequence[NodeProcess], since_epoch_s: float,
              stopped: Mapping[str, str] | None = None) -> dict[str, str]:
        """
        Return, per node, what it last said it waits for (log line, /diagnostics).

        Each /diagnostics value is quoted with the age of the status it comes from. Said
        first: that its process is stopped (``stopped``: {process name: what is stopped}),
        that it is busy in a callback (:meth:`busy_now`), that it waits behind such a node of
        its process (one executor runs one callback at a time), or else that its heartbeat
        stopped.
        """
        out = {}
        now = self._clock()
        stopped = stopped or {}
        busy = self.busy_now()
        for p in procs:
            name = getattr(p, 'name', p.nodes[0])
            blocking = [n for n in p.nodes if n in busy]
            for node in p.nodes:
                said = []
                line = last_waiting_line(p.log_path, since_epoch_s,
                                         node if len(p.nodes) > 1 else None)
                if line:
                    said.append(line)
                age = (f' (status {now - self.heard[node]:.1f} s old)'
                       if node in self.heard else '')
                said += [f'/diagnostics {k} = {v}{age}'
                         for k, v in self.diagnostics.get(node, {}).items()
                         if k.startswith('waiting') and v not in ('', '-1')]
                out[node] = '; '.join(said) or SILENT
                if name in stopped:
                    out[node] = f'STOPPED: its process {name} {stopped[name]}; ' + out[node]
                elif node in busy:
                    out[node] = f'BUSY: {busy[node]}; ' + out[node]
                elif blocking:
                    out[node] = (f'waits behind {blocking[0]} (the process {name} runs one '
                                 'callback at a time); ' + out[node])
                elif node in self.silent([node]):
                    out[node] = (f'HEARTBEAT STOPPED: last /diagnostics '
                                 f'{now - self.heard[node]:.1f} s ago (frozen or hung); '
                                 + out[node])
        return out

    def update_convergence(self, tolerance: convergence.Convergence) -> float:
        """
        Track since when the tool has been within ``tolerance``; return that duration (s).

        ``tolerance``: a :class:`~.convergence.Convergence`.
        """
        inside = tolerance.within(self.error_m, self.axis_deg)
        if not inside:
            self.within_since_ns = None
            return 0.0
        if self.within_since_ns is None:
            self.within_since_ns = self.sim_ns
        return ns_to_seconds(self.sim_ns - self.within_since_ns)


@dataclass
class Prepared:
    """A run ready to start (:func:`prepare`): its parameters and its files."""

    params: dict
    #: The sim time limit (s).
    duration_s: float
    out_dir: Path
    log_dir: Path
    params_file: Path
    bag_path: Path
    #: The target pose (4x4), from the parameters.
    target: np.ndarray
    #: The output folder, held while the run lives (:func:`.output_dir.claim`).
    claim: output_dir.Claim = None


@dataclass
class Outcome:
    """How :func:`watch` saw a run end: converged, a node's death, a failed teach, a stall..."""

    converged: bool = False
    died: NodeDied = None
    stalled: RunStalled = None
    teach_failed: TeachFailed = None
    #: Wall time from step 0 to the end (s); None if the run never got to :func:`watch`'s end.
    wall_duration_s: float = None
    #: SIGINT (KeyboardInterrupt) ended the run: what was recorded is analysed.
    interrupted: bool = False
    #: Optional processes (the viewers' node) that exited during the run: name -> exit code.
    lost: dict = field(default_factory=dict)
    #: Wall time (s) the runner itself did not run (stopped, or starved for more than
    #: :data:`HEARTBEAT_S` at once): said, and not held against the graph.
    paused_s: float = 0.0


def run_scenario(name: str, out_dir: str | Path, overrides: Mapping[str, Any] | None = None,
                 duration_s: float | None = None, record_images: bool = False,
                 wall_timeout_s: float = 1800.0, converge_hold_s: float | None = None,
                 progress: Callable[[str], None] = print, stall_s: float = STALL_S,
                 start_timeout_s: float = START_TIMEOUT_S, record_overlays: bool = False,
                 figures: bool = True,
                 on_metrics: Callable[[dict[str, Any]], None] | None = None,
                 graph: Graph = GRAPH) -> RunResult:
    """
    Run scenario ``name`` through the graph; write bag, metrics and figures to ``out_dir``.

    ``figures=False`` writes the bag and metrics only (``ibvs analyse`` draws the figures
    later): a study's runs save the seconds of matplotlib each.
    ``on_metrics(metrics)``: called as soon as ``metrics.json`` is written, before the
    figures (:func:`write_results`).

    ``record_overlays`` records the feature node's overlay images (/ibvs/debug/*/image,
    which it then draws for every frame; ``ibvs video`` makes a film of them).

    ``duration_s`` is the sim time limit (default: the scenario file's ``run_duration_s``,
    else 3 s). With ``converge_hold_s`` the run ends early once the tool has stayed within
    0.1 mm and 0.01 deg of the target for that long (sim time: :data:`.convergence.HOLD`). Raises
    :class:`scenario.ScenarioError` for a parameter no node declares or out of its range
    (:func:`graph_params.check`) or a configuration that cannot make progress (before
    starting anything), :class:`domains.DomainBusy` if its ROS domain is another run's
    (:mod:`ibvs_bringup.domains`), :class:`NodeDied` if a node exits, :class:`TeachFailed`
    if the feature node measured no taught target, and
    :class:`RunStalled` if sim time does not advance for ``stall_s`` of wall time (or the
    simulator has not taken its first step ``start_timeout_s`` after it was launched).
    A ``ROS_DOMAIN_ID`` or ``IBVS_ROS_DOMAINS`` that cannot be used raises
    :class:`domains.DomainError` before anything is written, and an output folder that
    is not an empty, new, study's or previous run's one, or that a live run holds,
    :class:`.output_dir.OutputRefused` before anything in it is touched. The death of an optional
    process (the viewers', :func:`optional`) once the simulator runs is said and the run
    goes on. SIGINT (also to a runner started with it ignored, :func:`interruptible`) stops
    the run as its end does, and the metrics of what was recorded are written
    (``RunResult.interrupted``); before the first step it raises KeyboardInterrupt.

    ``graph``: the graph's description (default :data:`~ibvs_bringup.graph.GRAPH`;
    ``GRAPH.separate()`` runs every node in a process of its own, as ``ros2 run`` by hand
    does: the equivalence test compares the two).

    The parts, in order: :func:`prepare`, :func:`start`, :func:`watch`, :func:`stop`,
    :func:`write_results`.
    """
    domains.domain_id()
    domains.pool()
    run = prepare(name, out_dir, overrides, duration_s)
    try:
        with interruptible(deferred=True) as interrupt:
            return _run_prepared(run, record_images, wall_timeout_s, converge_hold_s,
                                 progress, stall_s, start_timeout_s, record_overlays, figures,
                                 on_metrics, graph, interrupt)
    finally:
        run.claim.release()


@contextmanager
def interruptible(deferred: bool = False) -> Iterator[StopRequest | None]:
    """
    Let SIGINT interrupt what runs inside, also where the runner was started with it ignored.

    A shell starts a background job (``nohup ibvs run ... &``) with SIGINT ignored, and
    Python then installs no handler of its own: the runner could not be stopped by SIGINT.
    Inside, SIGINT raises KeyboardInterrupt (Python's own handler), which
    :func:`run_scenario` turns into a clean stop and the metrics of what was recorded; the
    handler found is put back after. Outside the main thread, where no handler can be
    set, nothing changes (None is yielded).

    ``deferred``: the first SIGINT only sets the yielded
    :class:`ibvs_common.node_main.StopRequest`, which :func:`watch` reads between two
    spins, as a node's spin loop does; a second raises KeyboardInterrupt at once. Python's
    handler raises at whatever bytecode runs next, and inside rclpy's C++ conversion of a
    message the recorder takes it surfaced as pybind11's "Unable to convert function return
    value" instead: the run ended with exit code 1 and no metrics (seen once in four
    ``make test`` runs of ``test_sigint_writes_the_metrics_also_when_the_runner_ignored_it``).
    """
    if threading.current_thread() is not threading.main_thread():
        yield None
        return
    if deferred:
        stop = StopRequest((signal.SIGINT,))
        stop.install()
        try:
            yield stop
        finally:
            stop.restore()
        return
    previous = signal.getsignal(signal.SIGINT)
    if previous is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield None
    finally:
        if previous is signal.SIG_IGN:
            signal.signal(signal.SIGINT, previous)


@dataclass
class JobStops:
    """How many times Ctrl-Z stopped the graph with the runner (:func:`stops_with_the_runner`)."""

    count: int = 0


@contextmanager
def stops_with_the_runner(procs: Sequence[NodeProcess]) -> Iterator[JobStops | None]:
    """
    Within, Ctrl-Z of the runner stops its graph too, and ``fg`` continues both (job control).

    Every node runs in a process group of its own (:func:`ibvs_common.process.supervised_child`),
    so the terminal's SIGTSTP reaches the runner alone, and the graph, which after step 0
    waits for nothing of the runner's, would run on without its recorder: past the run's
    end, with a bag that lacks everything sent meanwhile. Here SIGTSTP stops each process of
    ``procs`` (SIGSTOP to its group; the list as it is then: :func:`start` fills it) and
    then the runner itself; the SIGCONT of ``fg`` (or ``kill -CONT``) continues the
    processes the runner stopped, and only those. The lockstep then resumes at the step it
    was at: the run's numbers are those of a run never stopped. A runner stopped alone
    (SIGSTOP, a debugger) stops nothing else: :func:`watch` tells its own stop from the
    graph's. Yields the :class:`JobStops` it counts (None outside the main thread, where no
    handler can be set and nothing changes); the handlers found are put back after, and
    what is still stopped is continued.
    """
    if threading.current_thread() is not threading.main_thread():
        yield None
        return
    held, stops = [], JobStops()

    def go_on(*_):
        while held:
            held.pop().send_signal(signal.SIGCONT)

    def stop_all_and_self(*_):
        held.extend(p for p in procs if p.poll() is None and p not in held)
        for p in held:
            p.send_signal(signal.SIGSTOP)
        stops.count += 1
        os.kill(os.getpid(), signal.SIGSTOP)
        go_on()  # continued: SIGCONT's handler may not have run yet

    previous = {sig: signal.signal(sig, handler) for sig, handler in
                ((signal.SIGTSTP, stop_all_and_self), (signal.SIGCONT, go_on))}
    try:
        yield stops
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        go_on()


def _run_prepared(run, record_images, wall_timeout_s, converge_hold_s, progress, stall_s,
                  start_timeout_s, record_overlays, figures, on_metrics, graph=GRAPH,
                  interrupt=None):
    """Run the :class:`Prepared` ``run`` (:func:`run_scenario` after :func:`prepare`)."""
    clean_shm(progress, 'earlier processes (e.g. a runner killed with SIGKILL)')
    shm_before = shm.names()

    # A domain of its own (ibvs_bringup.domains), for this process and its nodes.
    with domains.held() as (domain, chosen):
        busy = chosen and domain != domains.pool()[0]
        progress(f'  ROS_DOMAIN_ID {domain}'
                 + (': the first free one, lower domains are used by other runs' if busy
                    else ' (set by ROS_DOMAIN_ID)' if not chosen else ''))
        dds.configure()  # before rclpy.init here, and inherited by the node processes
        context = rclpy.context.Context()
        # Explicit arguments: by default rclpy parses sys.argv, where rcl takes the
        # command line's -p name:=value for a deprecated remap rule and warns about it.
        # No rclpy signal handler: SIGINT is the runner's (interruptible, read by watch), and
        # the recorder goes on receiving while the nodes stop. No shared memory for the
        # runner itself: stopped (Ctrl-Z), it would not hear the graph again (dds).
        with dds.without_shared_memory():
            rclpy.init(args=[], context=context,
                       signal_handler_options=SignalHandlerOptions.NO)
        executor = make_executor(context)
        recorder = Recorder(run.bag_path, include_images=record_images, context=context,
                            include_overlays=record_overlays,
                            custom_data={analysis.PARAMS_KEY: yaml.safe_dump(run.params)})
        watcher = rclpy.create_node('ibvs_run_monitor', context=context,
                                    parameter_overrides=[])
        monitor = Monitor(watcher, recorder, run.target)
        executor.add_node(recorder)
        executor.add_node(watcher)
        procs = []
        outcome = Outcome()
        wall_start = time.monotonic()
        try:
            with stops_with_the_runner(procs) as job:
                start(run, executor, procs, graph)
                outcome = watch(run, executor, monitor, procs, wall_start, progress,
                                interrupt=interrupt, converge_hold_s=converge_hold_s,
                                wall_timeout_s=wall_timeout_s, stall_s=stall_s,
                                start_timeout_s=start_timeout_s, job=job)
        except KeyboardInterrupt:
            # SIGINT: stop as at the end of a run, and analyse what was recorded.
            progress(f'  interrupted (SIGINT) at sim time {ns_to_seconds(monitor.sim_ns):.3f}'
                     ' s: stopping the nodes, then the metrics of what was recorded')
            outcome.interrupted = True
            outcome.wall_duration_s = time.monotonic() - (monitor.started_wall or wall_start)
        finally:
            codes = stop(procs, graph, executor=executor)
            recorder.set_custom_data(analysis.RUN_KEY, yaml.safe_dump({
                'duration_s': run.duration_s, 'wall_duration_s': outcome.wall_duration_s,
                'exit_codes': codes, 'commands': {p.name: p.command for p in procs},
                'interrupted': outcome.interrupted, 'lost_processes': outcome.lost,
                'runner_paused_s': outcome.paused_s}))
            recorder.close()
            executor.shutdown()
            recorder.destroy_node()
            watcher.destroy_node()
            rclpy.shutdown(context=context)
            clean_shm(progress, 'node processes of this run that died', shm_before)
    if outcome.died:
        raise outcome.died
    if outcome.teach_failed:
        raise outcome.teach_failed
    if outcome.stalled:
        raise outcome.stalled
    if outcome.interrupted and monitor.sim_ns == 0:
        raise KeyboardInterrupt  # nothing was simulated: no metrics to write
    metrics = write_results(run.bag_path, run.out_dir, outcome.wall_duration_s, figures,
                            on_metrics)
    return RunResult(run.out_dir, run.bag_path, metrics, outcome.converged,
                     recorder.timing.values(), outcome.interrupted)


def resolve(name: str, overrides: Mapping[str, Any] | None = None,
            duration_s: float | None = None) -> tuple[dict[str, Any], float]:
    """
    Return the checked parameters of scenario ``name`` with ``overrides``, and the sim time.

    The scenario file's values, then the overrides (:func:`graph_params.check`,
    :func:`graph_params.check_rules`, :func:`scenario.check_progress` raise here); the sim
    time is ``duration_s``, else the ``duration_s`` parameter (the simulator's stop when
    started by hand) if > 0 (both, if they differ, are refused), else the file's
    ``run_duration_s``, else 3 s. Nothing is
    written (:func:`prepare` writes).
    """
    params = scenario.load_parameters(name)
    params.update(overrides or {})
    graph_params.check(params)
    graph_params.check_rules(params)
    scenario.check_progress(params)
    params.setdefault('scenario_name', Path(str(name)).stem)
    stop_s = params.get('duration_s')  # the simulator's stop when started by hand
    if stop_s and duration_s is not None and float(stop_s) != float(duration_s):
        raise scenario.ScenarioError(
            f'duration_s = {stop_s} and a sim time limit of {duration_s} s (--duration, or '
            "a study's duration_s): the runner stops the run, give one of them")
    if duration_s is None and stop_s:
        duration_s = stop_s
    duration_s = float(duration_s if duration_s is not None else params.get('run_duration_s', 3.0))
    return params, duration_s


def prepare(name: str, out_dir: str | Path, overrides: Mapping[str, Any] | None = None,
            duration_s: float | None = None) -> Prepared:
    """
    Check the parameters of scenario ``name`` with ``overrides``; write its parameters file.

    Return the :class:`Prepared` run, its output folder held (:func:`.output_dir.claim`:
    an empty, new, study's or previous run's folder that no live run holds, else
    :class:`.output_dir.OutputRefused`) until ``Prepared.claim.release()``; of a previous
    run's files only :data:`REPLACED` are removed. Nothing is started: the checks of
    :func:`run_scenario` that come before any node (:func:`graph_params.check`,
    :func:`scenario.check_progress`) raise here, before the folder is touched.
    """
    params, duration_s = resolve(name, overrides, duration_s)
    out_dir = Path(out_dir)
    # The folder's rule (.output_dir): empty, a study's or a previous run's, and not in use.
    claimed = output_dir.claim(out_dir, output_dir.STUDY_COMPANIONS)
    try:
        claimed.remove(REPLACED)
        log_dir = out_dir / 'logs'
        log_dir.mkdir(exist_ok=True)
        # duration_s: the runner stops the graph at the run's sim time limit itself (watch).
        node_params = {k: v for k, v in params.items() if k not in scenario.RUNNER_ONLY}
        params_file = scenario.write_parameters(node_params, out_dir / 'params.yaml')
    except BaseException:
        claimed.release()
        raise
    bag_path = out_dir / 'bag'
    return Prepared(params, duration_s, out_dir, log_dir, params_file, bag_path,
                    target_from_parameters(params), claimed)


def start(run: Prepared, executor: 'Executor', procs: list[NodeProcess],
          graph: Graph = GRAPH) -> None:
    """
    Start the processes of ``graph`` for ``run`` (:func:`process_plan`), appending to ``procs``.

    All at once, the simulator's last: its first step waits until every reader of step 0
    is matched (:func:`expected_readers`: the graph's readers and the runner's recorder and
    monitor), so that no node misses it (volatile topics: a node that misses the first
    /joint_states or CameraInfo waits for ever, and so does the lockstep). A node that never
    subscribes leaves the simulator saying what it waits for, and :func:`watch` ends the run
    after ``start_timeout_s`` with that in :class:`RunStalled`; a process that exits ends it
    with :class:`NodeDied`.
    """
    topic_of = ZED_TOPICS if uses_zed_names(run.params) else {}
    for spec, extra in process_plan(run.params, graph):
        if graph.simulator in spec.nodes:
            frame_states = uses_frame_states(run.params)
            counts = expected_readers(executor.get_nodes(), graph.step0_readers(frame_states),
                                      topic_of)
            if not frame_states:  # free-running: no /stereo/joint_states to wait for
                counts[contract.FRAME_JOINT_STATES] = 0
            extra += ('-p', 'min_joint_state_subscribers:='
                      f'{counts[contract.JOINT_STATES]}',
                      '-p', 'min_frame_joint_state_subscribers:='
                      f'{counts[contract.FRAME_JOINT_STATES]}',
                      '-p', f'min_tool_path_subscribers:={counts[contract.TOOL_PATH]}',
                      '-p', f'min_joint_path_subscribers:={counts[contract.JOINT_PATH]}',
                      '-p', 'min_camera_info_subscribers:='
                      f'{min(counts[contract.LEFT_INFO], counts[contract.RIGHT_INFO])}')
        procs.append(spec.start(run.params_file, run.log_dir, extra))


def watch(run: Prepared, executor: 'Executor', monitor: Monitor,
          procs: Sequence[NodeProcess], wall_start: float,
          progress: Callable[[str], None] = print, converge_hold_s: float | None = None,
          wall_timeout_s: float = 1800.0, stall_s: float = STALL_S,
          start_timeout_s: float = START_TIMEOUT_S,
          interrupt: StopRequest | None = None, job: JobStops | None = None) -> Outcome:
    """
    Spin and look at the run every ``POLL_S`` until it ends; return its :class:`Outcome`.

    Raises KeyboardInterrupt between two spins once ``interrupt`` is set (SIGINT,
    :func:`interruptible` deferred).

    It ends when a process exits (``died``), the feature node says it measured no taught
    target (``teach_failed``: :class:`TeachFailed`), the tool has converged
    (``converge_hold_s``),
    sim time reaches ``run.duration_s``, ``wall_timeout_s`` has passed since
    ``wall_start``, or sim time has not advanced for ``stall_s`` (``start_timeout_s``
    before step 0: ``stalled``). Progress is printed every :data:`PROGRESS_S` of wall time
    when sim time has moved since the last line; before step 0, once, that the nodes start.

    The runner's own stop is not the graph's: when more than :data:`HEARTBEAT_S` of wall
    time passed between two of its looks (Ctrl-Z and ``fg``, SIGSTOP and SIGCONT, a
    debugger, a starved CPU) it heard no heartbeat and saw no step meanwhile, so it says so
    and starts its stall and heartbeat clocks again (:meth:`Monitor.restart_clocks`); the
    time is added to ``Outcome.paused_s``. Ctrl-Z stopped the graph with it (``job``, one
    more in its count: :func:`stops_with_the_runner`): nothing was lost. Stopped alone, the
    graph ran on meanwhile (after step 0 nothing of the lockstep waits for the runner), and
    the bag lacks what a node's publisher could not keep for the stopped recorder (its
    queue: ``contract.RELIABLE``'s depth); the metrics take the steps before
    ``run.duration_s`` as always.
    """
    outcome = Outcome()
    procs = list(procs)
    last_print, printed_ns = 0.0, None
    last_sim_ns, last_advance = -1, time.monotonic()
    looked = last_advance  # the runner's own last look at the run
    job_stops = job.count if job is not None else 0
    never = Future()
    while True:
        # Every callback due in the next POLL_S, then one look at the run.
        executor.spin_until_future_complete(never, timeout_sec=POLL_S)
        if interrupt is not None and interrupt.is_set():
            raise KeyboardInterrupt
        gap = time.monotonic() - looked
        if gap > HEARTBEAT_S:
            # The runner itself did not run (its own stop: Ctrl-Z, SIGSTOP, a debugger; or
            # starved of CPU): it heard no heartbeat and saw no step meanwhile, whatever the
            # graph did. Its stall and heartbeat clocks start again from now.
            if job is not None and job.count > job_stops:
                job_stops = job.count
                said = ('stopped by Ctrl-Z with its graph, continued with it: nothing of '
                        'the run was lost')
            else:
                said = ('stopped alone: SIGSTOP, a debugger; or starved of CPU; the bag may '
                        'lack messages the graph sent meanwhile')
            progress(f'  the runner itself did not run for {gap:.1f} s of wall time ({said}):'
                     ' its stall and heartbeat clocks start again')
            monitor.restart_clocks()
            last_advance = time.monotonic()
            outcome.paused_s += gap
        looked = time.monotonic()
        monitor.poll()
        for p in procs:
            code = p.poll()
            if code is not None and optional(p) and monitor.started_wall is not None:
                # A viewer: nothing of the run waits for it once the simulator has started.
                progress(f'  the optional process {p.name} exited with code {code} at sim '
                         f'time {ns_to_seconds(monitor.sim_ns):.3f} s (log: {p.log_path}); '
                         'the run goes on without it')
                outcome.lost[p.name] = code
                procs.remove(p)
                break
            if code is not None:
                outcome.died = NodeDied(p.name, code, p.log_path, p.nodes)
                break
        if outcome.died:
            break
        failed = monitor.teach_failed()
        if failed is not None:
            outcome.teach_failed = TeachFailed(*failed, monitor.stalled_sim_s())
            break
        sim_s = ns_to_seconds(monitor.sim_ns)
        now = time.monotonic()
        if now - last_print >= PROGRESS_S and monitor.started_wall is None:
            if printed_ns is None:
                progress(f'  [{run.params["scenario_name"]}] starting: the nodes start up; '
                         'the simulator takes step 0 once every reader of it is there')
                printed_ns = -1
            last_print = now
        elif now - last_print >= PROGRESS_S and monitor.sim_ns != printed_ns:
            last_print, printed_ns = now, monitor.sim_ns
            rtf = sim_s / max(now - (monitor.started_wall or now), 1e-9)
            # Before the first tool pose there is no error to print yet.
            error = (f'{monitor.error_m * 1e3:9.3f} mm' if np.isfinite(monitor.error_m)
                     else '        - mm')
            axis = (f'{monitor.axis_deg:7.3f} deg' if np.isfinite(monitor.axis_deg)
                    else '      - deg')
            progress(f'  [{run.params["scenario_name"]}] sim {sim_s:6.3f}/{run.duration_s:.2f} s'
                     f'  position error {error}  axis error {axis}  RTF {rtf:5.3f}')
        if converge_hold_s is not None and \
                monitor.update_convergence(convergence.HOLD) >= converge_hold_s:
            outcome.converged = True
            break
        if sim_s >= run.duration_s:
            outcome.converged = bool(convergence.SUCCESS.within(monitor.error_m,
                                                                monitor.axis_deg))
            break
        if now - wall_start > wall_timeout_s:
            progress(f'  wall-clock limit {wall_timeout_s:.0f} s reached at sim '
                     f'{sim_s:.3f} s')
            break
        if monitor.sim_ns > last_sim_ns and monitor.started_wall is not None:
            last_sim_ns, last_advance = monitor.sim_ns, now
        limit = stall_s if monitor.started_wall is not None else start_timeout_s
        if now - last_advance > limit:
            window_start = time.time() - min(limit, 3.0)
            what = (f'no sim-time progress for {limit:.0f} s of wall time'
                    if monitor.started_wall is not None
                    else f'the simulator took no step within {limit:.0f} s of its launch')
            stopped = stopped_processes(procs)
            busy = monitor.busy_now()
            causes = [f'process {name} {text}' for name, text in stopped.items()]
            causes += [text for node, text in busy.items()
                       if not any(node in p.nodes and p.name in stopped for p in procs)]
            held = {n for p in procs if p.name in stopped or set(p.nodes) & set(busy)
                    for n in p.nodes}
            nodes = [n for p in procs for n in p.nodes if n not in held]
            outcome.stalled = RunStalled(what, monitor.stalled_sim_s(),
                                         monitor.waits(procs, window_start, stopped),
                                         monitor.silent(nodes), causes)
            break
    # From step 0 on: the nodes' start-up (PyBullet, EGL, discovery) is not sim time.
    outcome.wall_duration_s = time.monotonic() - (monitor.started_wall or wall_start)
    return outcome


def stopped_processes(procs: Sequence[NodeProcess]) -> dict[str, str]:
    """
    Return {process name: what of it is stopped} for the processes of ``procs`` that are.

    A stopped process (SIGSTOP: state T in /proc, :meth:`NodeProcess.stopped`) runs no
    callback and no watchdog: nothing of it reports, and it is named from outside. A
    stopped child (a worker it waits for) is named with its command line.
    """
    why = 'state T in /proc: SIGSTOP or a debugger'
    out = {}
    for p in procs:
        found = p.stopped()
        said = [f'is stopped (pid {pid}, {why})' for pid, _ in found if pid == p.proc.pid]
        said += [f'waits for its child {cmd or "?"} (pid {pid}), which is stopped ({why})'
                 for pid, cmd in found if pid != p.proc.pid]
        if said:
            out[p.name] = '; '.join(said)
    return out


def optional(process: NodeProcess, graph: Graph = GRAPH) -> bool:
    """
    Return whether the run can go on without ``process``: it holds none of the paper's nodes.

    The viewers' node (``viz_node``, :attr:`ibvs_bringup.graph.Node.paper` False) feeds
    RViz, Foxglove and the bag's /tf; no node of the lockstep waits for it once the
    simulator has taken its first step (before, the simulator waits for its subscriptions).
    """
    names = {n.name for n in graph.nodes if not n.paper}
    return bool(process.nodes) and all(n in names for n in process.nodes)


def stop(procs: Sequence[NodeProcess], graph: Graph = GRAPH,
         executor: 'Executor | None' = None) -> dict[str, int | None]:
    """
    Stop ``procs`` together; return their exit codes by name, in reverse start order.

    Every process gets each step of :func:`supervision.stop_all` at once, the simulator's
    signalled first: once it stops nothing is stepped, and a node that stops before it only
    makes it wait (the lockstep). The analysis takes the steps before the run's end only
    (:func:`.analysis.analyse_bag`), so the order cannot change a result. Stopping the
    simulator alone first would add its exit time to every run's.
    ``executor`` (the recorder's) spins meanwhile: the nodes' last /diagnostics, with
    their timing totals, reach the bag (a simulated second takes about one of wall time,
    between two of their heartbeats).
    """
    ordered = sorted(procs, key=lambda p: graph.simulator not in p.nodes)
    codes = stop_all(ordered, executor=executor)
    return {p.name: codes[p.name] for p in reversed(procs)}


def clean_shm(progress: Callable[[str], None], whose: str,
              new_since: set[str] | None = None) -> None:
    """
    Remove the Fast DDS shared memory dead processes left (:mod:`.shm`); say so.

    ``whose``: who left it, in the message given to ``progress``; ``new_since``: only what
    appeared since that :func:`shm.names` snapshot (what this run's processes left).
    """
    count, freed = shm.clean(new_since=new_since)
    if count:
        progress(f'  removed {count} Fast DDS shared-memory files ({freed / 1e6:.0f} MB) in '
                 f'{shm.SHM_DIR} that {whose} left')


def target_features(run: analysis.RunData) -> NDArray[np.float64] | None:
    """
    Return the target features the controller servoed to, for the feature figures.

    A taught run (``target_features_source: taught``): the features the feature node
    measured on the teach pair (:attr:`.analysis.RunData.taught_target`), which the
    controller used; F(q_target) would differ from them by the camera model's errors (a
    constant error in ``feature_error.png`` the controller never saw). Otherwise F(q_target)
    with the recorded camera and the nominal robot (None without a camera).
    """
    if run.params.get('target_features_source') == 'taught' and \
            run.taught_target is not None:
        return run.taught_target
    if run.camera is None:
        return None
    q = inverse_kinematics(run.target)
    return CameraRobotModel(run.camera, IRB4600).features(q)


def write_results(bag_path: str | Path, out_dir: str | Path,
                  wall_duration_s: float | None = None, figures: bool = True,
                  on_metrics: Callable[[dict[str, Any]], None] | None = None
                  ) -> dict[str, Any]:
    """
    Analyse a bag: write ``metrics.json`` and the figures into ``out_dir``; return metrics.

    ``on_metrics(metrics)`` is called once ``metrics.json`` is written, before the figures
    (matplotlib takes seconds): ``ibvs run`` prints the metrics then.
    """
    out_dir = Path(out_dir)
    recover(bag_path)  # the bag of a runner that was killed: readable again
    run, metrics = analysis.analyse_bag(bag_path)
    if wall_duration_s is not None:
        metrics['wall_duration_s'] = wall_duration_s
        metrics['real_time_factor'] = metrics['sim_duration_s'] / wall_duration_s
    metrics['bag'] = str(bag_path)
    (out_dir / 'metrics.json').write_text(json.dumps(metrics, indent=2) + '\n')
    if on_metrics is not None:
        on_metrics(metrics)
    if not figures:
        return metrics
    from . import plots  # here: matplotlib costs seconds of start-up
    plots.write_all(run, out_dir, target_features(run))
    if len(run.joints[0]):  # read and limited once, by analyse_bag
        plots.joints(run.joints, run.joint_limits, out_dir / 'joints.png', plots.title_of(run))
    return metrics
