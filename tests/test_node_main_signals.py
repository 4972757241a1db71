"""
Stopping a node process by signal (``ibvs_common.node_main.run``), as ``ros2 run`` users do.

The failure these tests guard against was seen in CI: a node that takes large Images while
SIGINT arrives exited 1 with ``RuntimeError: Unable to convert call argument '0'`` (the
KeyboardInterrupt raised inside rclpy's C++ message conversion) or ``RCLError: failed to
initialize wait set: the given context is not valid`` (rclpy's handler shutting the context
down between ``context.ok()`` and the wait). Under a flood of HD720 images the old ``main``
failed about one stop in ten; the stop is therefore repeated with random delays.
"""

import random
import subprocess
import sys
import textwrap
import threading
import time

import pytest
import rclpy
from sensor_msgs.msg import Image

#: A node process: subscribes to images, says 'ready' on the first one, then spins.
NODE_SCRIPT = textwrap.dedent("""
    import sys
    import time

    from ibvs_common.node_main import run
    from rclpy.node import Node
    from sensor_msgs.msg import Image


    class Sink(Node):
        def __init__(self):
            super().__init__('signal_sink')
            self.count = 0
            self.create_subscription(Image, 'flood', self.on_image, 10)

        def on_image(self, msg):
            self.count += 1
            if self.count == 1:
                print('ready', flush=True)
                if sys.argv[1] == 'stuck':
                    time.sleep(60.0)


    run(Sink)
    print('clean exit', flush=True)
""")


class Flood:
    """Publish one HD720 rgb8 Image after another from a thread, in a private context."""

    def __init__(self, context):
        self._node = rclpy.create_node('image_flood', context=context)
        self._pub = self._node.create_publisher(Image, 'flood', 10)
        self._msg = Image(height=720, width=1280, encoding='rgb8', step=1280 * 3,
                          data=bytes(720 * 1280 * 3))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)

    def _loop(self):
        while not self._stop.is_set():
            self._pub.publish(self._msg)
            time.sleep(0.002)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(5.0)
        self._node.destroy_node()


def start_sinks(mode='normal', count=1):
    """
    Start ``count`` node processes at once and wait until each has taken its first image.

    Lines before 'ready' are allowed: Fast DDS logs "Failed init_port ...:
    open_and_lock_file failed" when another process on the machine holds the shared-memory
    port it tried first, and goes on with the next one (eProsima/Fast-DDS#1095); with two
    test workers that happens. A process ending before 'ready' fails the test.
    """
    procs = [subprocess.Popen([sys.executable, '-c', NODE_SCRIPT, mode], text=True,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
             for _ in range(count)]
    for proc in procs:
        before = []
        for line in proc.stdout:
            if line.strip() == 'ready':
                break
            before.append(line)
        else:
            for p in procs:
                p.kill()
            pytest.fail(f'node did not start: {"".join(before)}')
    return procs


def stop_and_collect(proc, timeout_s=10.0):
    """Return (exit code, output) once ``proc`` has ended; fail if it hangs."""
    try:
        out, _ = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, _ = proc.communicate()
        pytest.fail(f'node still running {timeout_s} s after the signal: {out[-2000:]}')
    return proc.returncode, out


@pytest.mark.parametrize('signum', [subprocess.signal.SIGINT, subprocess.signal.SIGTERM])
def test_stop_signal_under_image_flood_exits_zero(context, signum):
    # Eight stops, two processes at a time (each start is mostly discovery, not CPU), each
    # stopped after its own random delay while both take the flood.
    rng = random.Random(20261121)
    with Flood(context):
        for attempt in range(0, 8, 2):
            procs = start_sinks(count=2)
            elapsed = 0.0
            for proc, delay in zip(procs, sorted(rng.uniform(0.0, 0.5) for _ in procs)):
                time.sleep(delay - elapsed)
                elapsed = delay
                proc.send_signal(signum)
            for index, proc in enumerate(procs):
                code, out = stop_and_collect(proc)
                assert code == 0, f'attempt {attempt + index}: exit code {code}\n{out[-3000:]}'
                assert 'clean exit' in out


def test_second_sigint_stops_a_node_stuck_in_a_callback(context):
    with Flood(context):
        proc, = start_sinks(mode='stuck')
        proc.send_signal(subprocess.signal.SIGINT)
        time.sleep(1.0)
        # The first signal waits for the callback to return (60 s here)...
        assert proc.poll() is None
        # ...the second one does not.
        proc.send_signal(subprocess.signal.SIGINT)
        code, out = stop_and_collect(proc)
        assert code == 0, out[-3000:]
