"""
The launcher: the life of a run of the graph, from its domain lock to its exit code.

``ibvs run`` (ibvs_experiments.runner), ``ibvs cell`` (ibvs_experiments.cell) and the
studies (which run ``ibvs run``) are its clients; what it owns, in the order of a run:

1. **The domain** (:func:`held_domain`): the run's ROS domain, locked on this machine
   (:mod:`.domains`): the first free one of the pool, or ``ROS_DOMAIN_ID``, or a default
   (a cell's: ROS's 0).
2. **The session** (:func:`ros_session`): the middleware's settings (:func:`ibvs_common.dds.
   configure`, inherited by the node processes), a private rclpy context with no signal
   handler of rclpy's (SIGINT is the launcher's, :func:`.job_control.interruptible`), an
   executor and the observer node; the recorder (:class:`.recorder.Recorder`) joins it.
3. **The start** (:func:`start`): the processes of the graph's description
   (:mod:`.graph`, :mod:`.supervision`), the simulator's last.
4. **One supervising loop** (:func:`supervise`): spin, take a deferred SIGINT, and let the
   client's per-tick callback look at the run; :func:`watch` is a simulated run's
   (progress, convergence, stalls, deaths: :mod:`.monitor`), ``ibvs cell`` has its own
   (the status line).
5. **The stop** (:func:`stop`, :func:`.supervision.stop_all`) of every process together, the
   bag closed, the session shut down, and the Fast DDS shared memory dead processes left
   removed (:func:`clean_shm`, :mod:`.shm`).

What the launcher knows of a run's success comes in as callables (:class:`Success`): it
imports no analysis and nothing of ibvs_experiments. The exit codes of the ``ibvs``
commands: 0 done, 2 a refused configuration, :data:`EXIT_NODE_DIED`, 4 a stall,
:data:`EXIT_CHECK_FAILED`, :data:`EXIT_TEACH_FAILED`, 130 SIGINT before anything ran.
"""

from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
import os
from pathlib import Path
import time
from typing import Any, TYPE_CHECKING, TypeVar

from ibvs_common import contract, dds
from ibvs_common.node_main import make_executor, StopRequest
from ibvs_common.timing import ns_to_seconds
import numpy as np
import rclpy
from rclpy.signals import SignalHandlerOptions
from rclpy.task import Future
import yaml

from . import domains, shm
from .graph import GRAPH, Graph, process_plan, uses_frame_states, uses_zed_names, ZED_TOPICS
from .job_control import JobStops, stops_with_the_runner
from .monitor import (HEARTBEAT_S, Monitor, PoseErrors, RunStalled, STALL_S, START_TIMEOUT_S,
                      stopped_processes, TeachFailed)
from .recorder import Recorder
from .supervision import expected_readers, NodeDied, NodeProcess, stop_all

if TYPE_CHECKING:
    from rclpy.context import Context
    from rclpy.executors import Executor
    from rclpy.node import Node

#: Wall time between two looks of the launcher at the run (progress, stall, end, node exits).
POLL_S = 0.02
#: Wall time between two progress lines of :func:`watch` (one only once sim time moved).
PROGRESS_S = 2.0
#: ``ibvs run``'s exit code when a node process died during the run (:class:`NodeDied`), and
#: ``ibvs cell``'s when a node exits; 2 is a refused configuration, 4 a stall.
EXIT_NODE_DIED = 3
#: ``ibvs cell``'s exit code when a topic of the cell is missing or does not match.
EXIT_CHECK_FAILED = 5
#: ``ibvs run``'s exit code when the taught target could not be measured (:class:`TeachFailed`).
EXIT_TEACH_FAILED = 6

#: What :func:`supervise`'s per-tick callback returns to end the loop.
Ended = TypeVar('Ended')


