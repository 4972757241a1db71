"""
A child process that dies with its parent, and one that ends without the interpreter's teardown.

Two kinds of children use it: the processes a runner supervises (the nodes of a run, a
study's runs: :func:`supervised_child`, their ``preexec_fn``) and the simulator's lens
worker (:mod:`ibvs_sim.lens_server`, which calls :func:`die_with_parent` itself and stays in
the simulator's process group, so that it is stopped with it). :func:`exit_now` ends a
worker process that has released what it holds, as a ``multiprocessing`` child ends.
:func:`quiet_output` keeps what C code writes meanwhile from the terminal (PyBullet's
build-time banner, written as its module loads).
"""

import contextlib
import ctypes
import os
import signal
import sys

#: prctl's option that asks for a signal when the parent dies (linux/prctl.h).
PR_SET_PDEATHSIG = 1


def die_with_parent() -> None:
    """Ask Linux to SIGKILL this process when its parent dies (no-op where prctl is absent)."""
    try:
        libc = ctypes.CDLL('libc.so.6', use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    except OSError:
        pass


def supervised_child() -> None:
    """
    Child-side: own process group, no blocked signal, and SIGKILL when the runner dies.

    A blocked signal mask is inherited across ``exec``: a Ray worker blocks SIGINT, and the
    nodes of a study's runs then never saw the runner's SIGINT; each stopped only at SIGTERM,
    10 s later (measured: 60 s of a 0.3 s run's 64 s). The own process group lets the runner
    signal a node and whatever it started (``ros2 run``'s child) at once.
    """
    os.setpgid(0, 0)
    signal.pthread_sigmask(signal.SIG_SETMASK, [])
    die_with_parent()


def exit_now(code: int = 0) -> None:
    """
    Flush stdio (Python's and C's), then end the process with ``code`` at once.

    What ``multiprocessing`` does at the end of a child (``os._exit`` after its target): the
    caller has closed what it holds, and the interpreter's teardown, freeing every module's
    objects one by one (0.15-0.25 s with numpy, scipy, OpenCV, PyBullet and rclpy loaded),
    would only hold up whoever waits for this process to exit. C's stdio is flushed too:
    PyBullet and the EGL plugin print through it, into a log file that is fully buffered.
    """
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, OSError, ValueError):
            pass
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):
        pass
    os._exit(code)


@contextlib.contextmanager
def quiet_output():
    """
    Send what is written to file descriptors 1 and 2 meanwhile to /dev/null (C code's too).

    For PyBullet's import, whose C module writes ``pybullet build time: ...`` to standard
    error as it loads: a line before every error message of ``ibvs`` and in every node's
    log, which says nothing. Python's and C's buffered streams are flushed before and after,
    so that nothing written before is lost and nothing written meanwhile comes out later.
    Python exceptions are raised as usual.
    """
    libc = ctypes.CDLL(None)
    sys.stdout.flush()
    sys.stderr.flush()
    libc.fflush(None)
    saved = [os.dup(fd) for fd in (1, 2)]
    try:
        with open(os.devnull, 'wb') as null:
            for fd in (1, 2):
                os.dup2(null.fileno(), fd)
        yield
    finally:
        libc.fflush(None)
        for fd, copy in zip((1, 2), saved):
            os.dup2(copy, fd)
            os.close(copy)
