"""
``ros2 run ibvs_bringup compose NODE ...``: several nodes of the graph in one process.

The runner holds the simulator and the joint controller in one such process (the lockstep
stays in it); these tests check the executable as a user starts it.
"""

import re
import signal
import subprocess
import time

from ibvs_bringup import compose, scenario, supervision
from ibvs_bringup.graph import GRAPH
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor

#: The nodes of the simulator's process in a run.
LOCKSTEP = GRAPH.shared('lockstep')


def test_node_classes_are_checked_before_anything_starts():
    assert [c.__name__ for c in compose.node_classes(['joint_controller_node', 'sim_node'])] \
        == ['JointControllerNode', 'SimNode']
    for names, why in (([], 'no node'), (['sim_node', 'nobody'], 'unknown node(s) nobody'),
                       (['sim_node', 'sim_node'], 'named twice')):
        with pytest.raises(ValueError, match=re.escape(why)):
            compose.node_classes(names)


def test_every_node_of_the_graph_can_be_composed():
    assert set(compose.NODES) == {n.name for n in GRAPH.nodes}
    assert set(LOCKSTEP) <= set(compose.NODES)


def _start(args, tmp_path, name):
    params_file = scenario.write_parameters(scenario.load_parameters('scenario1'),
                                            tmp_path / 'params.yaml')
    spec = supervision.ProcessSpec('ibvs_bringup', 'compose', tuple(args), tuple(args), name)
    return spec.start(params_file, tmp_path, ('-p', 'publish_images:=false'))


def test_composed_nodes_share_a_process_and_stop_on_sigint(context, installed_workspace,
                                                           tmp_path):
    proc = _start(LOCKSTEP, tmp_path, 'lockstep')
    observer = rclpy.create_node('compose_observer', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(observer)
    try:
        deadline = time.monotonic() + 60.0
        while not set(LOCKSTEP) <= set(observer.get_node_names()):
            assert proc.poll() is None, proc.log_path.read_text()[-2000:]
            assert time.monotonic() < deadline, 'the composed nodes never joined the graph'
            executor.spin_once(timeout_sec=0.2)
        # Both nodes, one process: the joint controller answers the simulator's steps.
        deadline = time.monotonic() + 60.0
        while 'starting at t = 0' not in proc.log_path.read_text():
            assert proc.poll() is None, proc.log_path.read_text()[-2000:]
            assert time.monotonic() < deadline, proc.log_path.read_text()[-2000:]
            executor.spin_once(timeout_sec=0.2)
        proc.proc.send_signal(signal.SIGINT)
        assert proc.proc.wait(timeout=30) == 0, proc.log_path.read_text()[-2000:]
    finally:
        proc.stop()
        executor.shutdown()
        observer.destroy_node()


def test_a_bad_parameter_of_one_composed_node_ends_the_process_with_code_2(
        installed_workspace, tmp_path):
    params_file = scenario.write_parameters(scenario.load_parameters('scenario1'),
                                            tmp_path / 'params.yaml')
    cmd = supervision.executable_command('ibvs_bringup', 'compose') + [
        *LOCKSTEP, '--ros-args', '--params-file', str(params_file),
        '-p', 'clock_rate_hz:=-1.0']
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2, done.stdout + done.stderr
    assert 'clock_rate_hz' in done.stdout + done.stderr


def test_an_unknown_node_is_refused_with_the_usage(installed_workspace):
    cmd = supervision.executable_command('ibvs_bringup', 'compose') + ['sim_node', 'nobody']
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert 'unknown node(s) nobody' in done.stderr and 'usage:' in done.stderr
