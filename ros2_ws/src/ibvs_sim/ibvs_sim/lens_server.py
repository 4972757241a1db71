"""
The lens worker's own side: build a World, then render the lens asked for, frame after frame.

The process that :class:`ibvs_sim.lens_worker.LensWorker` starts (``python -m
ibvs_sim.lens_server FD``, the socket to the simulator as FD); the protocol and why the
process ignores SIGINT are in :mod:`ibvs_sim.lens_worker`. In a module of its own so that
the simulator's side, which :mod:`ibvs_sim.world` imports, does not import the world back.
"""

from multiprocessing.connection import Connection
import signal
import sys
import traceback

from ibvs_common.process import die_with_parent, exit_now
import numpy as np

from .world import World


def serve(conn: Connection) -> None:
    """Worker side: build the World it is sent, then answer render requests until told to stop."""
    die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the simulator ends it (ibvs_sim.lens_worker)
    try:
        world = World(**conn.recv())
    except Exception:
        conn.send(('error', traceback.format_exc()))
        return
    conn.send(('ready', world.renderer))
    try:
        while True:
            try:
                request = conn.recv()
            except EOFError:
                return
            if request is None:
                return
            q, args = request
            try:
                world.reset(q)
                image = world.render_lens(*args)
            except Exception:
                conn.send(('error', traceback.format_exc()))
                continue
            conn.send(('image', image.shape))
            conn.send_bytes(np.ascontiguousarray(image).reshape(-1))
    finally:
        world.close()


if __name__ == '__main__':
    serve(Connection(int(sys.argv[1])))
    # The World is closed: no teardown for the simulator to wait for as it stops.
    exit_now(0)
