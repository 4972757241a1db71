"""The graph's one description (ibvs_bringup.graph) and what reads it; nothing is started."""

import dataclasses
import os
from pathlib import Path

from ament_index_python.packages import get_package_prefix
from ibvs_bringup import compose, graph, graph_topics, supervision
from ibvs_bringup.graph import GRAPH, Node
from ibvs_bringup.supervision import ProcessSpec
from ibvs_common import contract
import pytest

#: The paper's nodes, all in the simulator's process (the frame's messages need no DDS
#: there, ibvs_common.intra_process).
LOCKSTEP = ('feature_node', 'adaptive_feedback_node', 'feedforward_node',
            'joint_controller_node', 'sim_node')
FRAME = (f'{contract.JOINT_STATES}:={contract.FRAME_JOINT_STATES}',)


def _remaps(*pairs, node=None):
    return tuple(arg for pair in pairs for arg in ('-r', f'{node}:' * bool(node) + pair))


def test_the_process_plan_scopes_the_remaps_of_a_shared_process_to_their_node():
    plan = graph.process_plan({})
    assert plan == [
        (ProcessSpec('ibvs_viz', 'viz_node'), _remaps(*FRAME)),
        (ProcessSpec('ibvs_sim', 'robot_state_node'), _remaps(*FRAME)),
        (ProcessSpec('ibvs_bringup', 'compose', LOCKSTEP, LOCKSTEP, 'lockstep'),
         _remaps(*FRAME, node='feature_node') + _remaps(*FRAME, node='adaptive_feedback_node')),
    ]
    zed = dict(graph.process_plan({'camera_topics': 'zed_wrapper'}))
    info = (f'{contract.LEFT_INFO}:={contract.ZED_LEFT_INFO}',
            f'{contract.RIGHT_INFO}:={contract.ZED_RIGHT_INFO}')
    images = (f'{contract.LEFT_IMAGE}:={contract.ZED_LEFT_IMAGE}',
              f'{contract.RIGHT_IMAGE}:={contract.ZED_RIGHT_IMAGE}')
    assert zed[ProcessSpec('ibvs_viz', 'viz_node')] == _remaps(*FRAME, *info)
    assert zed[ProcessSpec('ibvs_sim', 'robot_state_node')] == _remaps(*FRAME)
    assert zed[ProcessSpec('ibvs_bringup', 'compose', LOCKSTEP, LOCKSTEP, 'lockstep')] == (
        _remaps(*FRAME, images[0], images[1], *info, node='feature_node')
        + _remaps(*FRAME, *info, node='adaptive_feedback_node')
        # the joint controller watches the camera (its camera_info) in position mode
        + _remaps(*info, node='joint_controller_node'))


def test_free_running_reads_joint_states_as_a_real_cell_does():
    """No /stereo/joint_states free-running: no remapping, /joint_states' readers."""
    info = (f'{contract.LEFT_INFO}:={contract.ZED_LEFT_INFO}',
            f'{contract.RIGHT_INFO}:={contract.ZED_RIGHT_INFO}')
    images = (f'{contract.LEFT_IMAGE}:={contract.ZED_LEFT_IMAGE}',
              f'{contract.RIGHT_IMAGE}:={contract.ZED_RIGHT_IMAGE}')
    plan = dict(graph.process_plan({'camera_topics': 'zed_wrapper',
                                    'command_interface': 'position'}))
    assert plan[ProcessSpec('ibvs_viz', 'viz_node')] == _remaps(*info)
    assert plan[ProcessSpec('ibvs_bringup', 'compose', LOCKSTEP, LOCKSTEP, 'lockstep')] == (
        _remaps(images[0], images[1], *info, node='feature_node')
        + _remaps(*info, node='adaptive_feedback_node')
        + _remaps(*info, node='joint_controller_node'))
    readers = GRAPH.step0_readers(frame_states=False)
    assert readers[contract.JOINT_STATES] == (
        'viz_node', 'robot_state_node', 'feature_node', 'adaptive_feedback_node',
        'feedforward_node', 'joint_controller_node')
    assert plan[ProcessSpec('ibvs_sim', 'robot_state_node')] == ()
    assert readers[contract.FRAME_JOINT_STATES] == ()
    assert {k: v for k, v in readers.items() if k not in (
        contract.JOINT_STATES, contract.FRAME_JOINT_STATES)} == {
        k: v for k, v in GRAPH.step0_readers().items() if k not in (
            contract.JOINT_STATES, contract.FRAME_JOINT_STATES)}
    assert graph.uses_frame_states({}) and graph.uses_frame_states({'command_interface': 'effort'})
    assert not graph.uses_frame_states({'command_interface': 'position'})


def test_the_step0_readers_are_the_runners_of_before():
    assert GRAPH.step0_readers() == {
        contract.JOINT_STATES: ('feedforward_node', 'joint_controller_node'),
        contract.FRAME_JOINT_STATES: ('viz_node', 'robot_state_node', 'feature_node',
                                      'adaptive_feedback_node'),
        contract.LEFT_INFO: ('viz_node', 'feature_node', 'adaptive_feedback_node'),
        contract.RIGHT_INFO: ('viz_node', 'feature_node', 'adaptive_feedback_node'),
        contract.TOOL_PATH: (),
        contract.JOINT_PATH: (),  # the recorder's, in the runner's process
    }
    assert GRAPH.paper_nodes() == (
        ('ibvs_vision', 'feature_node'), ('ibvs_control', 'adaptive_feedback_node'),
        ('ibvs_control', 'feedforward_node'), ('ibvs_control', 'joint_controller_node'),
        ('ibvs_sim', 'sim_node'))


