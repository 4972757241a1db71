"""
The output folder of a run or a cell session: claimed, locked, and only its own files replaced.

``ibvs run`` and ``ibvs cell`` write into a folder (``-o DIR``, or their default one) by the
same rule, :func:`claim`:

- The folder is made if it is not there. One that is there is taken only if it is empty,
  holds only what ``ibvs study`` writes beside a run (``companions``: its ``runner.log``),
  or is a previous run's or session's: it holds the marker file :data:`MARKER`, which every
  claim writes. Anything else (``-o ~``, a folder of one's own files) is refused with
  :class:`OutputRefused`, and nothing in it is touched.
- ``DIR`` itself a symbolic link is refused (naming where it points): the rule is about
  the folder named, and a link would take the run's removals out of it. A link further up
  the path (``results`` on another disk) is followed as usual.
- The marker is also the lock: the claim holds an exclusive ``flock`` on it while the run
  lives (a killed run's lock goes with its process) and writes its pid and command line
  into it, so that a second run into the same folder is refused, naming the first, before
  it has removed anything.
- A run then removes, of an earlier run's files, only those it writes itself, by name
  (:meth:`Claim.remove`): a link among them is removed, never followed.

Without ``-o``, ``ibvs cell`` and ``ibvs teach`` write into a new folder named after the
time they started (:func:`session_dir`).
"""

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
import fcntl
import fnmatch
import json
import os
from pathlib import Path
import shutil
import sys
import time
from typing import BinaryIO

#: The marker (and lock) file of a folder written by ``ibvs run`` or ``ibvs cell``.
MARKER = '.ibvs-run'
#: What ``ibvs study`` writes into a run's folder beside the run itself (before it, its
#: ``runner.log``; after it, ``run.json`` and each earlier attempt's log and logs).
STUDY_COMPANIONS = ('runner.log', 'run.json', 'runner.attempt*.log', 'logs.attempt*')


class OutputRefused(RuntimeError):
    """An output folder that a run must not write into (named, with the reason)."""


@dataclass
class Claim:
    """A claimed output folder (:func:`claim`): held until :meth:`release`."""

    path: Path
    #: Whether the claim made the folder (a refused start removes it again).
    created: bool
    _lock: BinaryIO

    def remove(self, names: Iterable[str]) -> None:
        """Remove the entries ``names`` of the folder (files, folders, links: not followed)."""
        for name in names:
            entry = self.path / name
            if entry.is_symlink() or entry.is_file():
                entry.unlink()
            elif entry.is_dir():
                shutil.rmtree(entry)

    def release(self, remove_if_unused: Sequence[str] | None = None) -> None:
        """
        Release the lock.

        ``remove_if_unused``: the names this claim's user wrote, for a start that was refused
        after the claim: if the claim made the folder, those and the marker are removed, and
        the folder too once it is empty.
        """
        if self._lock.closed:
            return
        if remove_if_unused is not None and self.created:
            self.remove(list(remove_if_unused) + [MARKER])
            try:
                self.path.rmdir()
            except OSError:  # something else is in it now: left
                pass
        self._lock.close()


def _holder(path):
    """Return what the marker ``path`` says of the run that holds it ('' if nothing yet)."""
    try:
        said = json.loads(Path(path).read_text() or '{}')
    except (OSError, ValueError):
        return ''
    return f"pid {said.get('pid', '?')}, command line: {said.get('command', '?')}"


def _command_line():
    """Return this process's command line as started (``python -m ...``), from /proc."""
    try:
        with open('/proc/self/cmdline', 'rb') as f:
            return [a.decode(errors='replace') for a in f.read().split(b'\0') if a]
    except OSError:
        return [sys.executable, *sys.argv]


def claim(path: str | Path, companions: Sequence[str] = (),
          command: Sequence[str] | None = None) -> Claim:
    """
    Claim the output folder ``path`` by the module's rule; return the held :class:`Claim`.

    ``companions``: name patterns (fnmatch) that another tool writes beside the run and that
    do not make the folder foreign (:data:`STUDY_COMPANIONS`); ``command``: the command line
    written into the marker (default this process's). Raises :class:`OutputRefused`.
    """
    path = Path(path)
    if path.is_symlink():
        raise OutputRefused(f'{path} is a symbolic link (to {os.path.realpath(path)}): give '
                            'the folder itself; a run writes and replaces files in the folder '
                            'named, never through a link')
    created = False
    try:
        if not path.exists():
            path.mkdir(parents=True)
            created = True
        entries = os.listdir(path)
    except NotADirectoryError:
        raise OutputRefused(f'{path} is not a folder') from None
    except OSError as exc:
        raise OutputRefused(f'cannot create or read the output folder {path}: '
                            f'{exc.strerror or exc}') from None
    foreign = sorted(e for e in entries if e != MARKER
                     and not any(fnmatch.fnmatch(e, p) for p in companions))
    if foreign and MARKER not in entries:
        shown = ', '.join(foreign[:5]) + (', ...' if len(foreign) > 5 else '')
        raise OutputRefused(
            f'{path} holds files that no run wrote ({shown}; no {MARKER} marker): give an '
            "empty or new folder, or a previous run's (one written before runs marked their "
            f'folders: `touch {path / MARKER}` marks it)')
    marker = path / MARKER
    try:
        fd = os.open(marker, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except OSError as exc:
        if created:
            path.rmdir()
        raise OutputRefused(f'cannot write the output folder {path}: '
                            f'{exc.strerror or exc}') from None
    lock = os.fdopen(fd, 'r+b')
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.close()
        holder = _holder(marker)
        raise OutputRefused(f'{path} is in use by another run ({holder or "just starting"}); '
                            'wait for it to end, or give another folder') from None
    said = {'pid': os.getpid(), 'command': ' '.join(command if command is not None
                                                    else _command_line())}
    lock.truncate(0)
    lock.write((json.dumps(said) + '\n').encode())
    lock.flush()
    return Claim(path, created, lock)


def session_dir(root: Path) -> Path:
    """Return a new folder for a session's parameters and logs: ``root/<date-time>``."""
    return root / time.strftime('%Y%m%d-%H%M%S')
