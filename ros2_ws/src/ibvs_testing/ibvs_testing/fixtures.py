"""
The pytest fixtures every package's tests share, and :func:`spin_until`.

Each test directory's ``conftest.py`` imports the fixtures it uses from here, so they work
both from the repository root (``make test``, ``pytest``) and under ``colcon test``. The
process's ROS domain is set before, by :func:`ibvs_testing.isolation.isolate` (the root
``conftest.py``).

- :func:`context`: a private, initialised rclpy Context on this process's domain;
- :func:`executor_of`: executors of nodes in that context, torn down after the test;
- :func:`domain_id`: that domain, for child processes;
- :func:`proc_tools`: process inspection through /proc (:class:`.proc_tools.ProcTools`);
- :func:`closed_after_module`: a module-scoped fixture of an object closed after the module
  (e.g. ibvs_sim's PyBullet ``World``, which the conftests that use it name);
- :func:`spin_until`: spin an executor until a condition holds (a deadline guards a hang;
  tests wait on conditions, never on wall-clock time).
"""

import time
from typing import Any, Callable, Iterator, List, Tuple, Type, TypeVar

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.node import Node

from .isolation import domain_id_of_process
from .proc_tools import ProcTools

#: Default deadline of :func:`spin_until` (seconds): only a guard against a hang.
DEADLINE_S = 60.0

T = TypeVar('T')


@pytest.fixture(scope='session')
def domain_id() -> int:
    """Return the ROS domain of this test process, e.g. for the environment of a child."""
    return domain_id_of_process()


@pytest.fixture
def context() -> Iterator[Context]:
    """Yield a private, initialised rclpy Context (as rclpy's own tests do)."""
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain_id_of_process())
    try:
        yield ctx
    finally:
        rclpy.try_shutdown(context=ctx)


@pytest.fixture
def executor_of(context: Context) -> Iterator[Callable[..., SingleThreadedExecutor]]:
    """
    Yield make(*nodes): a SingleThreadedExecutor of ``context`` spinning ``nodes``.

    At teardown every executor made is shut down and its nodes destroyed.
    """
    made: List[Tuple[SingleThreadedExecutor, Tuple[Node, ...]]] = []

    def make(*nodes: Node) -> SingleThreadedExecutor:
        executor = SingleThreadedExecutor(context=context)
        for node in nodes:
            executor.add_node(node)
        made.append((executor, nodes))
        return executor

    yield make
    for executor, nodes in made:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()


@pytest.fixture
def proc_tools() -> Type[ProcTools]:
    """Return the /proc helpers."""
    return ProcTools


def closed_after_module(make: Callable[[], T], doc: str = '') -> Any:
    """
    Return a module-scoped fixture that yields ``make()`` and calls its ``close()`` after.

    Parameters
    ----------
    make : callable
        Builds the object (no arguments), once per test module.
    doc : str
        The fixture's docstring (what ``pytest --fixtures`` shows).

    Returns
    -------
    fixture
        To be bound in a ``conftest.py`` under the name the tests ask for.

    """
    def fixture() -> Iterator[T]:
        resource = make()
        try:
            yield resource
        finally:
            resource.close()  # type: ignore[attr-defined]

    fixture.__doc__ = doc or f'Yield {getattr(make, "__name__", "the object")}(), closed after.'
    return pytest.fixture(scope='module')(fixture)


def spin_until(executor: Executor, condition: Callable[[], bool],
               deadline_s: float = DEADLINE_S, what: str = 'condition') -> None:
    """Spin ``executor`` until ``condition()`` is true; fail naming ``what`` at the deadline."""
    end = time.monotonic() + deadline_s
    while not condition():
        assert time.monotonic() < end, f'timed out waiting for {what}'
        executor.spin_once(timeout_sec=0.05)
