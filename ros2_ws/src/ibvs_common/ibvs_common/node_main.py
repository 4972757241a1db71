"""
The ``main()`` of every node, in the shape of ros2/demos ``demo_nodes_py`` (jazzy).

:func:`run` checks the configuration before rclpy starts, builds the nodes, spins them
until SIGINT/SIGTERM, and keeps a :class:`Watchdog` beside the executor: a thread that
says on /diagnostics which callback has been running for how long, while the executor, and
with it every heartbeat of the process, waits for that callback.
"""

from collections.abc import Callable, Iterable, Sequence
import inspect
import os
import signal
import sys
import threading
import time
from typing import TYPE_CHECKING

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.experimental import EventsExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.signals import SignalHandlerOptions

from . import contract, dds, process, ros_args
from .diagnostics import publish_last, publisher_of
from .intra_process import bus_of
from .params import check_declared, check_retired, Param, ParameterError, plain_value

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
    ``KeyboardInterrupt`` at once, for a node stuck in a callback. ``signals``: those it
    handles (the runner's: SIGINT alone, :func:`ibvs_experiments.runner.interruptible`).
    """

    def __init__(self, signals: tuple[int, ...] = STOP_SIGNALS) -> None:
        self._signals = tuple(signals)
        self._event = threading.Event()
        self._previous = {}

    def install(self) -> None:
        """Install the handlers (main thread only), remembering the previous ones."""
        for signum in self._signals:
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


#: How long a callback runs before the :class:`Watchdog` says so (s): longer than any
#: callback of a healthy run (a frame's detection, 10-100 ms), shorter than the runner's
#: heartbeat timeout (``ibvs_experiments.runner.HEARTBEAT_S``, 3 s).
BUSY_S = 1.0
#: How often the :class:`Watchdog` looks at the spinning thread (s).
WATCH_S = 0.25
#: The second half of the name of the Watchdog's /diagnostics status (``<node>: watchdog``).
WATCHDOG = 'watchdog'


class Watchdog:
    """
    A thread that names the callback a node process has been busy in, and for how long.

    The executor runs one callback at a time: while one runs long (a detection of a noisy
    frame, a hang), no timer fires and every node of the process falls silent, those that
    only wait behind it included. The watchdog looks at the spinning thread's Python stack
    every ``period_s`` (:func:`sys._current_frames`; OpenCV and numpy release the GIL, and
    Python switches threads every 5 ms otherwise): the outermost frame of a method of one
    of the nodes, below the spin loop, is the running callback. Once the same call has run
    for ``busy_s``, it publishes, at most once a second, a WARN status
    ``<node>: watchdog`` on /diagnostics (on the node's own publisher): ``busy in <node>
    <Class.method> for <s> s``, with ``busy_callback``, ``busy_s`` and ``pid``. A call
    inside a C extension that holds the GIL (PyBullet) delays it until it returns.
    """

    def __init__(self, nodes: 'Sequence[Node]', spin_code: object,
                 period_s: float = WATCH_S, busy_s: float = BUSY_S,
                 clock: Callable[[], float] = time.monotonic) -> None:
        """Watch the calling thread, which spins ``nodes`` in the function of ``spin_code``."""
        self._ident = threading.get_ident()
        self._spin_code = spin_code
        self._period_s, self._busy_s, self._clock = period_s, busy_s, clock
        self._methods = {}
        for node in nodes:
            for klass in type(node).__mro__:
                if klass.__module__.startswith('rclpy') or klass is object:
                    continue
                for name, member in vars(klass).items():
                    func = inspect.unwrap(getattr(member, '__func__', member))
                    if inspect.isfunction(func):
                        self._methods.setdefault(func.__code__, (
                            node.get_name(), f'{klass.__name__}.{name}'))
        # The nodes' own /diagnostics publisher, where one has it: one publisher a node.
        self._pub = next((pub for pub in map(publisher_of, nodes) if pub is not None),
                         None) or nodes[0].create_publisher(DiagnosticArray,
                                                            contract.DIAGNOSTICS, 10)
        self._hardware_id = nodes[0].get_fully_qualified_name()
        self._node = nodes[0]
        #: The call seen last: (spin count, id of its frame), its (node, callback), since.
        self._call = None
        self._said = 0.0
        #: Incremented by the spin loop at each ``spin_once``: a new call, even at the same
        #: frame address, is another call.
        self.spins = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='ibvs-watchdog', daemon=True)

    def start(self) -> None:
        """Start watching."""
        self._thread.start()

    def stop(self) -> None:
        """Stop watching (before the nodes are destroyed)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)

    def running(self) -> tuple[str, str, float] | None:
        """Return (node, callback, seconds it has run) of the callback now running, or None."""
        frame = sys._current_frames().get(self._ident)
        found = None
        while frame is not None and frame.f_code is not self._spin_code:
            if frame.f_code in self._methods:
                found = frame  # the outermost method of a node so far
            frame = frame.f_back
        if frame is None or found is None:  # not in the spin loop, or waiting for events
            self._call = None
            return None
        key = (self.spins, id(found), found.f_code)
        now = self._clock()
        if self._call is None or self._call[0] != key:
            self._call = (key, self._methods[found.f_code], now)
        (node, callback), since = self._call[1], self._call[2]
        return node, callback, now - since

    def _run(self):
        while not self._stop.wait(self._period_s):
            try:
                self.check()
            except Exception:  # never take the process down: the watchdog only reports
                pass

    def check(self) -> DiagnosticArray | None:
        """Look once; publish and return the status if a callback is busy (else None)."""
        running = self.running()
        if running is None or running[2] < self._busy_s:
            return None
        now = self._clock()
        if now - self._said < 1.0:
            return None
        self._said = now
        node, callback, seconds = running
        msg = DiagnosticArray()
        msg.header.stamp = self._node.get_clock().now().to_msg()
        msg.status = [DiagnosticStatus(
            level=DiagnosticStatus.WARN, name=f'{node}: {WATCHDOG}',
            message=f'busy in {node} {callback} for {seconds:.1f} s',
            hardware_id=self._hardware_id,
            values=[KeyValue(key='busy_callback', value=callback),
                    KeyValue(key='busy_s', value=f'{seconds:.1f}'),
                    KeyValue(key='pid', value=str(os.getpid()))])]
        self._pub.publish(msg)
        return msg


def make_executor(context: 'Context') -> EventsExecutor:
    """
    Return the executor every node of the graph spins in: rclpy's ``EventsExecutor``.

    The lockstep passes one message per physics step through several processes, so the
    executor's cost per callback bounds the simulation speed. ``SingleThreadedExecutor``
    rebuilds its wait set in Python before every callback; the ``EventsExecutor`` (C++,
    shipped with Jazzy's rclpy) queues middleware events instead, about a third of the cost
    per round trip between two processes. Callbacks still run one at a time in arrival
    order.
    """
    return EventsExecutor(context=context)


def spin_until_stopped(nodes: 'Node | Sequence[Node]', stop: StopRequest,
                       poll_s: float = STOP_POLL_S) -> None:
    """
    Spin ``nodes`` (one node or several of one context) until ``stop`` or shutdown.

    The executor also delivers the messages that the nodes of the process pass to each
    other directly (:mod:`.intra_process`): a task, in turn with the other callbacks. A
    :class:`Watchdog` says which callback keeps the executor busy, and for how long.
    """
    nodes = list(nodes) if isinstance(nodes, (list, tuple)) else [nodes]
    context = nodes[0].context
    executor = make_executor(context)
    for node in nodes:
        executor.add_node(node)
    bus = bus_of(context)
    bus.attach(lambda: executor.create_task(bus.drain_task))
    watchdog = Watchdog(nodes, spin_until_stopped.__code__)
    watchdog.start()
    try:
        while context.ok() and not stop.is_set():
            watchdog.spins += 1
            executor.spin_once(timeout_sec=poll_s)
            bus.raise_failure()
    finally:
        watchdog.stop()
        bus.detach()
        for node in nodes:
            executor.remove_node(node)
        executor.shutdown(timeout_sec=0.0)


def ros_parameter_args(argv: Sequence[str]) -> tuple[list[str], list[str]]:
    """
    Return the names set by ``-p``/``--param`` and the ``--params-file`` paths of ``argv``.

    Only what lies in a ``--ros-args`` section (up to ``--``) counts, as rcl reads it; a
    ``-p node:name:=value`` gives ``name``. The files are not read here.
    """
    names, files = [], []
    inside, i = False, 0
    while i < len(argv):
        arg = argv[i]
        if arg == '--ros-args':
            inside = True
        elif arg == '--':
            inside = False
        elif inside and arg in ('-p', '--param') and i + 1 < len(argv):
            i += 1
            names.append(argv[i].split(':=', 1)[0].split(':')[-1])
        elif inside and arg == '--params-file' and i + 1 < len(argv):
            i += 1
            files.append(argv[i])
        elif inside and arg in ('-r', '--remap') + ros_args.VALUED_FLAGS:
            i += 1
        i += 1
    return names, files


def file_parameter_names(path: str) -> list[str]:
    """
    Return the names a parameter file sets for named nodes (not under ``/**`` or ``/*``).

    Raises :class:`ParameterError` if the file cannot be read or is not a ROS 2 parameter
    file (``node: {ros__parameters: {...}}``). Names under a wildcard are left out: the
    graph's file (``ibvs run``'s ``params.yaml``) gives every node the parameters of all,
    and ``ibvs run`` checks those against the whole graph.
    """
    try:
        sections = ros_args.file_sections(path)
    except ros_args.ArgumentsError as exc:
        raise ParameterError(str(exc)) from None
    return [name for key, params in sections
            if key.rstrip('/').split('/')[-1] not in ('*', '**') for name, _ in params]


#: rclpy's own parameter that every node declares, checked as a node's own are.
USE_SIM_TIME = Param('use_sim_time', False, 'run on the time of /clock')


def node_name_of(cls: type) -> str:
    """Return the name a node class gives its node: its module's (``feature_node``)."""
    return getattr(cls, 'NODE_NAME', cls.__module__.rsplit('.', 1)[-1])


def check_types(classes: Iterable[type], parsed: 'ros_args.RosArguments') -> None:
    """
    Refuse a value of the wrong type or range for a parameter a node of ``classes`` declares.

    Each value a node would get from ``-p`` and the parameter files (the sections that
    match its name, merged as rclpy merges them: :mod:`.ros_args`) is checked against the
    node's declared :class:`Param` (its module's ``PARAMS``; ``use_sim_time`` too) before
    any node declares: the value given last in a section, the one meant. rclpy would keep
    another one where a section gives the parameter values of two types (a wrong-typed
    ``-p`` after the file's value; an integer before a double): that is refused too, naming
    both. Raises :class:`ParameterError` naming the parameter, the type it must have and
    where the value came from.
    """
    for params in parsed.sections.values():
        for name, given in params.items():
            for value, origin in given.values:
                if value is ros_args.UNTYPED:
                    raise ParameterError(
                        f"parameter '{name}' (from {origin}): rcl takes a scalar or an array "
                        'of scalars of one type (write 0.0, not 0, among doubles)', name)
    for cls in classes:
        specs = list(getattr(sys.modules.get(cls.__module__), 'PARAMS', None) or ())
        specs.append(USE_SIM_TIME)
        given = parsed.for_node(parsed.node_name(node_name_of(cls)))
        for spec in specs:
            if spec.name not in given:
                continue
            value, origin = given[spec.name].last()
            try:
                spec.check(plain_value(value, spec.default))
            except ParameterError as exc:
                raise ParameterError(f'{exc} (from {origin})', spec.name) from None
            kept, kept_origin = given[spec.name].kept()
            if kept_origin != origin or type(kept) is not type(value):
                raise ParameterError(
                    f"parameter '{spec.name}': {kept_origin} gives it as the "
                    f'{ros_args.type_name(kept)} {kept!r} and then {origin} as the '
                    f'{ros_args.type_name(value)} {value!r}; rcl keeps the '
                    f'{ros_args.type_name(kept)} and would drop the later value: give each '
                    f'as {spec.kind()}', spec.name)


def check_arguments(classes: Iterable[type], argv: Sequence[str]) -> None:
    """
    Refuse, before rclpy starts, a parameter of ``argv`` that no node of ``classes`` declares.

    A node class's module lists what the node declares as ``PARAMS`` (the list the runner
    checks a run against, :func:`ibvs_bringup.graph_params.declared`). Raises
    :class:`ParameterError` naming the closest declared names (:func:`check_declared`,
    the words of ``ibvs run``), for a parameter file that cannot be read or parsed, for a
    :data:`~.params.RETIRED` name in any section, ``/**`` too (:func:`check_retired`,
    naming where it came from), and for a value of the wrong type or range
    (:func:`check_types`). Classes whose module has no ``PARAMS`` disable the name check.
    """
    classes = list(classes)
    known = []
    for cls in classes:
        params = getattr(sys.modules.get(cls.__module__), 'PARAMS', None)
        if params is None:
            known = None
            break
        known += [p.name for p in params]
    try:
        parsed = ros_args.parse(argv)
    except ros_args.ArgumentsError as exc:
        raise ParameterError(str(exc)) from None
    for params in parsed.sections.values():  # under /** too: a retired name is nobody's
        for name, given in params.items():
            check_retired([name], given.last()[1])
    names = list(parsed.rule_names)
    for path in parsed.files:
        names += file_parameter_names(path)
    if known is not None:
        owner = ', '.join(cls.__name__ for cls in classes)
        check_declared(names, known, owner=f'no node of this process ({owner})')
    check_types(classes, parsed)


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
    logger = rclpy.logging.get_logger(name or classes[0].__name__)
    try:
        dds.domain_id()
        check_arguments(classes, sys.argv if args is None else args)
    except (dds.DomainError, ParameterError) as exc:
        logger.fatal(str(exc))
        sys.exit(2)
    process.keep_freed_memory()  # frames' buffers from the heap, not fresh pages each
    stop = StopRequest()
    stop.install()
    dds.configure()
    try:
        rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    except _rclpy.RCLError as exc:
        logger.fatal(f'the ROS arguments were refused: {exc}')
        stop.restore()
        sys.exit(2)
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
