"""
ROS domains of the runs on one machine: no two runs share one.

Two graphs on one ROS domain hear each other: each recorder would record both simulators and
each controller would answer both. Every run therefore holds an exclusive ``flock`` on its
domain's file in a directory under the system's temporary directory, whoever started it
(``ibvs run``, a report, a study, a Ray worker); a run that dies releases its domain with
its process.

- ``ROS_DOMAIN_ID`` set: the run takes that domain, or stops with :class:`DomainBusy` if
  another run holds it. The value is checked first (:func:`ibvs_common.dds.domain_id`): a
  plain decimal number within :data:`SAFE_RANGE`, else :class:`DomainError` naming the
  variable, so that the lock is on the domain ROS will use (rcl reads ``-1`` as another
  number, ``010`` as octal 8).
- Not set: the run takes the first free domain of the pool, from 0 on by default, so that a
  lone run is on domain 0, where the ``ros2`` CLI looks by default.

The pool of every run, study, report and test is the one environment variable
``IBVS_ROS_DOMAINS`` (``LOW-HIGH``), by default the whole range ROS 2 documents as safe on
Linux, 0-101 (higher IDs can collide with the ephemeral ports of the operating system). It
is read when a run claims its domain, not on import: a broken value is a
:class:`DomainError` naming the variable, which ``ibvs`` turns into exit code 2.
- A study holds the domains of its runs itself and says so in ``IBVS_DOMAIN_HELD``; so does
  a test process (:func:`ibvs_testing.isolation.isolate`), for the runs its tests start.
"""

from collections.abc import Iterator, MutableMapping
from contextlib import contextmanager
import fcntl
import os
from pathlib import Path
import tempfile
import time
from typing import TextIO

from ibvs_common.dds import DOMAIN_ENV, domain_id, DomainError, SAFE_RANGE

#: Directory of the lock files, one per domain ID.
LOCK_DIR = Path(tempfile.gettempdir()) / 'ibvs-ros-domains'
#: Environment variable by which a parent that holds the lock of ROS_DOMAIN_ID says so.
HELD_ENV = 'IBVS_DOMAIN_HELD'
#: Environment variable that sets the pool of domains (``LOW-HIGH``) of every run.
POOL_ENV = 'IBVS_ROS_DOMAINS'


__all__ = ['claim', 'DOMAIN_ENV', 'domain_id', 'DomainBusy', 'DomainError', 'held',
           'HELD_ENV', 'lock_domain', 'LOCK_DIR', 'parse_pool', 'pool', 'POOL_ENV',
           'SAFE_RANGE', 'try_lock']


def parse_pool(text: str) -> tuple[int, int]:
    """Return ``'LOW-HIGH'`` as (low, high) within :data:`SAFE_RANGE`; ValueError if not."""
    try:
        low, high = (int(x) for x in str(text).strip().split('-'))
    except ValueError:
        raise ValueError(f'domain range {text!r}: expected LOW-HIGH, e.g. 50-101') from None
    if not SAFE_RANGE[0] <= low <= high <= SAFE_RANGE[1]:
        raise ValueError(f'domain range {text!r}: expected {SAFE_RANGE[0]} <= LOW <= HIGH <= '
                         f'{SAFE_RANGE[1]} (the ROS domains that are safe on Linux)')
    return low, high


def pool(environ: MutableMapping[str, str] = os.environ) -> tuple[int, int]:
    """
    Return the pool of domains: ``IBVS_ROS_DOMAINS`` if set, else :data:`SAFE_RANGE`.

    Raises :class:`DomainError` (a ValueError) naming the variable if its value is broken.
    """
    text = environ.get(POOL_ENV, '').strip()
    try:
        return parse_pool(text) if text else SAFE_RANGE
    except ValueError as exc:
        raise DomainError(f'{POOL_ENV}={text!r}: {exc}') from None


_environ_pool = pool  # for the functions whose argument ``pool`` hides it


class DomainBusy(RuntimeError):
    """The domain a run was told to use is held by another run."""


def try_lock(domain: int) -> TextIO | None:
    """Return an open file that holds ``domain``'s lock, or None if another process holds it."""
    LOCK_DIR.mkdir(exist_ok=True)
    lock = open(LOCK_DIR / f'{int(domain)}.lock', 'w')
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.close()
        return None
    return lock


def lock_domain(low: int, high: int, poll_s: float = 0.5) -> tuple[int, TextIO]:
    """
    Return ``(domain, lock)``: the first free ROS_DOMAIN_ID in [low, high], held until closed.

    Waits while every ID is taken (a study's pool: its runs wait for a free domain).
    """
    while True:
        for domain in range(low, high + 1):
            lock = try_lock(domain)
            if lock is not None:
                return domain, lock
        time.sleep(poll_s)


def claim(environ: MutableMapping[str, str] = os.environ,
          pool: tuple[int, int] | None = None,
          from_top: bool = False) -> tuple[int, TextIO | None]:
    """
    Return ``(domain, lock)`` for a run started with ``environ`` (module docstring).

    ``pool``: the domains to choose from when ROS_DOMAIN_ID is unset (default: the
    environment's, :func:`pool`), the lowest free one, or the highest with ``from_top``
    (a test process's: away from domain 0, where a graph that takes no lock, ``ros2 run``
    without ROS_DOMAIN_ID, is most likely, and from the domains runs take first). ``lock``
    is None when the parent holds the domain (``IBVS_DOMAIN_HELD``); close it when the run
    ends. Raises :class:`DomainError` for a
    ROS_DOMAIN_ID or IBVS_ROS_DOMAINS that cannot be used, :class:`DomainBusy` when
    ROS_DOMAIN_ID names a domain another run holds, or when every domain of the pool is held.
    """
    domain = domain_id(environ)
    if domain is not None:
        if environ.get(HELD_ENV, '').strip() == str(domain):
            return domain, None
        lock = try_lock(domain)
        if lock is None:
            raise DomainBusy(f'ROS_DOMAIN_ID={domain} is used by another run on this machine '
                             f'(lock {LOCK_DIR / f"{domain}.lock"}); choose another ID, or '
                             'unset ROS_DOMAIN_ID to take the first free one')
        return domain, lock
    pool = _environ_pool(environ) if pool is None else pool
    order = range(pool[1], pool[0] - 1, -1) if from_top else range(pool[0], pool[1] + 1)
    for domain in order:
        lock = try_lock(domain)
        if lock is not None:
            return domain, lock
    raise DomainBusy(f'every ROS domain from {pool[0]} to {pool[1]} is used by another run')


@contextmanager
def held(environ: MutableMapping[str, str] = os.environ,
         pool: tuple[int, int] | None = None) -> Iterator[tuple[int, bool]]:
    """
    Hold a run's domain (:func:`claim`) with ``ROS_DOMAIN_ID`` set to it in ``environ``.

    Yields ``(domain, chosen)``, ``chosen`` True when ROS_DOMAIN_ID was not set and the
    domain is the first free one. On leaving, however that happens, the lock is released and
    ``environ`` is as it was, so that a process can run one graph after another.
    """
    saved = environ.get(DOMAIN_ENV)
    domain, lock = claim(environ, pool)
    environ[DOMAIN_ENV] = str(domain)
    try:
        yield domain, not (saved or '').strip()
    finally:
        if lock is not None:
            lock.close()
        if saved is None:
            del environ[DOMAIN_ENV]
        else:
            environ[DOMAIN_ENV] = saved
