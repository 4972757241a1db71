"""
Signals of the launcher's process: SIGINT taken between two spins, Ctrl-Z with the graph.

:func:`interruptible` lets SIGINT stop a run also where the process was started with it
ignored, and defers it to the launcher's supervising loop (:func:`.launcher.supervise`);
:func:`stops_with_the_runner` makes Ctrl-Z stop the graph with the launcher's process and
``fg`` continue both.
"""

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
import os
import signal
import threading
from typing import TYPE_CHECKING

from ibvs_common.node_main import StopRequest

if TYPE_CHECKING:
    from .supervision import NodeProcess


@contextmanager
def interruptible(deferred: bool = False) -> Iterator[StopRequest | None]:
    """
    Let SIGINT interrupt what runs inside, also where the runner was started with it ignored.

    A shell starts a background job (``nohup ibvs run ... &``) with SIGINT ignored, and
    Python then installs no handler of its own: the runner could not be stopped by SIGINT.
    Inside, SIGINT raises KeyboardInterrupt (Python's own handler), which
    :func:`.launcher.run_graph` turns into a clean stop and the metrics of what was
    recorded; the handler found is put back after. Outside the main thread, where no handler
    can be set, nothing changes (None is yielded).

    ``deferred``: the first SIGINT only sets the yielded
    :class:`ibvs_common.node_main.StopRequest`, which :func:`.launcher.supervise` reads
    between two spins, as a node's spin loop does; a second raises KeyboardInterrupt at
    once. Python's handler raises at whatever bytecode runs next, and inside rclpy's C++
    conversion of a message the recorder takes it surfaced as pybind11's "Unable to convert
    function return value" instead: the run ended with exit code 1 and no metrics.
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
def stops_with_the_runner(procs: Sequence['NodeProcess']) -> Iterator[JobStops | None]:
    """
    Within, Ctrl-Z of the runner stops its graph too, and ``fg`` continues both (job control).

    Every node runs in a process group of its own (:func:`ibvs_common.process.supervised_child`),
    so the terminal's SIGTSTP reaches the runner alone, and the graph, which after step 0
    waits for nothing of the runner's, would run on without its recorder: past the run's
    end, with a bag that lacks everything sent meanwhile. Here SIGTSTP stops each process of
    ``procs`` (SIGSTOP to its group; the list as it is then: :func:`.launcher.start` fills it) and
    then the runner itself; the SIGCONT of ``fg`` (or ``kill -CONT``) continues the
    processes the runner stopped, and only those. The lockstep then resumes at the step it
    was at: the run's numbers are those of a run never stopped. A runner stopped alone
    (SIGSTOP, a debugger) stops nothing else: :func:`.launcher.watch` tells its own stop from the
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
