"""
Supervise the processes of a run: start each as ``ros2 run`` would, watch them, stop them.

:class:`ProcessSpec` says what to start, :class:`NodeProcess` runs it with its output in a
log file and dies with the runner (:func:`ibvs_common.process.supervised_child`),
:func:`stop_all` stops several at once (SIGINT, then SIGTERM, then SIGKILL), and
:func:`expected_readers` is the start handshake: how many readers of step 0 the simulator
waits for. A process that exits during a run is reported by :class:`NodeDied`, which names
it, its exit code and its last log line.
"""

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
import os
from pathlib import Path
import shutil
import signal
import subprocess
import time
from typing import TYPE_CHECKING

from ament_index_python.packages import get_package_prefix
from ibvs_common.process import supervised_child

if TYPE_CHECKING:
    from rclpy.executors import Executor
    from rclpy.node import Node


@dataclass(frozen=True)
class ProcessSpec:
    """One process of a run: ``ros2 run package executable *args``, holding ``nodes``."""

    package: str
    executable: str
    args: tuple = ()
    nodes: tuple = ()
    #: Its name in logs (``logs/<name>.log``), exit codes and error messages.
    name: str = ''

    def __post_init__(self):
        """Fill the defaults: one node, named as its executable."""
        if not self.nodes:
            object.__setattr__(self, 'nodes', (self.executable,))
        if not self.name:
            object.__setattr__(self, 'name', self.executable)

    def start(self, params_file: str | Path, log_dir: str | Path,
              extra_args: Sequence[str] = ()) -> 'NodeProcess':
        """Start this process (:class:`NodeProcess`) with the run's parameters file."""
        return NodeProcess(self.package, self.executable, params_file, log_dir, extra_args,
                           self)


class NodeDied(RuntimeError):
    """
    A node process exited during a run; ``node`` and ``returncode`` say which and how.

    ``node`` is the process's name (a node's, or a shared process's such as ``lockstep``);
    ``nodes``, the nodes it held, are named in the message when they are several.
    """

    def __init__(self, node: str, returncode: int | None, log_path: str | Path,
                 nodes: Sequence[str] = ()) -> None:
        """Keep which node died, its exit code and where its log is; quote its last line."""
        try:
            lines = Path(log_path).read_text(errors='replace').strip().splitlines()
        except OSError:
            lines = []
        last = f'; its last words: {lines[-1].strip()}' if lines else ''
        held = f' (nodes {", ".join(nodes)})' if len(nodes) > 1 else ''
        super().__init__(f'node {node}{held} exited with code {returncode} during the run '
                         f'(log: {log_path}){last}')
        self.node = node
        self.returncode = returncode
        self.log_path = log_path


def executable_command(package: str, executable: str) -> list[str]:
    """Return the command that ``ros2 run <package> <executable>`` stands for."""
    if shutil.which('ros2'):
        return ['ros2', 'run', package, executable]
    path = Path(get_package_prefix(package)) / 'lib' / package / executable
    if not os.access(path, os.X_OK):
        raise FileNotFoundError(f'{package} {executable}: no executable at {path}')
    return [str(path)]


class NodeProcess:
    """One process of the graph (one node, or several: ``spec``), its output in a log file."""

    def __init__(self, package: str, executable: str, params_file: str | Path,
                 log_dir: str | Path, extra_args: Sequence[str] = (),
                 spec: ProcessSpec | None = None) -> None:
        """Start ``package executable [spec.args] --ros-args --params-file params_file``."""
        spec = spec or ProcessSpec(package, executable)
        cmd = executable_command(package, executable) + [
            *spec.args, '--ros-args', '--params-file', str(params_file), *extra_args]
        self._launch(cmd, spec.name, spec.nodes, Path(log_dir) / f'{spec.name}.log')

    @classmethod
    def of_command(cls, command: Iterable[str], name: str, log_path: str | Path,
                   nodes: Iterable[str] = ()) -> 'NodeProcess':
        """Start any ``command`` supervised as a node's process is (tools, tests)."""
        process = cls.__new__(cls)
        process._launch(list(command), name, tuple(nodes), Path(log_path))
        return process

    def _launch(self, command, name, nodes, log_path):
        self.name, self.nodes, self.log_path, self.command = name, nodes, log_path, command
        self._log = open(self.log_path, 'wb')
        self.proc = subprocess.Popen(command, stdout=self._log, stderr=subprocess.STDOUT,
                                     stdin=subprocess.DEVNULL, preexec_fn=supervised_child)

    def poll(self) -> int | None:
        """Return the exit code, or None while running."""
        return self.proc.poll()

    def stopped(self) -> list[tuple[int, str]]:
        """
        Return (pid, command) of this process and of each process below it that is stopped.

        Stopped: state ``T`` or ``t`` in ``/proc/<pid>/stat`` (SIGSTOP, SIGTSTP, a
        debugger), which handles nothing, answers nobody and publishes no heartbeat until it
        is continued; any child it started (a worker) counts as well.
        """
        found, todo = [], [self.proc.pid]
        while todo:
            pid = todo.pop()
            if _state(pid) in ('T', 't'):
                found.append((pid, _command(pid)))
            todo += _children(pid)
        return found

    def stop(self, timeout_s: float = 10.0) -> int | None:
        """SIGINT, wait; then SIGTERM, wait; then SIGKILL the process group. Return the code."""
        return stop_all([self], timeout_s)[self.name]

    def send_signal(self, sig: int) -> None:
        """Send ``sig`` to the process group, if it is still there."""
        try:
            os.killpg(self.proc.pid, sig)
        except (ProcessLookupError, PermissionError):
            pass