@dataclass(frozen=True)
class Success:
    """
    What the launcher is told of a run's success, by its client: callables, no analysis.

    ``errors(pose, target)``: the tool's position (m) and tool-axis (deg) errors of a pose
    against the target (:data:`.monitor.PoseErrors`); ``settled(error_m, axis_deg)``:
    whether they are within the tolerance a run may end early on, once held for
    ``converge_hold_s``; ``reached(error_m, axis_deg)``: whether they are a success, at the
    run's sim time limit.
    """

    errors: PoseErrors
    settled: Callable[[float, float], bool]
    reached: Callable[[float, float], bool]


@dataclass
class Prepared:
    """A run ready to start (a client's ``prepare``): its parameters and its files."""

    params: dict
    #: The sim time limit (s).
    duration_s: float
    out_dir: Path
    log_dir: Path
    params_file: Path
    bag_path: Path
    #: The target pose (4x4), from the parameters.
    target: np.ndarray
    #: The client's hold on the output folder while the run lives (its ``release()`` ends it).
    claim: Any = None


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
    #: :data:`.monitor.HEARTBEAT_S` at once): said, and not held against the graph.
    paused_s: float = 0.0


@dataclass
class Ran:
    """What :func:`run_graph` hands back: its outcome, the sim time reached, the recording."""

    outcome: Outcome
    #: The last sim time seen (ns): 0 when nothing was simulated.
    sim_ns: int
    #: The recorder's own cost: ibvs_common.profiling.Stopwatch values (``make bench``).
    recording: dict


@contextmanager
def held_domain(progress: Callable[[str], None] | None = None,
                default: int | None = None) -> Iterator[int]:
    """
    Hold the run's ROS domain within (:func:`.domains.held`); yield it.

    ``default``: the domain to take when ``ROS_DOMAIN_ID`` is unset (a cell's: ROS's 0,
    never a free one of the pool), set in the environment for this process and its nodes;
    without it, the first free domain of the pool. ``progress`` is told which domain, and
    why (``ibvs run``'s line). Raises :class:`.domains.DomainBusy` when another run holds it.
    """
    if default is not None and domains.domain_id() is None:
        os.environ[domains.DOMAIN_ENV] = str(default)
    with domains.held() as (domain, chosen):
        if progress is not None:
            busy = chosen and domain != domains.pool()[0]
            progress(f'  ROS_DOMAIN_ID {domain}'
                     + (': the first free one, lower domains are used by other runs' if busy
                        else ' (set by ROS_DOMAIN_ID)' if not chosen else ''))
        yield domain


@dataclass
class RosSession:
    """The launcher's own rclpy: a private context, its executor, the observer node."""

    context: 'Context'
    executor: 'Executor'
    node: 'Node'
    #: Nodes added with :meth:`add`, destroyed with the session (before :attr:`node`).
    nodes: list = field(default_factory=list)

    def add(self, node: 'Node') -> 'Node':
        """Spin ``node`` (the recorder) in the session's executor; return it."""
        self.executor.add_node(node)
        self.nodes.append(node)
        return node


@contextmanager
def ros_session(node_name: str, shared_memory: bool = True,
                executor: Callable[['Context'], 'Executor'] = make_executor
                ) -> Iterator[RosSession]:
    """
    Within, a private rclpy context with the observer node ``node_name`` in ``executor``.

    The middleware's settings first (:func:`ibvs_common.dds.configure`: before rclpy.init
    here, and inherited by the node processes). Explicit arguments: by default rclpy parses
    sys.argv, where rcl takes the command line's ``-p name:=value`` for a deprecated remap
    rule and warns about it. No rclpy signal handler: SIGINT is the launcher's
    (:func:`.job_control.interruptible`, read by :func:`supervise`), and the recorder goes
    on receiving while the nodes stop. ``shared_memory`` False: none for this process (a
    runner stopped by Ctrl-Z would not hear the graph again, :mod:`ibvs_common.dds`). On the
    way out: the executor shut down, the added nodes and the observer destroyed, the
    context shut down.
    """
    dds.configure()
    context = rclpy.context.Context()
    if shared_memory:
        rclpy.init(args=[], context=context, signal_handler_options=SignalHandlerOptions.NO)
    else:
        with dds.without_shared_memory():
            rclpy.init(args=[], context=context,
                       signal_handler_options=SignalHandlerOptions.NO)
    spinner = executor(context=context)
    observer = rclpy.create_node(node_name, context=context, parameter_overrides=[])
    spinner.add_node(observer)
    session = RosSession(context, spinner, observer)
    try:
        yield session
    finally:
        spinner.shutdown()
        for node in session.nodes:
            node.destroy_node()
        observer.destroy_node()
        context.try_shutdown()


