"""
One bad publisher on the domain does not take the graph down: a /clock with a negative ``sec``.

rclpy's TimeSource raises ``ValueError: Seconds value must not be negative`` inside the
executor for such a message, which would end every node that runs on sim time with exit 1.
The four sim-time nodes run here as their own processes (as the runner starts them), are fed
malformed /clock messages, and must count them on /diagnostics and keep running.
"""

import time

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from ibvs_bringup import scenario
from ibvs_bringup.graph import GRAPH
from ibvs_bringup.supervision import NodeProcess
from ibvs_common import contract
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rosgraph_msgs.msg import Clock

#: The nodes that follow /clock (the simulator publishes it).
SIM_TIME_NODES = [node for node in GRAPH.paper_nodes() if node[1] != 'sim_node']
DEADLINE_S = 90.0


def test_sim_time_nodes_survive_a_negative_clock(context, installed_workspace, tmp_path):
    params_file = scenario.write_parameters(scenario.load_parameters('scenario1'),
                                            tmp_path / 'params.yaml')
    talker = rclpy.create_node('bad_clock', context=context)
    pub = talker.create_publisher(Clock, contract.CLOCK, contract.RELIABLE)
    counted = {}

    def on_diagnostics(msg):
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            counted[status.name.split(':')[0]] = int(
                values.get('rejected[/clock: negative time]', '0'))

    talker.create_subscription(DiagnosticArray, contract.DIAGNOSTICS, on_diagnostics, 50)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(talker)
    procs = [NodeProcess(package, executable, params_file, tmp_path)
             for package, executable in SIM_TIME_NODES]
    names = {executable for _, executable in SIM_TIME_NODES}
    try:
        deadline = time.monotonic() + DEADLINE_S
        while not (names <= {n for n, c in counted.items() if c > 0}):
            assert time.monotonic() < deadline, f'rejections counted so far: {counted}'
            for p in procs:
                assert p.poll() is None, \
                    f'{p.name} exited {p.poll()}: {p.log_path.read_text()[-1500:]}'
            if pub.get_subscription_count() >= len(procs):
                pub.publish(Clock(clock=Time(sec=-1, nanosec=0)))
            executor.spin_once(timeout_sec=0.1)
        for p in procs:
            assert p.poll() is None, f'{p.name} exited {p.poll()}'
            assert p.stop() == 0, f'{p.name}: {p.log_path.read_text()[-1500:]}'
    finally:
        for p in procs:
            p.stop(timeout_s=2.0)
        executor.shutdown()
        talker.destroy_node()
