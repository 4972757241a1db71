"""
A node process names the callback it is busy in.

A callback kept busy (a detection of a noisy frame, say) silences every node of its process,
and a stall report would call them all frozen. The watchdog of
``ibvs_common.node_main`` says on /diagnostics which callback runs, and for how long, while
the executor waits for it; here a node's timer callback is made busy on purpose (a test
hook in the test's own node, not a real detection).
"""

import subprocess
import sys
import textwrap
import time

from diagnostic_msgs.msg import DiagnosticArray
from ibvs_common import contract
from ibvs_common.node_main import WATCHDOG
from ibvs_testing.fixtures import spin_until
import rclpy
from rclpy.executors import SingleThreadedExecutor

#: A node process whose timer callback, at its second call, runs busy for 4 s.
NODE_SCRIPT = textwrap.dedent("""
    import time

    from ibvs_common.node_main import run
    from rclpy.node import Node


    class BusySink(Node):
        def __init__(self):
            super().__init__('busy_sink')
            self.calls = 0
            self.create_timer(0.2, self.on_timer)

        def on_timer(self):
            self.calls += 1
            if self.calls == 2:
                print('busy', flush=True)
                self.work(4.0)

        def work(self, seconds):
            end = time.monotonic() + seconds
            while time.monotonic() < end:  # Python bytecode: the GIL passes every 5 ms
                sum(range(1000))


    run(BusySink)
""")


def test_the_watchdog_names_the_busy_callback_while_the_executor_waits(context):
    heard = []
    node = rclpy.create_node('watchdog_listener', context=context)
    node.create_subscription(DiagnosticArray, contract.DIAGNOSTICS,
                             lambda msg: heard.extend(msg.status), 10)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    proc = subprocess.Popen([sys.executable, '-c', NODE_SCRIPT], text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        began = time.monotonic()
        spin_until(executor, lambda: any(s.name == f'busy_sink: {WATCHDOG}' for s in heard),
                   60.0, 'the watchdog of a busy callback')
        status = next(s for s in heard if s.name == f'busy_sink: {WATCHDOG}')
        values = {kv.key: kv.value for kv in status.values}
        assert status.message.startswith('busy in busy_sink BusySink.on_timer for '), status
        assert values['busy_callback'] == 'BusySink.on_timer'
        assert 1.0 <= float(values['busy_s']) < 4.0
        assert values['pid'] == str(proc.pid)
        assert time.monotonic() - began < 60.0
        # Once the call has returned, the watchdog says nothing more.
        spin_until(executor, lambda: time.monotonic() - began > 6.0, 30.0, 'time')
        heard.clear()
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.1)
        assert not [s for s in heard if s.name == f'busy_sink: {WATCHDOG}']
    finally:
        proc.terminate()
        out, _ = proc.communicate(timeout=20)
        executor.shutdown()
        node.destroy_node()
    assert proc.returncode == 0, out
