"""
Composed or not, the same run: scenario 1 in the runner's processes and in one process a node.

``ibvs run`` composes the paper's nodes and the simulator into one process, where messages
between them are handed over as objects (:mod:`ibvs_common.intra_process`, rclcpp's rule);
by hand, ``ros2 run`` starts each node in its own process and every message crosses DDS
(:meth:`ibvs_bringup.graph.Graph.separate`). The lockstep makes the run independent of
speed and transport, so both must record the same /ibvs/q_feedback and the same joint
commands (the torque of each physics step, on /ibvs/joint_path) to the bit, stamps
included. A transport that drops, reorders, duplicates or alters a message on either path
breaks the equality.
"""

from pathlib import Path

from ibvs_bringup.graph import GRAPH
from ibvs_common import contract
from ibvs_common.conversions import read_joint_path, stamp_ns
from ibvs_experiments import runner
import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import get_typestore, Stores

SIM_SECONDS = 0.3


def streams(bag_path, end_ns):
    """
    Return {'q_feedback': (stamps, values), 'joint_path': (stamps, q, qd, tau)} of a bag.

    Only what is stamped before ``end_ns``: the run stops asynchronously once sim time
    reaches its end, so how far past it a run goes depends on timing (the analysis too takes
    only the steps before the end, :func:`ibvs_analysis.analysis.analyse_bag`).
    """
    feedback_t, feedback_q, path = [], [], ([], [], [], [])
    with AnyReader([Path(bag_path)],
                   default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        connections = [c for c in reader.connections
                       if c.topic in (contract.Q_FEEDBACK, contract.JOINT_PATH)]
        for conn, _, raw in reader.messages(connections=connections):
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == contract.Q_FEEDBACK:
                feedback_t.append(stamp_ns(msg.header.stamp))
                feedback_q.append(np.asarray(msg.position, dtype=float))
            else:
                for part, values in zip(path, read_joint_path(msg)):
                    part.append(np.asarray(values))
    feedback_t = np.asarray(feedback_t)
    order = np.argsort(feedback_t, kind='stable')
    order = order[feedback_t[order] < end_ns]
    path = tuple(np.concatenate(p) for p in path)
    kept = path[0] < end_ns
    return {'q_feedback': (feedback_t[order], np.asarray(feedback_q)[order]),
            'joint_path': tuple(p[kept] for p in path)}


def run(tmp_path, name, graph):
    result = runner.run_scenario('scenario1', tmp_path / name, duration_s=SIM_SECONDS,
                                 figures=False, progress=lambda line: None, graph=graph)
    return streams(result.bag_path, round(SIM_SECONDS * 1e9))


@pytest.mark.slow
def test_composed_and_separate_processes_give_the_same_streams(tmp_path):
    composed = run(tmp_path, 'composed', GRAPH)
    separate = run(tmp_path, 'separate', GRAPH.separate())
    assert len(GRAPH.processes()) < len(GRAPH.separate().processes()) == len(GRAPH.nodes)
    frames = round(SIM_SECONDS * 30)
    for name in ('q_feedback', 'joint_path'):
        a, b = composed[name], separate[name]
        assert len(a[0]) == (frames if name == 'q_feedback' else round(SIM_SECONDS * 1000)), \
            f'{name}: only {len(a[0])} messages in the composed run'
        for k, (x, y) in enumerate(zip(a, b)):
            assert x.shape == y.shape, f'{name}[{k}]: {x.shape} composed, {y.shape} separate'
            diff = np.flatnonzero(np.any(np.reshape(x != y, (len(x), -1)), axis=1))
            assert diff.size == 0, (f'{name}[{k}] differs at {diff.size} of {len(x)} entries, '
                                    f'first at entry {diff[0]}: {x[diff[0]]} composed, '
                                    f'{y[diff[0]]} separate')
