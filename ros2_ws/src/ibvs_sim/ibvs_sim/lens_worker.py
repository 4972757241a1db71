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


class LensWorker:
    """
    Render a lens in another process: :meth:`submit`, do other work, then :meth:`result`.

    ``world_kwargs`` are the keyword arguments of the :class:`ibvs_sim.world.World` to build
    there (the same robot, floor and renderer as the simulator's own).
    """

    def __init__(self, world_kwargs: Mapping[str, Any]) -> None:
        """
        Start the worker building its World; :meth:`wait_ready` waits until it has.

        The caller does its own start-up meanwhile: the worker's imports, EGL and URDF load
        then overlap with the simulator's (about a second of every run's start, issue 24).
        """
        ours, theirs = socket.socketpair()
        self._process = subprocess.Popen(
            [sys.executable, '-m', 'ibvs_sim.lens_server', str(theirs.fileno())],
            pass_fds=(theirs.fileno(),))
        theirs.close()
        self._conn = Connection(ours.detach())
        self._pending = False
        #: The renderer the worker's World uses ('egl' or 'tiny'); None until ready.
        self.renderer = None
        self._conn.send(world_kwargs)

    def wait_ready(self) -> str:
        """Wait until the worker's World is built; return its renderer (LensWorkerError if not)."""
        if self.renderer is None:
            kind, detail = self._receive(START_TIMEOUT_S, 'start')
            if kind != 'ready':
                self.close()
                raise LensWorkerError(f'the lens worker did not start: {detail}')
            self.renderer = detail
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
            self.close()
            raise LensWorkerError(f'the lens worker is gone ({what}): {exc!r}') from None

    def submit(self, q: ArrayLike, *args: Any) -> None:
        """Ask for :meth:`World.render_lens` (``args``) with the robot at joint angles ``q``."""
        if self._pending:
            raise LensWorkerError('submit() again before result()')
        self.wait_ready()
        try:
            self._conn.send((np.asarray(q, dtype=float), args))
        except (BrokenPipeError, OSError) as exc:
            self.close()
            raise LensWorkerError(f'the lens worker is gone: {exc!r}') from None
        self._pending = True

    def result(self) -> NDArray[np.uint8]:
        """Return the (H, W, 3) uint8 image asked for by the last :meth:`submit`."""
        if not self._pending:
            raise LensWorkerError('result() without submit()')
        self._pending = False
        kind, detail = self._receive(RENDER_TIMEOUT_S, 'render')
        if kind != 'image':
            raise LensWorkerError(f'the lens worker failed to render: {detail}')
        data = self._conn.recv_bytes()
        return np.frombuffer(data, dtype=np.uint8).reshape(detail).copy()

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
