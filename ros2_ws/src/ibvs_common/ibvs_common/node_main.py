"""The ``main()`` of every node, in the shape of ros2/demos ``demo_nodes_py`` (jazzy)."""

from collections.abc import Sequence
import signal
import sys
import threading
from typing import TYPE_CHECKING

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.signals import SignalHandlerOptions

from . import dds
from .diagnostics import publish_last
from .intra_process import bus_of
from .params import ParameterError

if TYPE_CHECKING:
    from rclpy.context import Context
    from rclpy.node import Node

#: Longest a stop request waits for the executor to come back from ``wait`` (seconds).
STOP_POLL_S = 0.1
#: Signals that ask a node to stop cleanly (exit code 0).
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopRequest:
    """
    Turn SIGINT/SIGTERM into a flag that the spin loop reads between callbacks.

    Why not rclpy's own handlers: they shut the context down from another thread at any
    moment, and Python's default SIGINT handler raises ``KeyboardInterrupt`` at whatever
    bytecode runs next. Either can land inside a callback or inside rclpy's C++ message
    conversion (likely while a large Image is taken), where it surfaces as an opaque
    ``RuntimeError`` or ``RCLError`` ("context is not valid") and the node exits 1 instead
    of 0. Here the first signal only sets a flag; the node finishes its callback, leaves the
    spin loop, destroys itself and shuts rclpy down. A second signal raises
    ``KeyboardInterrupt`` at once, for a node stuck in a callback.
    """

    def __init__(self) -> None:
        self._event = threading.Event()
        self._previous = {}

    def install(self) -> None:
        """Install the handlers (main thread only), remembering the previous ones."""
        for signum in STOP_SIGNALS:
            self._previous[signum] = signal.signal(signum, self._handle)

    def restore(self) -> None:
        """Put the previous handlers back."""
        for signum, handler in self._previous.items():
            signal.signal(signum, handler)
        self._previous.clear()

    def _handle(self, signum, frame):
        if self._event.is_set():
            raise KeyboardInterrupt
        self._event.set()

    def is_set(self) -> bool:
        """Return whether a stop was requested."""
        return self._event.is_set()


def make_executor(context: 'Context') -> EventsExecutor:
    """
    Return the executor every node of the graph spins in: rclpy's ``EventsExecutor``.

    The lockstep passes one message per physics step through several processes, so the
    executor's cost per callback bounds the simulation speed. ``SingleThreadedExecutor``
    rebuilds its wait set in Python before every callback (measured: 0.53 ms per round trip
    between two processes); the ``EventsExecutor`` (C++, shipped with Jazzy's rclpy) queues
    middleware events instead (0.18 ms). Callbacks still run one at a time in arrival order.
    """
    return EventsExecutor(context=context)


def spin_until_stopped(nodes: 'Node | Sequence[Node]', stop: StopRequest,
                       poll_s: float = STOP_POLL_S) -> None:
    """
    Spin ``nodes`` (one node or several of one context) until ``stop`` or shutdown.

    The executor also delivers the messages that the nodes of the process pass to each
    other directly (:mod:`.intra_process`): a task, in turn with the other callbacks.
    """
    nodes = list(nodes) if isinstance(nodes, (list, tuple)) else [nodes]
    context = nodes[0].context
    executor = make_executor(context)
    for node in nodes:
        executor.add_node(node)
    bus = bus_of(context)
    bus.attach(lambda: executor.create_task(bus.drain_task))
    try:
        while context.ok() and not stop.is_set():
            executor.spin_once(timeout_sec=poll_s)
            bus.raise_failure()
    finally:
        bus.detach()
        for node in nodes:
            executor.remove_node(node)
        executor.shutdown(timeout_sec=0.0)


def run(node_class: 'type[Node] | Sequence[type[Node]]', args: list[str] | None = None,
        name: str | None = None) -> None:
    """
    Init rclpy, build ``node_class()``, spin until SIGINT/SIGTERM, then clean up.

    ``node_class`` may also be a sequence of node classes: they are built in that order and
    spin in one executor, in one process (:mod:`ibvs_bringup.compose`), as a component
    container holds several nodes; a message between two of them then does not leave the
    process. A :class:`ParameterError` at start is logged as fatal and ends the process with
    exit code 2, so that a runner can tell a bad configuration from a crash. A stop signal
    ends it with exit code 0 once the running callback has returned (see
    :class:`StopRequest`).
    """
    classes = list(node_class) if isinstance(node_class, (list, tuple)) else [node_class]
    stop = StopRequest()
    stop.install()
    dds.configure()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    nodes = []
    code = 0
    building = classes[0]
    try:
        for building in classes:
            nodes.append(building())
        spin_until_stopped(nodes, stop)
    except ParameterError as exc:
        rclpy.logging.get_logger(name or building.__name__).fatal(str(exc))
        code = 2
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        for node in reversed(nodes):
            if node.context.ok():
                publish_last(node)
            node.destroy_node()
        rclpy.try_shutdown()
        stop.restore()
    if code:
        sys.exit(code)