def start(run: Prepared, executor: 'Executor', procs: list[NodeProcess],
          graph: Graph = GRAPH) -> None:
    """
    Start the processes of ``graph`` for ``run`` (:func:`process_plan`), appending to ``procs``.

    All at once, the simulator's last: its first step waits until every reader of step 0
    is matched (:func:`expected_readers`: the graph's readers and the launcher's recorder
    and monitor), so that no node misses it (volatile topics: a node that misses the first
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


def supervise(executor: 'Executor', tick: Callable[[], Ended | None],
              interrupt: StopRequest | None = None, poll_s: float = POLL_S) -> Ended:
    """
    Spin for ``poll_s``, then ``tick()``, until it returns an end: the one supervising loop.

    Every callback due in the next ``poll_s`` runs, then one look at the run: the client's
    ``tick`` (:func:`watch`'s for a simulated run, ``ibvs cell``'s status line), whose first
    value other than None is returned. Raises KeyboardInterrupt between two spins once
    ``interrupt`` is set (SIGINT, :func:`.job_control.interruptible` deferred), never inside
    a callback.
    """
    while True:
        # A new future each spin: rclpy adds its wake-up callbacks to the future it is
        # given, so one future for a session of hours would hold them all.
        executor.spin_until_future_complete(Future(), timeout_sec=poll_s)
        if interrupt is not None and interrupt.is_set():
            raise KeyboardInterrupt
        ended = tick()
        if ended is not None:
            return ended


class _RunWatch:
    """:func:`watch`'s look at the run, once a tick: the state kept between two looks."""

    def __init__(self, run, monitor, procs, wall_start, progress, converge_hold_s,
                 wall_timeout_s, stall_s, start_timeout_s, job, success):
        self.run, self.monitor, self.procs = run, monitor, procs
        self.wall_start, self.progress, self.job, self.success = wall_start, progress, job, success
        self.converge_hold_s, self.wall_timeout_s = converge_hold_s, wall_timeout_s
        self.stall_s, self.start_timeout_s = stall_s, start_timeout_s
        self.outcome = Outcome()
        self.last_print, self.printed_ns = 0.0, None
        self.last_sim_ns, self.last_advance = -1, time.monotonic()
        self.looked = self.last_advance  # the runner's own last look at the run
        self.job_stops = job.count if job is not None else 0

    def __call__(self) -> Outcome | None:
        """Look at the run once; return its :class:`Outcome` once it has ended."""
        monitor, outcome = self.monitor, self.outcome
        self._own_pause()
        monitor.poll()
        if self._exits():
            return outcome
        failed = monitor.teach_failed()
        if failed is not None:
            outcome.teach_failed = TeachFailed(*failed, monitor.stalled_sim_s())
            return outcome
        sim_s = ns_to_seconds(monitor.sim_ns)
        now = time.monotonic()
        self._progress(sim_s, now)
        if self.converge_hold_s is not None and self.success is not None and \
                monitor.update_convergence(self.success.settled) >= self.converge_hold_s:
            outcome.converged = True
            return outcome
        if sim_s >= self.run.duration_s:
            outcome.converged = self.success is not None and bool(
                self.success.reached(monitor.error_m, monitor.axis_deg))
            return outcome
        if now - self.wall_start > self.wall_timeout_s:
            self.progress(f'  wall-clock limit {self.wall_timeout_s:.0f} s reached at sim '
                          f'{sim_s:.3f} s')
            return outcome
        if monitor.sim_ns > self.last_sim_ns and monitor.started_wall is not None:
            self.last_sim_ns, self.last_advance = monitor.sim_ns, now
        limit = self.stall_s if monitor.started_wall is not None else self.start_timeout_s
        if now - self.last_advance > limit:
            outcome.stalled = self._stalled(limit)
            return outcome
        return None

    def _own_pause(self):
        gap = time.monotonic() - self.looked
        if gap > HEARTBEAT_S:
            # The runner itself did not run (its own stop: Ctrl-Z, SIGSTOP, a debugger; or
            # starved of CPU): it heard no heartbeat and saw no step meanwhile, whatever the
            # graph did. Its stall and heartbeat clocks start again from now.
            job = self.job
            if job is not None and job.count > self.job_stops:
                self.job_stops = job.count
                said = ('stopped by Ctrl-Z with its graph, continued with it: nothing of '
                        'the run was lost')
            else:
                said = ('stopped alone: SIGSTOP, a debugger; or starved of CPU; the bag may '
                        'lack messages the graph sent meanwhile')
            self.progress(f'  the runner itself did not run for {gap:.1f} s of wall time '
                          f'({said}): its stall and heartbeat clocks start again')
            self.monitor.restart_clocks()
            self.last_advance = time.monotonic()
            self.outcome.paused_s += gap
        self.looked = time.monotonic()

    def _exits(self):
        """Take the processes that exited: an optional one is let go, any other ends the run."""
        monitor = self.monitor
        for p in self.procs:
            code = p.poll()
            if code is not None and optional(p) and monitor.started_wall is not None:
                # A viewer: nothing of the run waits for it once the simulator has started.
                self.progress(f'  the optional process {p.name} exited with code {code} at '
                              f'sim time {ns_to_seconds(monitor.sim_ns):.3f} s (log: '
                              f'{p.log_path}); the run goes on without it')
                self.outcome.lost[p.name] = code
                self.procs.remove(p)
                return False
            if code is not None:
                self.outcome.died = NodeDied(p.name, code, p.log_path, p.nodes)
                return True
        return False

    def _progress(self, sim_s, now):
        monitor, name = self.monitor, self.run.params['scenario_name']
        if now - self.last_print >= PROGRESS_S and monitor.started_wall is None:
            if self.printed_ns is None:
                self.progress(f'  [{name}] starting: the nodes start up; the simulator takes '
                              'step 0 once every reader of it is there')
                self.printed_ns = -1
            self.last_print = now
        elif now - self.last_print >= PROGRESS_S and monitor.sim_ns != self.printed_ns:
            self.last_print, self.printed_ns = now, monitor.sim_ns
            rtf = sim_s / max(now - (monitor.started_wall or now), 1e-9)
            # Before the first tool pose there is no error to print yet.
            error = (f'{monitor.error_m * 1e3:9.3f} mm' if np.isfinite(monitor.error_m)
                     else '        - mm')
            axis = (f'{monitor.axis_deg:7.3f} deg' if np.isfinite(monitor.axis_deg)
                    else '      - deg')
            self.progress(f'  [{name}] sim {sim_s:6.3f}/{self.run.duration_s:.2f} s'
                          f'  position error {error}  axis error {axis}  RTF {rtf:5.3f}')

    def _stalled(self, limit):
        monitor, procs = self.monitor, self.procs
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
        return RunStalled(what, monitor.stalled_sim_s(),
                          monitor.waits(procs, window_start, stopped),
                          monitor.silent(nodes), causes)


