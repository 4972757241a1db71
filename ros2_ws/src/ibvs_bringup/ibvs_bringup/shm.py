"""
Fast DDS shared-memory files that dead processes left in /dev/shm: find them, remove them.

Fast DDS (the RMW of the graph) gives each participant shared-memory segments and ports,
files in /dev/shm. A process that exits cleanly removes its own; one killed with SIGKILL
leaves them, about 68 MB per lockstep process, and nothing reclaims them. The rule is Fast
DDS's own (``fastdds shm clean``, tools/fastdds/shm/clean.py of eProsima/Fast-DDS): each
segment ``fastrtps_<16 characters>`` and each port ``fastrtps_port<N>`` has a lock file
(``_el`` or ``_sl`` appended) that its owner holds with ``flock`` while it is alive; a lock
file that can be locked belongs to a dead owner, and its segment can go. Unlike that tool
this module leaves alone files younger than :data:`MIN_AGE_S` that a live process has open
(or, when it cannot see the descriptors of every process of the file's owner, any such
file: another user's, unless run as root), so that it cannot
race a participant that has created its lock file but not yet locked it, and it removes
participants' segments only, not ports: a segment has a name of its own, drawn at random by
its one owner, and holds the memory (about 68 MB per killed lockstep process); a port
(52 kB) is shared by the participants of its domain, and a participant that was opening a
port while another graph's clean-up tested or removed its lock failed to start ("Failed
init_port ...: open_and_lock_file failed", seen with two test workers at once). It reports
what it freed.
"""

from collections.abc import Container
import fcntl
import os
from pathlib import Path
import re
import time

#: Where Fast DDS keeps its shared memory on Linux.
SHM_DIR = Path('/dev/shm')
#: A participant segment's lock file (Fast DDS 2.x names); ports are left (module docstring).
LOCK_FILE = re.compile(r'^fastrtps_[0-9a-z]{16}_(?:el|sl)$')
#: Files younger than this (s) are left alone: their owner may be starting.
MIN_AGE_S = 10.0


def _locked(path):
    """Return whether another open file description holds ``path``'s flock."""
    try:
        with open(path, 'rb') as fd:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:  # gone meanwhile, or not ours to open: leave it
        return True
    return False


def names(shm_dir: str | Path = SHM_DIR) -> set[str]:
    """Return the names of the files in ``shm_dir`` now (a run's snapshot at its start)."""
    try:
        return set(os.listdir(shm_dir))
    except FileNotFoundError:
        return set()


def open_files(shm_dir: str | Path = SHM_DIR, proc: str | Path = '/proc',
               uid: int | None = None) -> tuple[set[str], bool]:
    """
    Return the files of ``shm_dir`` a live process has open, and whether all were seen.

    The second value says whether every process's descriptors could be read (as root: yes;
    else only one's own), or with ``uid`` every process of that user's (one's own user:
    yes), the only ones that can be creating a file that user owns.

    A participant holds its lock file open from the moment it creates it (``flock`` needs an
    open file): a lock file nobody has open belongs to a dead owner, however young it is.
    """
    shm_dir = os.path.realpath(shm_dir)
    found, complete = set(), True
    for pid in os.listdir(proc):
        if not pid.isdigit():
            continue
        fd_dir = os.path.join(proc, pid, 'fd')
        try:
            fds = os.listdir(fd_dir)
        except FileNotFoundError:  # ended meanwhile
            continue
        except PermissionError:
            try:
                theirs = uid is None or os.stat(os.path.join(proc, pid)).st_uid == uid
            except OSError:  # ended meanwhile
                continue
            complete = complete and not theirs
            continue
        for fd in fds:
            try:
                target = os.readlink(os.path.join(fd_dir, fd))
            except OSError:
                continue
            if os.path.dirname(target) == shm_dir:
                found.add(os.path.basename(target))
    return found, complete


def zombies(shm_dir: str | Path = SHM_DIR, min_age_s: float = MIN_AGE_S,
            now: float | None = None, new_since: Container[str] | None = None) -> list[Path]:
    """
    Return the files of the segments whose owner is dead (module docstring).

    With ``new_since`` (a :func:`names` snapshot) only lock files created since count: what
    processes started and died since then left. Files younger than ``min_age_s`` are left
    in either case: another graph (a study's parallel run, a test) may be starting on this
    machine, and a lock file its participant has created but not yet locked looks dead
    (removing it made that participant fail with "open_and_lock_file failed"), unless no
    live process has it open (:func:`open_files`, which sees the descriptors of every
    process of the file's owner: as root any file's, else one's own files'): then even a
    young one is a dead owner's, so that what a run killed in its first seconds left goes
    at the next run's start too; another user's young files are left to that user.
    """
    now = time.time() if now is None else now
    held = {}  # open_files() by owner, read once and only for a young lock file
    found = []
    for name in sorted(names(shm_dir)):
        if not LOCK_FILE.match(name) or (new_since is not None and name in new_since):
            continue
        lock = Path(shm_dir) / name
        try:
            stat = lock.stat()
        except FileNotFoundError:
            continue
        if now - stat.st_mtime < min_age_s:
            if stat.st_uid not in held:
                held[stat.st_uid] = open_files(shm_dir, uid=stat.st_uid)
            seen, complete = held[stat.st_uid]
            if not complete or name in seen:
                continue
        if _locked(lock):
            continue
        found += [lock, lock.with_name(name[:-3])]
    return found


def clean(shm_dir: str | Path = SHM_DIR, min_age_s: float = MIN_AGE_S,
          new_since: Container[str] | None = None) -> tuple[int, int]:
    """Remove :func:`zombies`; return (files removed, bytes freed)."""
    count, freed = 0, 0
    for path in zombies(shm_dir, min_age_s, new_since=new_since):
        try:
            size = path.stat().st_size
            path.unlink()
        except OSError:
            continue
        count += 1
        freed += size
    return count, freed
