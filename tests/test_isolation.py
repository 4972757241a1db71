"""
Test processes take their ROS domain through the lock of the runs.

A test process that chose its domain by a hash of pids, outside the lock every run takes
(:mod:`ibvs_bringup.domains`), could share it with another ROS 2 graph, and its nodes would
then read that graph's messages (the joint controller waiting for the other graph's
frames).
"""

import os
import subprocess
import sys

from ibvs_bringup import domains
from ibvs_testing import isolation


def release_last():
    isolation._HELD.pop().close()


def test_this_test_process_holds_its_domain():
    domain = isolation.domain_id_of_process()
    assert os.environ[domains.HELD_ENV] == str(domain)
    if isolation._HELD:  # else a parent holds it for us (IBVS_DOMAIN_HELD)
        assert domains.try_lock(domain) is None


def test_a_test_process_takes_the_highest_free_domain_runs_the_lowest():
    """Tests keep away from domain 0 (lock-free graphs) and from the runs' first domains."""
    top, lock1 = domains.claim({}, pool=(195, 198), from_top=True)
    below, lock2 = domains.claim({}, pool=(195, 198), from_top=True)
    low, lock3 = domains.claim({}, pool=(195, 198))
    try:
        assert (top, below, low) == (198, 197, 195)
    finally:
        for lock in (lock1, lock2, lock3):
            lock.close()


def _free(domain):
    """Return whether nobody holds ``domain`` now (the probe's lock is let go at once)."""
    lock = domains.try_lock(domain)
    if lock is None:
        return False
    lock.close()
    return True


def test_isolate_takes_a_free_domain_of_the_pool_and_holds_it():
    mine = isolation.domain_id_of_process()
    # A pool of this process's domain and a free one (the other xdist worker holds a domain
    # next to ours, the runs of other sessions others).
    free = next(d for d in range(101, -1, -1) if d != mine and _free(d))
    environ = {domains.POOL_ENV: f'{min(mine, free)}-{max(mine, free)}'}
    domain = isolation.isolate(environ, take=domains.claim, held_env=domains.HELD_ENV)
    try:
        assert domain != mine and environ['ROS_DOMAIN_ID'] == str(domain)
        assert environ[domains.HELD_ENV] == str(domain)
        assert environ[isolation.DOMAIN_SET_BY] == 'isolate'
        assert domains.try_lock(domain) is None  # held: a run cannot take it
        # An xdist worker inherits the controller's domain and takes one of its own.
        worker = dict(environ, PYTEST_XDIST_WORKER='gw0')
        isolation._HELD.append(isolation._HELD.pop())  # still this process's first lock
        held = list(isolation._HELD)
        isolation._HELD.clear()
        try:
            other = dict(worker, **{domains.POOL_ENV: '0-101'})
            second = isolation.isolate(other, take=domains.claim, held_env=domains.HELD_ENV)
            assert second not in (domain, mine) and other[domains.HELD_ENV] == str(second)
            release_last()
        finally:
            isolation._HELD.extend(held)
    finally:
        release_last()


def test_a_second_session_cannot_take_a_domain_a_test_process_holds():
    if not isolation._HELD:
        return  # a parent holds this process's domain: nothing of ours to contend for
    env = {k: v for k, v in os.environ.items()
           if k not in (domains.HELD_ENV, isolation.DOMAIN_SET_BY, 'PYTEST_XDIST_WORKER')}
    probe = f'{os.path.abspath(__file__)}::test_this_test_process_holds_its_domain'
    done = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
                           probe], capture_output=True, text=True, env=env, timeout=120,
                          cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out = done.stdout + done.stderr
    assert done.returncode != 0 and 'is used by another run' in out, out