def watch(run: Prepared, executor: 'Executor', monitor: Monitor,
          procs: Sequence[NodeProcess], wall_start: float,
          progress: Callable[[str], None] = print, converge_hold_s: float | None = None,
          wall_timeout_s: float = 1800.0, stall_s: float = STALL_S,
          start_timeout_s: float = START_TIMEOUT_S,
          interrupt: StopRequest | None = None, job: JobStops | None = None,
          success: Success | None = None) -> Outcome:
    """
    Supervise a simulated run (:func:`supervise`) until it ends; return its :class:`Outcome`.

    Raises KeyboardInterrupt between two spins once ``interrupt`` is set (SIGINT,
    :func:`.job_control.interruptible` deferred).

    It ends when a process exits (``died``), the feature node says it measured no taught
    target (``teach_failed``: :class:`TeachFailed`), the tool has converged
    (``converge_hold_s`` held within ``success.settled``), sim time reaches
    ``run.duration_s`` (``converged``: ``success.reached``; without ``success`` never),
    ``wall_timeout_s`` has passed since ``wall_start``, or sim time has not advanced for
    ``stall_s`` (``start_timeout_s`` before step 0: ``stalled``). Progress is printed every
    :data:`PROGRESS_S` of wall time when sim time has moved since the last line; before
    step 0, once, that the nodes start.

    The runner's own stop is not the graph's: when more than :data:`.monitor.HEARTBEAT_S`
    of wall time passed between two of its looks (Ctrl-Z and ``fg``, SIGSTOP and SIGCONT, a
    debugger, a starved CPU) it heard no heartbeat and saw no step meanwhile, so it says so
    and starts its stall and heartbeat clocks again (:meth:`Monitor.restart_clocks`); the
    time is added to ``Outcome.paused_s``. Ctrl-Z stopped the graph with it (``job``, one
    more in its count: :func:`.job_control.stops_with_the_runner`): nothing was lost.
    Stopped alone, the graph ran on meanwhile (after step 0 nothing of the lockstep waits
    for the runner), and the bag lacks what a node's publisher could not keep for the
    stopped recorder (its queue: ``contract.RELIABLE``'s depth); the metrics take the steps
    before ``run.duration_s`` as always. A process that exits is :func:`optional` (the
    viewers') once the simulator runs: said, and the run goes on (``Outcome.lost``).
    """
    look = _RunWatch(run, monitor, list(procs), wall_start, progress, converge_hold_s,
                     wall_timeout_s, stall_s, start_timeout_s, job, success)
    outcome = supervise(executor, look, interrupt)
    # From step 0 on: the nodes' start-up (PyBullet, EGL, discovery) is not sim time.
    outcome.wall_duration_s = time.monotonic() - (monitor.started_wall or wall_start)
    return outcome


