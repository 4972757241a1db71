"""
Process-wide settings: dying with the parent, ending at once, quiet imports, kept memory.

The processes a runner supervises (the nodes of a run, a study's runs) start with
:func:`supervised_child` (their ``preexec_fn``); :func:`die_with_parent` is its part that
any process may call itself. :func:`exit_now` ends a process that has released what it
holds, as a ``multiprocessing`` child ends. :func:`quiet_output` keeps what C code writes
meanwhile from the terminal (PyBullet's build-time banner, written as its module loads).
:func:`keep_freed_memory` stops glibc from giving back, and faulting in again, the
megabytes of every frame's images (every node's process calls it at start:
:func:`ibvs_common.node_main.run`).
"""

import contextlib
import ctypes
import os
import signal
import sys

#: prctl's option that asks for a signal when the parent dies (linux/prctl.h).
PR_SET_PDEATHSIG = 1
#: mallopt's parameters (glibc's malloc.h).
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3
#: Blocks from this size (bytes) up are mapped on their own: glibc's largest mmap threshold
#: on 64-bit (4 MiB x sizeof(long)), above any image's buffer (an HD720 RGB image: 2.8 MB;
#: an HD2K BGRA one: 11.0 MB).
MMAP_THRESHOLD_BYTES = 32 * 2 ** 20
#: Free memory (bytes) at the heap's top that malloc keeps instead of giving it back: room
#: for several frames' buffers (a stereo frame at HD720 allocates and frees about 20 MB in
#: the simulator's process: its images, their messages, the detector's arrays).
TRIM_THRESHOLD_BYTES = 256 * 2 ** 20


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
    nodes of a study's runs would never see the runner's SIGINT and stop only at its
    SIGTERM, 10 s later. The own process group lets the runner signal a node and whatever it
    started (``ros2 run``'s child) at once.
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
    PyBullet prints through it, into a log file that is fully buffered.
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


def keep_freed_memory() -> bool:
    """
    Have glibc's malloc keep the memory it frees for the next allocation; True if it could.

    By default glibc maps a block above its mmap threshold (128 KiB at start, raised to the
    size of each mapped block freed) on its own and unmaps it when it is freed, and gives
    back the free top of the heap beyond its trim threshold (twice the mmap threshold).
    Image buffers of a few megabytes, allocated and freed 60 times a simulated second, then
    come back as fresh pages that the kernel faults in one by one as they are first written:
    about 1 ms an HD720 image on this repository's machine, in the renderer's readback, the
    messages' copies and the detector. Fixed thresholds (:data:`MMAP_THRESHOLD_BYTES`,
    :data:`TRIM_THRESHOLD_BYTES`; ``mallopt``, as ``GLIBC_TUNABLES=glibc.malloc.*`` would
    set them) keep those pages in the heap: ``make demo``'s real-time factor went from
    0.91-0.93 to 1.05-1.07 (two runs each, docs/speed.md). The cost is memory the process
    holds after a peak, at most the trim threshold more. No-op (False) where the C library
    is not glibc.
    """
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    return bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
                and mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES))


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
