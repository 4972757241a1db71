"""
What the launcher sees of a running graph: sim time, the tool's errors, who waits for what.

:class:`Monitor` reads what the recorder of the launcher's process receives (/clock, the
tool's path) and the nodes' /diagnostics; it says when sim time stopped advancing and why
(:class:`RunStalled`: the nodes' "waiting ..." log lines, :func:`last_waiting_line`, their
/diagnostics, their heartbeats, their processes' watchdogs, :func:`stopped_processes`), and
when the feature node could not measure the taught target (:class:`TeachFailed`). What a
tool pose's errors are is the client's (``errors``, a callable): this package imports no
analysis.
"""

from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
import re
import time
from typing import TYPE_CHECKING

from diagnostic_msgs.msg import DiagnosticArray
from ibvs_common import contract
from ibvs_common.conversions import pose_matrix
from ibvs_common.node_main import WATCHDOG
from ibvs_common.timing import ns_to_seconds
from nav_msgs.msg import Path as PathMsg
import numpy as np
from numpy.typing import NDArray
from rclpy.serialization import deserialize_message

if TYPE_CHECKING:
    from rclpy.node import Node

    from .recorder import Recorder
    from .supervision import NodeProcess

#: The errors of a tool pose (4x4) against the target (4x4): (position m, tool axis deg).
PoseErrors = Callable[[NDArray[np.float64], NDArray[np.float64]], tuple[float, float]]

#: Default wall time without sim-time progress after which a run is declared stalled (s).
#: Long enough for the slowest single step seen on a loaded 2-core machine (the
#: feedforward's trajectory at t = 0 took 11 s with a load average of 17); the runner then
#: names who waits for what.
STALL_S = 60.0
#: Default wall time from the last node's launch to the simulator's first step (s):
#: start-up (PyBullet, EGL, discovery) takes seconds, more on a loaded machine.
START_TIMEOUT_S = 120.0
#: What the stall report says of a node that reported no wait: busy, frozen, or a node that
#: does not report its waits.
SILENT = 'said nothing about waiting (no "waiting" log line, no /diagnostics waiting_for)'
#: Wall time (s) without a /diagnostics from a node after which its heartbeat counts as
#: stopped: every node publishes its status once a second on a steady clock, also while it
#: waits (ibvs_common.diagnostics), so only a frozen or hung node falls silent that long.
HEARTBEAT_S = 3.0
#: A node's log line saying what it waits for: ``[LEVEL] [<epoch s>] [<node>]: waiting ...``.
_WAITING_LINE = re.compile(r'^\[\w+\] \[(\d+(?:\.\d+)?)\] \[([^\]]+)\]: (waiting .*)$')


class TeachFailed(RuntimeError):
    """
    The feature node measured no target features on the teach pair: no frame can be answered.

    With ``target_features_source: taught`` the simulator renders the tool at the target
    once, before the run, and the feature node measures p_bar on that pair; when it cannot
    (a marker hidden or cut at the target) it says so on /diagnostics
    (``contract.TEACH_FAILED``), and :func:`.launcher.watch` ends the run at once instead
    of waiting for the stall bound. ``node``: who said it; ``why``: its words.
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


class Monitor:
    """
    Sim time and tool pose of the running graph, for progress, convergence and stalls.

    Read from what the recorder (same process) receives: no subscription of its own to the
    per-step topics, so the graph does not deliver each step twice to this process, and the
    newest tool pose is decoded only when :meth:`poll` is called (every
    :data:`.launcher.POLL_S` of wall time), not at each step. ``errors`` (:data:`PoseErrors`,
    the client's: the launcher imports no analysis) gives the tool's errors against
    ``target``; without it they stay NaN.
    """

    def __init__(self, node: 'Node', recorder: 'Recorder', target: NDArray[np.float64],
                 clock: Callable[[], float] = time.monotonic,
                 errors: PoseErrors | None = None) -> None:
        """Follow ``recorder``'s /clock and /ibvs/tool_path; /diagnostics on ``node``."""
        self._clock = clock
        self._errors = errors
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
        if raw is None or raw is self._pose_raw or self._errors is None:
            return
        self._pose_raw = raw
        poses = deserialize_message(raw, PathMsg).poses
        if poses:
            error_m, axis_deg = self._errors(pose_matrix(poses[-1].pose), self.target)
            self.error_m, self.axis_deg = float(error_m), float(axis_deg)

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
        their silence is the runner's (:func:`.launcher.watch` calls this then), not theirs.
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

    def waits(self, procs: Sequence['NodeProcess'], since_epoch_s: float,
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

    def update_convergence(self, within: Callable[[float, float], bool]) -> float:
        """
        Track since when the tool has been within a tolerance; return that duration (s).

        ``within(error_m, axis_deg)``: whether the errors are within it (the client's, e.g.
        a ``Convergence.within`` of ibvs_experiments).
        """
        inside = within(self.error_m, self.axis_deg)
        if not inside:
            self.within_since_ns = None
            return 0.0
        if self.within_since_ns is None:
            self.within_since_ns = self.sim_ns
        return ns_to_seconds(self.sim_ns - self.within_since_ns)


def stopped_processes(procs: Sequence['NodeProcess']) -> dict[str, str]:
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
