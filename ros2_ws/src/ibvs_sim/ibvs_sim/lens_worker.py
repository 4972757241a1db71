"""
A second process that renders one lens of the stereo pair while the simulator renders the other.

Rendering is most of a frame's cost and one lens does not need the other, so the two can be
drawn at once on two cores: :class:`LensWorker` starts a process (``python -m
ibvs_sim.lens_server``, :mod:`ibvs_sim.lens_server`: a fresh interpreter, nothing of the
parent's ROS, DDS or OpenGL state is inherited, and the parent's ``__main__`` is not
imported again) that builds its own
:class:`ibvs_sim.world.World` with the same robot, floor and renderer. For each frame the
simulator sends the true joint angles and the lens to draw; the worker sets its robot to
those angles (``resetJointState``: a copy of the state, no dynamics), renders, and sends the
image back over a pipe. The image depends only on the joint angles and the lens, so a run
stays deterministic; :func:`ibvs_sim.world.World.render_stereo` draws the same pair either way
(tested to the bit).

The worker dies with the simulator: it asks Linux for SIGKILL when its parent exits, and it
ends on a closed pipe and on ``close``. It ignores SIGINT: Ctrl-C in a terminal, or the
runner stopping the simulator, signals the whole process group, and a worker that died
mid-frame would make the simulator fail its last render (exit code 1) instead of stopping
cleanly; the simulator stops and closes it.
"""

from collections.abc import Mapping
from multiprocessing.connection import Connection
import signal
import socket
import subprocess
import sys
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

#: How long to wait for the worker to start (spawn, imports, PyBullet and EGL), s.
START_TIMEOUT_S = 120.0
#: How long to wait for one lens image, s (a render takes well under a second).
RENDER_TIMEOUT_S = 60.0


class LensWorkerError(RuntimeError):
    """The lens worker could not start, failed to render, or is gone."""


class _WorkerGone(LensWorkerError):
    """The worker's end of the pipe closed: its process ended."""


#: How often a worker killed by a signal is started again before :class:`LensWorkerError`.
#: A crash below us, not an error of ours: twice on 2026-11-26 the worker died of a
#: segmentation fault inside libc's malloc while PyBullet's EGL plugin rendered
#: (docs/studies.md). The image depends on the joint angles and the lens only, so the new
#: worker renders the same one. A worker that exits by itself is never started again.
MAX_RESTARTS = 2
#: The signals a worker is started again after: a crash (SIGKILL: the kernel's out-of-memory
#: killer), not a request to stop (SIGTERM, SIGINT, SIGHUP: the run is ending).
CRASH_SIGNALS = frozenset({signal.SIGSEGV, signal.SIGBUS, signal.SIGABRT, signal.SIGILL,
                           signal.SIGFPE, signal.SIGKILL})


class LensWorker:
    """
    Render a lens in another process: :meth:`submit`, do other work, then :meth:`result`.

    ``world_kwargs`` are the keyword arguments of the :class:`ibvs_sim.world.World` to build
    there (the same robot, floor and renderer as the simulator's own). A worker killed by one
    of :data:`CRASH_SIGNALS` while it renders is started again and asked for the same image,
    up to :data:`MAX_RESTARTS` times; :attr:`restarts` says why each time.
    """

    def __init__(self, world_kwargs: Mapping[str, Any]) -> None:
        """
        Start the worker building its World; :meth:`wait_ready` waits until it has.

        The caller does its own start-up meanwhile: the worker's imports, EGL and URDF load
        then overlap with the simulator's (about a second of every run's start, issue 24).
        """
        self._world_kwargs = dict(world_kwargs)
        self._process = None
        #: The request of the image not yet returned ((q, args)), or None.
        self._pending = None
        #: The renderer the worker's World uses ('egl' or 'tiny'); None until ready.
        self.renderer = None
        #: Why the worker was started again, once per restart (:data:`MAX_RESTARTS`).
        self.restarts: list[str] = []
        self._start()

    def _start(self):
        ours, theirs = socket.socketpair()
        self._process = subprocess.Popen(
            [sys.executable, '-m', 'ibvs_sim.lens_server', str(theirs.fileno())],
            pass_fds=(theirs.fileno(),))
        theirs.close()
        self._conn = Connection(ours.detach())
        self._ready = False
        self._conn.send(self._world_kwargs)

    def wait_ready(self) -> str:
        """Wait until the worker's World is built; return its renderer (LensWorkerError if not)."""
        if not self._ready:
            kind, detail = self._receive(START_TIMEOUT_S, 'start')
            if kind != 'ready' or detail != (self.renderer or detail):
                self.close()
                raise LensWorkerError(f'the lens worker did not start: {detail}')
            self.renderer, self._ready = detail, True
        return self.renderer

    def _receive(self, timeout_s, what):
        if not self._conn.poll(timeout_s):
            alive = self._process.poll() is None
            self.close()
            raise LensWorkerError(f'no answer from the lens worker within {timeout_s:.0f} s '
                                  f'({what}); process {"alive" if alive else "gone"}')
        try:
            return self._conn.recv()
        except (EOFError, OSError) as exc:
            raise _WorkerGone(f'the lens worker is gone ({what}): {exc!r}') from None

    def submit(self, q: ArrayLike, *args: Any) -> None:
        """Ask for :meth:`World.render_lens` (``args``) with the robot at joint angles ``q``."""
        if self._pending is not None:
            raise LensWorkerError('submit() again before result()')
        self._pending = (np.asarray(q, dtype=float), args)
        self._send(self._pending)

    def _send(self, request):
        try:
            self.wait_ready()
            self._conn.send(request)
        except (BrokenPipeError, OSError):
            pass  # the worker is gone: result() finds out, and why

    def result(self) -> NDArray[np.uint8]:
        """Return the (H, W, 3) uint8 image asked for by the last :meth:`submit`."""
        if self._pending is None:
            raise LensWorkerError('result() without submit()')
        request, self._pending = self._pending, None
        while True:
            try:
                kind, detail = self._receive(RENDER_TIMEOUT_S, 'render')
                break
            except _WorkerGone as exc:
                self._restart_or_raise(exc)
                self._send(request)
        if kind != 'image':
            raise LensWorkerError(f'the lens worker failed to render: {detail}')
        data = self._conn.recv_bytes()
        return np.frombuffer(data, dtype=np.uint8).reshape(detail).copy()

    def _restart_or_raise(self, gone):
        """Start a worker again after one killed by a signal (MAX_RESTARTS); else raise."""
        try:
            code = self._process.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            code = None
        if code is None or code >= 0 or -code not in CRASH_SIGNALS or \
                len(self.restarts) >= MAX_RESTARTS:
            self.close()
            ended = 'still running' if code is None else f'exit code {code}'
            raise LensWorkerError(f'{gone} ({ended}; {len(self.restarts)} restart(s) '
                                  'before)') from None
        self.restarts.append(f'the lens worker was killed by {signal.Signals(-code).name} '
                             'while it rendered; started again, the frame rendered again')
        self._conn.close()
        self._start()

    def close(self) -> None:
        """Stop the worker (idempotent)."""
        if self._process is None:
            return
        try:
            self._conn.send(None)
        except (BrokenPipeError, OSError):
            pass
        try:
            self._process.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            self._process.kill()
            self._process.wait(timeout=5.0)
        self._conn.close()
        self._process = None
