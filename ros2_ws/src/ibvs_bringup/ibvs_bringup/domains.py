"""
ROS domains of the runs on one machine: no two runs share one.

Two graphs on one ROS domain hear each other: each recorder would record both simulators and
each controller would answer both. Every run therefore holds an exclusive ``flock`` on its
domain's file in a directory under the system's temporary directory, whoever started it
(``ibvs run``, a report, a study, a Ray worker); a run that dies releases its domain with
its process.

- ``ROS_DOMAIN_ID`` set: the run takes that domain, or stops with :class:`DomainBusy` if
  another run holds it.
- Not set: the run takes the first free domain of the pool, from 0 on by default, so that a
  lone run is on domain 0, where the ``ros2`` CLI looks by default.

The pool of every run, study, report and test is the one environment variable
``IBVS_ROS_DOMAINS`` (``LOW-HIGH``), by default the whole range ROS 2 documents as safe on
Linux, 0-101 (higher IDs can collide with the ephemeral ports of the operating system).
- A study holds the domains of its runs itself and says so in ``IBVS_DOMAIN_HELD``.
"""

from collections.abc import Iterator, MutableMapping
from contextlib import contextmanager
import fcntl
import os
from pathlib import Path
import tempfile
import time
from typing import TextIO

#: Directory of the lock files, one per domain ID.
LOCK_DIR = Path(tempfile.gettempdir()) / 'ibvs-ros-domains'
#: Environment variable by which a parent that holds the lock of ROS_DOMAIN_ID says so.
HELD_ENV = 'IBVS_DOMAIN_HELD'
#: The ROS domains ROS 2 documents as safe on Linux (inclusive): above 101 a domain's ports
#: can collide with the kernel's ephemeral ports.
SAFE_RANGE = (0, 101)
#: Environment variable that sets the pool of domains (``LOW-HIGH``) of every run.
POOL_ENV = 'IBVS_ROS_DOMAINS'


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
    """Return the pool of domains: ``IBVS_ROS_DOMAINS`` if set, else :data:`SAFE_RANGE`."""
    text = environ.get(POOL_ENV, '').strip()
    return parse_pool(text) if text else SAFE_RANGE


#: Domains a run without ROS_DOMAIN_ID may take (inclusive), as the environment says.
FREE_POOL = pool()


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
          pool: tuple[int, int] = FREE_POOL) -> tuple[int, TextIO | None]:
    """
    Return ``(domain, lock)`` for a run started with ``environ`` (module docstring).

    ``lock`` is None when the parent holds the domain (``IBVS_DOMAIN_HELD``); close it when
    the run ends. Raises :class:`DomainBusy` when ROS_DOMAIN_ID names a domain another run
    holds, or when every domain of ``pool`` is held.
    """
    text = environ.get('ROS_DOMAIN_ID', '').strip()
    if text:
        domain = int(text)
        if environ.get(HELD_ENV, '').strip() == text:
            return domain, None
        lock = try_lock(domain)
        if lock is None:
            raise DomainBusy(f'ROS_DOMAIN_ID={domain} is used by another run on this machine '
                             f'(lock {LOCK_DIR / f"{domain}.lock"}); choose another ID, or '
                             'unset ROS_DOMAIN_ID to take the first free one')
        return domain, lock
    for domain in range(pool[0], pool[1] + 1):
        lock = try_lock(domain)
        if lock is not None:
            return domain, lock
    raise DomainBusy(f'every ROS domain from {pool[0]} to {pool[1]} is used by another run')


@contextmanager
def held(environ: MutableMapping[str, str] = os.environ,
         pool: tuple[int, int] = FREE_POOL) -> Iterator[tuple[int, bool]]:
    """
    Hold a run's domain (:func:`claim`) with ``ROS_DOMAIN_ID`` set to it in ``environ``.

    Yields ``(domain, chosen)``, ``chosen`` True when ROS_DOMAIN_ID was not set and the
    domain is the first free one. On leaving, however that happens, the lock is released and
    ``environ`` is as it was, so that a process can run one graph after another.
    """
    saved = environ.get('ROS_DOMAIN_ID')
    domain, lock = claim(environ, pool)
    environ['ROS_DOMAIN_ID'] = str(domain)
    try:
        yield domain, not (saved or '').strip()
    finally:
        if lock is not None:
            lock.close()
        if saved is None:
            del environ['ROS_DOMAIN_ID']
        else:
            environ['ROS_DOMAIN_ID'] = saved
