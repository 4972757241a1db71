"""
Run one scenario through the node graph: prepare it, launch it, analyse it.

``ibvs run``'s side of a run: the scenario's checked parameters (:func:`resolve`), its
output folder and parameters file (:func:`prepare`), and its metrics and figures
(:func:`ibvs_analysis.results.write_results`); the run's life in between is the launcher's
(:mod:`ibvs_bringup.launcher`: the domain, the session, the start, the supervising loop, the
stop, the shared memory), told the project's success as callables (:data:`SUCCESS`).

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
process leaves in /dev/shm is removed, and the runner says so (:mod:`ibvs_bringup.shm`): at
the end of a run what its dead processes left, at the start what earlier dead processes
left.

No silent hang: a configuration that cannot advance sim time is refused before any node
starts (:func:`scenario.check_progress`), and a run whose sim time stops advancing for
``stall_s`` of wall time ends with :class:`RunStalled`, which quotes what each node last
said it waits for (its once-a-second "waiting ..." log line and the ``waiting_for`` values
it publishes on /diagnostics).

The launcher's names that this module's clients and tests use (:class:`Monitor`,
:func:`watch`, :func:`interruptible`, the exit codes...) are importable from here too.
"""

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ibvs_analysis import analysis, convergence
from ibvs_analysis.metrics import axis_angle_deg
from ibvs_analysis.results import write_results
from ibvs_bringup import domains, graph_params, launcher, scenario
from ibvs_bringup.graph import GRAPH, Graph
from ibvs_bringup.job_control import (interruptible, JobStops,  # noqa: F401 (re-exported)
                                      stops_with_the_runner)
from ibvs_bringup.launcher import (clean_shm, EXIT_NODE_DIED,  # noqa: F401 (re-exported)
                                   EXIT_TEACH_FAILED, optional, Outcome, POLL_S, Prepared,
                                   PROGRESS_S, start, stop)
from ibvs_bringup.monitor import (HEARTBEAT_S, last_waiting_line,  # noqa: F401 (re-exported)
                                  Monitor, RunStalled, SILENT, STALL_S, START_TIMEOUT_S,
                                  stopped_processes, TeachFailed)
from ibvs_bringup.supervision import NodeDied  # noqa: F401 (re-exported)
from ibvs_common.shared_params import target_from_parameters
import numpy as np
from numpy.typing import NDArray
import yaml

from . import output_dir

#: What a run into a previous run's folder removes of it first (:func:`prepare`): the
#: entries it writes anew whole; the rest it writes (params.yaml, logs/<process>.log, the
#: figures) it overwrites.
REPLACED = ('bag', 'metrics.json')


def tool_errors(pose: NDArray[np.float64],
                target: NDArray[np.float64]) -> tuple[float, float]:
    """Return the tool's position error (m) and tool-axis error (deg) of ``pose`` (4x4)."""
    return (float(np.linalg.norm(pose[:3, 3] - target[:3, 3])),
            float(axis_angle_deg(pose[None, :3, :3], target[:3, :3])[0]))


#: What the launcher is told of a run's success (:class:`ibvs_bringup.launcher.Success`):
#: the tool's errors as the analysis defines them, :data:`ibvs_analysis.convergence.HOLD`
#: to end a run early on, :data:`ibvs_analysis.convergence.SUCCESS` at its sim time limit.
SUCCESS = launcher.Success(tool_errors, convergence.HOLD.within, convergence.SUCCESS.within)


def watch(*args: Any, success: launcher.Success = SUCCESS, **kwargs: Any) -> Outcome:
    """:func:`ibvs_bringup.launcher.watch` with the project's success (:data:`SUCCESS`)."""
    return launcher.watch(*args, success=success, **kwargs)


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
    figures (:func:`ibvs_analysis.results.write_results`).

    ``record_overlays`` records the feature node's overlay images (/ibvs/debug/*/image,
    which it then draws for every frame; ``ibvs video`` makes a film of them).

    ``duration_s`` is the sim time limit (default: the scenario file's ``run_duration_s``,
    else 3 s). With ``converge_hold_s`` the run ends early once the tool has stayed within
    0.1 mm and 0.01 deg of the target for that long (sim time:
    :data:`ibvs_analysis.convergence.HOLD`). Raises
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

    The parts, in order: :func:`prepare`, the launcher's
    :func:`~ibvs_bringup.launcher.run_graph` (:func:`start`, :func:`watch`, :func:`stop`),
    :func:`ibvs_analysis.results.write_results`.
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


def _run_prepared(run, record_images, wall_timeout_s, converge_hold_s, progress, stall_s,
                  start_timeout_s, record_overlays, figures, on_metrics, graph=GRAPH,
                  interrupt=None):
    """Run the :class:`Prepared` ``run`` (:func:`run_scenario` after :func:`prepare`)."""
    ran = launcher.run_graph(
        run, SUCCESS, {analysis.PARAMS_KEY: yaml.safe_dump(run.params)}, analysis.RUN_KEY,
        progress, graph, interrupt, record_images, record_overlays,
        converge_hold_s=converge_hold_s, wall_timeout_s=wall_timeout_s, stall_s=stall_s,
        start_timeout_s=start_timeout_s)
    outcome = ran.outcome
    if outcome.died:
        raise outcome.died
    if outcome.teach_failed:
        raise outcome.teach_failed
    if outcome.stalled:
        raise outcome.stalled
    if outcome.interrupted and ran.sim_ns == 0:
        raise KeyboardInterrupt  # nothing was simulated: no metrics to write
    metrics = write_results(run.bag_path, run.out_dir, outcome.wall_duration_s, figures,
                            on_metrics)
    return RunResult(run.out_dir, run.bag_path, metrics, outcome.converged, ran.recording,
                     outcome.interrupted)


def with_servo_law(overrides: dict[str, Any]) -> dict[str, Any]:
    """
    Return ``overrides`` with the feedforward parameters of its servo_law added.

    The one place a law's feedforward (:func:`ibvs_control.servo_laws.feedforward_overrides`:
    ``feedforward_method: hold`` for ibvs and pbvs, ``feedforward_ratio`` for switching)
    joins a run's parameters: ``ibvs run``, the law study and the benchmark's graph runs
    take it from here. A value ``overrides`` gives is kept; without ``servo_law`` nothing is
    added. ``overrides`` itself is completed and returned.
    """
    law = overrides.get('servo_law')
    if law is None:
        return overrides
    # Here, not at the top: ibvs_control pulls in scipy.signal, seconds of start-up that a
    # run without servo_law does not need.
    from ibvs_control.servo_laws import feedforward_overrides
    for key, value in feedforward_overrides(law).items():
        overrides.setdefault(key, value)
    return overrides


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
