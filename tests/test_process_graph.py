"""
The installed executables as separate processes, resolved as ``ros2 run`` resolves them.

Asserts the topic graph that ``ros2 node list`` and ``ros2 topic list -t`` (with ``-v``
counts) would show, then a clean shutdown of every process on SIGINT.
"""

import signal
import time

from ibvs_bringup import scenario
from ibvs_bringup.graph import GRAPH
from ibvs_bringup.supervision import NodeProcess
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor

NODE_NAMES = {'sim_node', 'feature_node', 'joint_controller_node', 'feedforward_node',
              'adaptive_feedback_node', 'robot_state_node'}
#: The paper's nodes and the simulator's stand-in for robot_state_publisher.
EXECUTABLES = GRAPH.paper_nodes() + tuple((n.package, n.name) for n in GRAPH.nodes
                                          if n.sim_side and not n.paper)

#: topic -> (type, publishers, subscribers): the contract of docs/design.md §3.
EXPECTED = {
    '/clock': ('rosgraph_msgs/msg/Clock', 1, None),
    '/joint_states': ('sensor_msgs/msg/JointState', 1, None),
    '/stereo/left/image_raw': ('sensor_msgs/msg/Image', 1, 1),
    '/stereo/right/image_raw': ('sensor_msgs/msg/Image', 1, 1),
    '/stereo/left/camera_info': ('sensor_msgs/msg/CameraInfo', 1, None),
    '/stereo/right/camera_info': ('sensor_msgs/msg/CameraInfo', 1, None),
    '/stereo/pose': ('geometry_msgs/msg/PoseStamped', 1, None),
    '/ibvs/features': ('geometry_msgs/msg/PolygonStamped', 1, 1),
    '/ibvs/feature_status': ('diagnostic_msgs/msg/DiagnosticArray', 1, 0),
    '/ibvs/feedforward_trajectory': ('trajectory_msgs/msg/JointTrajectory', 1, 1),
    '/ibvs/q_feedback': ('sensor_msgs/msg/JointState', 1, 1),
    '/joint_effort_commands': ('sensor_msgs/msg/JointState', 1, 1),
    '/ibvs/tool_path': ('nav_msgs/msg/Path', 1, 0),
    '/stereo/joint_states': ('sensor_msgs/msg/JointState', 1, 0),
    '/diagnostics': ('diagnostic_msgs/msg/DiagnosticArray', 6, 0),
    # robot_state_node alone (ABB's frames); the viewers' node is not started here
    '/robot_description': ('std_msgs/msg/String', 1, 0),
    '/tf': ('tf2_msgs/msg/TFMessage', 1, 0),
    '/tf_static': ('tf2_msgs/msg/TFMessage', 1, 0),
}
#: Who must read what (subscriber counts of at least these).
MIN_SUBSCRIBERS = {
    '/joint_states': 3,           # feature node, feedforward, joint controller (+ feedback)
    '/stereo/left/camera_info': 1,
    '/stereo/pose': 1,
    '/clock': 4,                  # every node with use_sim_time
}


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
            counts_ok = all(
                observer.count_publishers(t) >= pubs and
                (subs is None or observer.count_subscribers(t) >= subs)
                for t, (_, pubs, subs) in EXPECTED.items())
            if NODE_NAMES <= set(observer.get_node_names()) and counts_ok:
                break
        assert NODE_NAMES <= set(observer.get_node_names())
        for topic, (type_name, pubs, subs) in EXPECTED.items():
            assert topic in topics, f'{topic} missing from the graph'
            assert topics[topic] == [type_name], f'{topic}: {topics[topic]}'
            assert observer.count_publishers(topic) == pubs, topic
            if subs is not None:
                assert observer.count_subscribers(topic) == subs, topic
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
