"""
Each test process on its own ROS domain, held by a lock, with discovery on localhost only.

Nothing happens on import: the repository's root ``conftest.py`` calls :func:`isolate` from
its ``pytest_configure`` hook, in the controlling pytest process and in each pytest-xdist
worker, before any test module is collected. It hands :func:`isolate` the domain lock of
every run (:mod:`ibvs_bringup.domains`; this package imports no IBVS package), so that a
test process and a run, a study or another ``make test`` on the same machine never share a
domain.
"""

from collections.abc import Callable
import os
from typing import Any, MutableMapping

#: Environment variable that says the process's ROS domain was chosen by :func:`isolate`.
DOMAIN_SET_BY = 'IBVS_TEST_DOMAIN_SET_BY'
#: The locks this process holds, for as long as it lives (the kernel drops them with it).
_HELD = []


def isolate(environ: MutableMapping[str, str] = os.environ,
            take: Callable[[MutableMapping[str, str]], tuple[int, Any]] | None = None,
            held_env: str | None = None) -> int:
    """
    Give this test process its own ROS domain and keep discovery on localhost.

    Parallel test runs (two CI jobs, a developer's shell, other agents' graphs) must not
    hear each other. An explicit ``ROS_DOMAIN_ID`` in the environment wins.

    ``take(environ)`` returns ``(domain, lock)``: the domain for ``environ`` (the explicit
    one, else the first free one of the pool) and a lock that holds it while it is open
    (None when a parent holds it), as a run takes its own
    (:func:`ibvs_bringup.domains.claim`); it raises if the explicit domain is another
    run's. The lock is kept open until the process ends, and ``held_env`` (the runs'
    ``IBVS_DOMAIN_HELD``) names the domain, so that a graph run a test starts takes the
    test process's domain, which the process holds for it. Without ``take`` the domain is
    chosen without a lock (a hash of the pids: two processes can then meet).

    Under pytest-xdist (``make test`` runs two workers) the workers inherit the environment
    of the controlling pytest process, which set its own domain here: each worker then takes
    a domain of its own (:data:`DOMAIN_SET_BY` marks a domain chosen here, not by the
    user), else the workers' nodes would hear each other and their graph runs would contend
    for one domain's lock. Calling it again in the same process changes nothing.

    Parameters
    ----------
    environ : mutable mapping of str to str
        The environment to set (the process's own by default).
    take : callable, optional
        ``take(environ) -> (domain, lock or None)``: the lock of the runs' domains.
    held_env : str, optional
        The environment variable by which a holder of a domain's lock says so.

    Returns
    -------
    int
        The ROS domain of this process.

    """
    worker = environ.get('PYTEST_XDIST_WORKER', '')
    chosen_here = environ.get(DOMAIN_SET_BY) == 'isolate'
    if _HELD and chosen_here:
        return int(environ['ROS_DOMAIN_ID'])  # this process's own, taken before
    if worker and chosen_here:
        del environ['ROS_DOMAIN_ID']  # the controller's: each worker takes one of its own
        if held_env:
            environ.pop(held_env, None)
    if 'ROS_DOMAIN_ID' not in environ:
        environ[DOMAIN_SET_BY] = 'isolate'
    if take is not None:
        domain, lock = take(environ)
        if lock is not None:
            _HELD.append(lock)
        environ['ROS_DOMAIN_ID'] = str(domain)
        if held_env:
            environ[held_env] = str(domain)
    elif 'ROS_DOMAIN_ID' not in environ:
        index = int(worker[2:]) if worker.startswith('gw') and worker[2:].isdigit() else 0
        # 1..100: inside the range ROS 2 documents as safe on Linux; two workers (gw0, gw1)
        # of one run get neighbouring domains.
        environ['ROS_DOMAIN_ID'] = str(1 + (2 * (os.getppid() % 50) + index) % 100
                                       if worker else 1 + os.getpid() % 100)
    environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return int(environ['ROS_DOMAIN_ID'])


def domain_id_of_process() -> int:
    """Return the ROS domain of this test process (``ROS_DOMAIN_ID``, set by :func:`isolate`)."""
    return int(os.environ['ROS_DOMAIN_ID'])