def optional(process: NodeProcess, graph: Graph = GRAPH) -> bool:
    """
    Return whether the run can go on without ``process``: it holds none of the paper's nodes.

    The viewers' node (``viz_node``, :attr:`.graph.Node.paper` False) feeds RViz, Foxglove
    and the bag's /tf; no node of the lockstep waits for it once the simulator has taken
    its first step (before, the simulator waits for its subscriptions).
    """
    names = {n.name for n in graph.nodes if not n.paper}
    return bool(process.nodes) and all(n in names for n in process.nodes)


def stop(procs: Sequence[NodeProcess], graph: Graph = GRAPH,
         executor: 'Executor | None' = None) -> dict[str, int | None]:
    """
    Stop ``procs`` together; return their exit codes by name, in reverse start order.

    Every process gets each step of :func:`.supervision.stop_all` at once, the simulator's
    signalled first: once it stops nothing is stepped, and a node that stops before it only
    makes it wait (the lockstep). The analysis takes the steps before the run's end only,
    so the order cannot change a result. Stopping the simulator alone first would add its
    exit time to every run's. ``executor`` (the recorder's) spins meanwhile: the nodes' last
    /diagnostics, with their timing totals, reach the bag (a simulated second takes about
    one of wall time, between two of their heartbeats).
    """
    ordered = sorted(procs, key=lambda p: graph.simulator not in p.nodes)
    codes = stop_all(ordered, executor=executor)
    return {p.name: codes[p.name] for p in reversed(procs)}


def clean_shm(progress: Callable[[str], None], whose: str,
              new_since: set[str] | None = None) -> None:
    """
    Remove the Fast DDS shared memory dead processes left (:mod:`.shm`); say so.

    ``whose``: who left it, in the message given to ``progress``; ``new_since``: only what
    appeared since that :func:`.shm.names` snapshot (what this run's processes left).
    """
    count, freed = shm.clean(new_since=new_since)
    if count:
        progress(f'  removed {count} Fast DDS shared-memory files ({freed / 1e6:.0f} MB) in '
                 f'{shm.SHM_DIR} that {whose} left')


