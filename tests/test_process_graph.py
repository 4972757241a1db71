"""
The installed executables as separate processes, resolved as ``ros2 run`` resolves them.

Asserts the topic graph that ``ros2 node list`` and ``ros2 topic list -t`` (with ``-v``
counts) would show, then a clean shutdown of every process on SIGINT.
"""

import signal
import time

from ibvs_bringup import scenario
from ibvs_bringup.graph import GRAPH
from ibvs_bringup.graph_topics import expected_counts
from ibvs_bringup.supervision import NodeProcess
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor

#: The paper's nodes and the simulator's stand-in for robot_state_publisher.
EXECUTABLES = GRAPH.paper_nodes() + tuple((n.package, n.name) for n in GRAPH.nodes
                                          if n.sim_side and not n.paper)
NODE_NAMES = {name for _, name in EXECUTABLES}

#: topic -> (type, publishers, subscribers): what the nodes record opening (ibvs_bringup.
#: graph_topics, the one source of docs/design.md §1 and §3), as ``ros2 run`` starts them.
OPENED = expected_counts(name for _, name in EXECUTABLES)
EXPECTED = {
    **OPENED,
    # The feedforward node drops its subscription after the first good state: MIN_SUBSCRIBERS.
    '/joint_states': OPENED['/joint_states'][:2] + (None,),
    # rclpy's time source in every node (use_sim_time) reads /clock: MIN_SUBSCRIBERS.
    '/clock': ('rosgraph_msgs/msg/Clock', 1, None),
}
#: Who must read what (subscriber counts of at least these).
MIN_SUBSCRIBERS = {
    '/clock': 4,                  # every node with use_sim_time
    '/joint_states': OPENED['/joint_states'][2] - 1,
}


def _count(endpoints):
    """Return how many nodes of NODE_NAMES are among ``endpoints`` (TopicEndpointInfo)."""
    return len({info.node_name for info in endpoints if info.node_name in NODE_NAMES})


def test_executables_form_the_contract_graph_and_stop_on_sigint(context, installed_workspace,
                                                                tmp_path, proc_tools):
    params = scenario.load_parameters('scenario1')
    params_file = scenario.write_parameters(params, tmp_path / 'params.yaml')
    procs = []
    observer = rclpy.create_node('graph_observer', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(observer)
    try:
        for package, executable in EXECUTABLES:
            procs.append(NodeProcess(package, executable, params_file, tmp_path))
        deadline = time.monotonic() + 90.0
        topics = {}
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.2)
            for p in procs:
                assert p.poll() is None, f'{p.name} exited: {p.log_path.read_text()[-2000:]}'
            topics = dict(observer.get_topic_names_and_types())
            # Counted as the checks below count: this graph's nodes only (a reader left in
            # discovery by an earlier test on this domain must not end the wait early).
            counts_ok = all(
                _count(observer.get_publishers_info_by_topic(t)) >= pubs and
                (subs is None or _count(observer.get_subscriptions_info_by_topic(t)) >= subs)
                for t, (_, pubs, subs) in EXPECTED.items())
            if NODE_NAMES <= set(observer.get_node_names()) and counts_ok:
                break
        assert NODE_NAMES <= set(observer.get_node_names())
        for topic, (type_name, pubs, subs) in EXPECTED.items():
            assert topic in topics, f'{topic} missing from the graph'
            assert topics[topic] == [type_name], f'{topic}: {topics[topic]}'
            # This graph's nodes, each once: a node of an earlier test on this domain, of the
            # same name, stays in DDS discovery until its lease ends (seen under load: 7
            # /diagnostics publishers for 6 nodes). No node opens a topic twice (the kit's
            # records, test_design_graph_table), so nodes count publishers.
            assert _count(observer.get_publishers_info_by_topic(topic)) == pubs, topic
            if subs is not None:
                assert _count(observer.get_subscriptions_info_by_topic(topic)) == subs, topic
        for topic, least in MIN_SUBSCRIBERS.items():
            assert observer.count_subscribers(topic) >= least, topic
        # Clean shutdown on SIGINT: every node exits 0, and nothing is left behind.
        descendants = {p.name: proc_tools.descendants(p.proc.pid) for p in procs}
        for p in procs:
            p.proc.send_signal(signal.SIGINT)
        for p in procs:
            try:
                code = p.proc.wait(20.0)
            except Exception:  # noqa: B902 (report which one hung)
                pytest.fail(f'{p.name} did not stop within 20 s of SIGINT')
            assert code == 0, f'{p.name} exit code {code}: {p.log_path.read_text()[-2000:]}'
        for name, pids in descendants.items():
            assert not [pid for pid in pids if proc_tools.alive(pid)], name
    finally:
        for p in procs:
            p.stop(timeout_s=2.0)
        executor.shutdown()
        observer.destroy_node()