def test_compose_holds_every_node_of_the_graph():
    assert set(compose.NODES) == {n.name for n in GRAPH.nodes}
    assert [c.__name__ for c in compose.node_classes([n.name for n in GRAPH.nodes])] == \
        [n.cls for n in GRAPH.nodes]


def test_every_node_has_its_executable():
    # ros2 run <package> <node>: the console script in the node package's setup.py.
    for n in GRAPH.nodes:
        path = Path(get_package_prefix(n.package)) / 'lib' / n.package / n.name
        assert os.access(path, os.X_OK), f'{n.package} {n.name}: no executable at {path}'


def test_adding_a_node_is_one_entry_of_the_description():
    # A dummy node between the feedback and the lockstep, reading /joint_states at step 0
    # and a remapped camera_info, with no other edit.
    dummy = Node('dummy_node', 'ibvs_dummy', 'ibvs_dummy.dummy_node', 'DummyNode',
                 remaps={contract.LEFT_INFO: '/elsewhere/camera_info'},
                 step0_reads=(contract.JOINT_STATES,))
    # What it opens: the records of ibvs_bringup.graph_topics, one row more.
    opened = graph_topics.opened() + (graph_topics.Opened(
        'dummy_node', 'subscribes', contract.JOINT_STATES, 'sensor_msgs/msg/JointState',
        'RELIABLE', tuple(graph_topics.MODES)),)
    at = [n.name for n in GRAPH.nodes].index('adaptive_feedback_node') + 1
    bigger = dataclasses.replace(GRAPH, nodes=GRAPH.nodes[:at] + (dummy,) + GRAPH.nodes[at:])
    plan = graph.process_plan({}, bigger)
    assert [spec.name for spec, _ in plan] == ['viz_node', 'robot_state_node', 'dummy_node',
                                               'lockstep']
    assert plan[2] == (ProcessSpec('ibvs_dummy', 'dummy_node'),
                       ('-r', f'{contract.LEFT_INFO}:=/elsewhere/camera_info'))
    assert bigger.step0_readers()[contract.JOINT_STATES] == \
        ('dummy_node', 'feedforward_node', 'joint_controller_node')
    assert bigger.compose_table()['dummy_node'] == ('ibvs_dummy.dummy_node', 'DummyNode')
    assert '| `dummy_node` | `ibvs_dummy.dummy_node` | its own | /joint_states; ' \
        f'{contract.LEFT_INFO} read as /elsewhere/camera_info' in \
        graph_topics.node_table(bigger, opened)
    # Into the simulator's process: one field more.
    shared = dataclasses.replace(dummy, process='lockstep')
    bigger = dataclasses.replace(GRAPH, nodes=GRAPH.nodes[:at] + (shared,) + GRAPH.nodes[at:])
    spec, remaps = graph.process_plan({}, bigger)[-1]
    assert spec.nodes == LOCKSTEP[:2] + ('dummy_node',) + LOCKSTEP[2:]
    assert _remaps(f'{contract.LEFT_INFO}:=/elsewhere/camera_info', node='dummy_node') \
        == remaps[-2:]


def test_the_simulators_nodes_do_not_run_beside_a_cell():
    # On a cell the driver's robot_state_publisher publishes the description and the links.
    assert GRAPH.sim_side() == ('robot_state_node', 'sim_node')
    assert GRAPH.simulator in GRAPH.sim_side()
    assert [n.name for n in GRAPH.cell_nodes()] == [
        'viz_node', 'feature_node', 'adaptive_feedback_node', 'feedforward_node',
        'joint_controller_node']


def test_the_simulator_starts_last():
    first = dataclasses.replace(GRAPH.node('sim_node'), process='')
    with pytest.raises(ValueError, match='must start last'):
        dataclasses.replace(GRAPH, nodes=(first,) + GRAPH.nodes[:-1]).processes()
    assert graph.GRAPH.processes()[-1].nodes[-1] == GRAPH.simulator


class _Sub:

    def __init__(self, topic):
        self.topic_name = topic


class _Local:

    def __init__(self, *topics):
        self.subscriptions = [_Sub(t) for t in topics]


def test_the_simulator_waits_for_each_reader_of_step0_and_the_runners_own():
    # Known before any process starts (every process of a run starts at once):
    # the graph's readers of step 0, one subscription each, and the runner's recorder and
    # monitor on the topic as this run names it; at least one on each topic.
    recorder = _Local(contract.JOINT_PATH, contract.TOOL_PATH, contract.ZED_LEFT_INFO,
                      contract.CLOCK)
    counts = supervision.expected_readers([recorder, _Local(contract.TOOL_PATH)],
                                          GRAPH.step0_readers(), graph.ZED_TOPICS)
    assert counts == {contract.JOINT_STATES: 2, contract.FRAME_JOINT_STATES: 4,
                      contract.LEFT_INFO: 4, contract.RIGHT_INFO: 3,
                      contract.TOOL_PATH: 2, contract.JOINT_PATH: 1}
    bare = supervision.expected_readers([], {contract.TOOL_PATH: ()})
    assert bare == {contract.TOOL_PATH: 1}