def run_graph(run: Prepared, success: Success, custom_data: Mapping[str, str], run_key: str,
              progress: Callable[[str], None] = print, graph: Graph = GRAPH,
              interrupt: StopRequest | None = None, record_images: bool = False,
              record_overlays: bool = False, converge_hold_s: float | None = None,
              wall_timeout_s: float = 1800.0, stall_s: float = STALL_S,
              start_timeout_s: float = START_TIMEOUT_S) -> Ran:
    """
    Run the :class:`Prepared` ``run`` through ``graph``, recorded, from its domain to its stop.

    The shared memory earlier dead processes left removed; then, on the run's domain
    (:func:`held_domain`) and in a session of the launcher's own (:func:`ros_session`,
    without shared memory: the runner may be stopped while the graph runs on), the recorder
    opens ``run.bag_path`` with ``custom_data`` in its metadata, the processes start
    (:func:`start`, Ctrl-Z stops them with this process:
    :func:`.job_control.stops_with_the_runner`) and :func:`watch` supervises them, with
    ``success``, ``converge_hold_s``, ``wall_timeout_s``, ``stall_s`` and
    ``start_timeout_s``. SIGINT
    (``interrupt``) stops the run as its end does (``Outcome.interrupted``). Then every
    process stops (:func:`stop`), the run's record goes into the bag's metadata under
    ``run_key`` (exit codes, commands, wall time, interruption, lost processes, the
    runner's pauses), the bag is closed, and the shared memory this run's dead processes
    left is removed. What ended the run is the :class:`Outcome`'s, for the client to raise.
    """
    clean_shm(progress, 'earlier processes (e.g. a runner killed with SIGKILL)')
    shm_before = shm.names()
    with held_domain(progress):
        try:
            with ros_session('ibvs_run_monitor', shared_memory=False) as ros:
                recorder = ros.add(Recorder(run.bag_path, include_images=record_images,
                                            context=ros.context,
                                            include_overlays=record_overlays,
                                            custom_data=dict(custom_data)))
                monitor = Monitor(ros.node, recorder, run.target, errors=success.errors)
                limits = {'converge_hold_s': converge_hold_s, 'wall_timeout_s': wall_timeout_s,
                          'stall_s': stall_s, 'start_timeout_s': start_timeout_s}
                outcome = _supervised(run, ros.executor, monitor, recorder, run_key, progress,
                                      graph, interrupt, success, limits)
        finally:
            clean_shm(progress, 'node processes of this run that died', shm_before)
    return Ran(outcome, monitor.sim_ns, recorder.timing.values())


def _supervised(run, executor, monitor, recorder, run_key, progress, graph, interrupt, success,
                limits):
    """Start, watch and stop the run (:func:`run_graph`); close its bag; return its outcome."""
    procs = []
    outcome = Outcome()
    wall_start = time.monotonic()
    try:
        with stops_with_the_runner(procs) as job:
            start(run, executor, procs, graph)
            outcome = watch(run, executor, monitor, procs, wall_start, progress,
                            interrupt=interrupt, job=job, success=success, **limits)
    except KeyboardInterrupt:
        # SIGINT: stop as at the end of a run, and analyse what was recorded.
        progress(f'  interrupted (SIGINT) at sim time {ns_to_seconds(monitor.sim_ns):.3f}'
                 ' s: stopping the nodes, then the metrics of what was recorded')
        outcome.interrupted = True
        outcome.wall_duration_s = time.monotonic() - (monitor.started_wall or wall_start)
    finally:
        codes = stop(procs, graph, executor=executor)
        recorder.set_custom_data(run_key, yaml.safe_dump({
            'duration_s': run.duration_s, 'wall_duration_s': outcome.wall_duration_s,
            'exit_codes': codes, 'commands': {p.name: p.command for p in procs},
            'interrupted': outcome.interrupted, 'lost_processes': outcome.lost,
            'runner_paused_s': outcome.paused_s}))
        recorder.close()
    return outcome