def _state(pid):
    """Return the state letter of ``pid`` in /proc ('' if gone)."""
    try:
        with open(f'/proc/{pid}/stat') as f:
            return f.read().rsplit(')', 1)[-1].split()[0]
    except (OSError, IndexError):
        return ''


def _children(pid):
    """Return the pids of the children of ``pid`` (every thread's), from /proc."""
    out = []
    try:
        tasks = os.listdir(f'/proc/{pid}/task')
    except OSError:
        return out
    for task in tasks:
        try:
            with open(f'/proc/{pid}/task/{task}/children') as f:
                out += [int(c) for c in f.read().split()]
        except OSError:
            pass
    return out


def _command(pid):
    """Return the command line of ``pid`` as one string ('' if gone)."""
    try:
        with open(f'/proc/{pid}/cmdline', 'rb') as f:
            return f.read().replace(b'\0', b' ').decode(errors='replace').strip()
    except OSError:
        return ''


#: stop_all with an executor: the longest one spin blocks (s), and the spins after the last
#: exit (what the nodes sent last is in the caller's DDS readers by then).
STOP_SPIN_S = 0.01
SETTLE_SPINS = 10


def stop_all(procs: Sequence[NodeProcess], timeout_s: float = 10.0,
             executor: 'Executor | None' = None) -> dict[str, int | None]:
    """
    Stop ``procs`` (:class:`NodeProcess`) together; return their exit codes by name.

    Each escalation step (SIGINT, then SIGTERM after ``timeout_s``, then SIGKILL after 3 s)
    goes to every process still running at once, and the waits overlap: five nodes take as
    long to stop as the slowest of them, not the sum. A stopped (SIGSTOP) process handles no
    signal until it is continued, so each first gets SIGCONT. Whatever a node left in its
    process group (``ros2 run``'s child) is killed last. ``executor`` (the caller's
    subscribers): spun while waiting and :data:`SETTLE_SPINS` times after the last exit, so
    that what the nodes publish as they stop (their last /diagnostics, the simulator's last
    batches) reaches them.
    """
    for p in procs:
        p.send_signal(signal.SIGCONT)
    for sig, wait in ((signal.SIGINT, timeout_s), (signal.SIGTERM, 3.0),
                      (signal.SIGKILL, 3.0)):
        running = [p for p in procs if p.proc.poll() is None]
        if not running:
            break
        for p in running:
            p.send_signal(sig)
        deadline = time.monotonic() + wait
        if executor is not None:
            while time.monotonic() < deadline and any(p.proc.poll() is None for p in running):
                executor.spin_once(timeout_sec=STOP_SPIN_S)
            continue
        for p in running:
            try:
                p.proc.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass
    for _ in range(SETTLE_SPINS if executor is not None else 0):
        executor.spin_once(timeout_sec=STOP_SPIN_S)
    for p in procs:
        p.send_signal(signal.SIGKILL)
        p._log.close()
    return {p.name: p.proc.returncode for p in procs}


def expected_readers(local: Iterable['Node'], readers: Mapping[str, Sequence[str]],
                     topic_of: Mapping[str, str] | None = None) -> dict[str, int]:
    """
    Return how many subscribers the simulator waits for on each topic of step 0.

    ``readers``: {topic: the nodes that must read it} (the graph's readers of step 0,
    :meth:`ibvs_bringup.graph.Graph.step0_readers`), one subscription each; ``local``: the
    caller's own nodes (the runner's recorder and monitor), whose subscriptions on the topic
    count too; ``topic_of``: the name each contract topic is remapped to in this run (the
    result is by contract name). At least one on each topic.

    This is the start handshake: it is known before any process starts, so that a run
    starts all its processes at once, and the simulator's first step waits until that many
    readers are matched (its ``min_*_subscribers``; it says once a second which it still
    waits for, and the runner's start timeout quotes it), rather than each process waiting
    to be in the graph before the next one starts, which would serialise the start.
    """
    topic_of = topic_of or {}
    local = list(local)
    return {topic: max(1, len(names) + sum(
                s.topic_name == topic_of.get(topic, topic)
                for node in local for s in node.subscriptions))
            for topic, names in readers.items()}
