"""
The node graph in one place: nodes, processes, remappings, the readers of step 0, start order.

:data:`GRAPH` describes the graph of docs/design.md §1; everything that needs to know the
graph reads it: the runner's process plan (:func:`process_plan`: :meth:`Graph.processes`
with :meth:`Graph.remaps`) and its start handshake (:meth:`Graph.step0_readers`),
``compose``'s node table (:meth:`Graph.compose_table`), and the table of docs/design.md
§1 (:func:`.graph_topics.node_table`, checked against the file by a test). Adding a node
to the graph is one :class:`Node` entry here plus its module (and its executable in its
package's ``setup.py``, which ``ros2 run`` needs; a test checks that each node has one),
and the records of what it opens regenerated (:mod:`.graph_topics`).
"""

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from ibvs_common import contract, shared_params

from .supervision import ProcessSpec

#: sim_node camera_topics 'zed_wrapper': the ZED wrapper's names, which the camera's readers
#: take by remapping alone, as on a real cell.
ZED_TOPICS = {contract.LEFT_IMAGE: contract.ZED_LEFT_IMAGE,
              contract.RIGHT_IMAGE: contract.ZED_RIGHT_IMAGE,
              contract.LEFT_INFO: contract.ZED_LEFT_INFO,
              contract.RIGHT_INFO: contract.ZED_RIGHT_INFO}
#: The camera_info part of :data:`ZED_TOPICS`, for the nodes that read no image.
ZED_INFO = {contract.LEFT_INFO: contract.ZED_LEFT_INFO,
            contract.RIGHT_INFO: contract.ZED_RIGHT_INFO}
#: The feature and feedback nodes (and the viewers' node) need the joint state of each
#: frame's stamp only: from /stereo/joint_states they get those (30 a second) instead of
#: being woken by every physics step's /joint_states (1000 a second), which the lockstep
#: would wait for.
FRAME_STATES = {contract.JOINT_STATES: contract.FRAME_JOINT_STATES}


@dataclass(frozen=True)
class Node:
    """
    One node of the graph: its executable, its class, its process and its topics.

    ``name`` is the node's name and its executable's (``ros2 run package name``);
    ``module``.``cls`` is its class (what ``compose`` builds). ``process``: the name of the
    process it shares with the other nodes of that name (``ros2 run ibvs_bringup compose
    ...``, in the order of the description), '' for a process of its own. ``remaps``: the
    remappings every run gives it; ``zed_remaps``: those added when the simulator publishes
    the ZED wrapper's names (``camera_topics: zed_wrapper``). ``step0_reads``: the topics of
    step 0 it must be subscribed to before the simulator publishes them (volatile: a node
    that misses them waits for ever). ``paper``: one of the paper's nodes (the viewers' node
    is not). ``sim_side``: the simulator's, standing in for the cell (the simulator itself,
    and robot_state_node for the driver's robot_state_publisher): a run beside a real cell
    (``ibvs cell``) leaves these out (:meth:`Graph.cell_nodes`). The ``doc_*`` fields are
    its row of docs/design.md §1 (:func:`.graph_topics.node_table`), whose reads and writes
    are what the node records opening.
    """

    name: str
    package: str
    module: str
    cls: str
    process: str = ''
    remaps: dict = field(default_factory=dict)
    zed_remaps: dict = field(default_factory=dict)
    step0_reads: tuple = ()
    paper: bool = True
    sim_side: bool = False
    doc_module: str = ''
    doc_rate: str = ''


@dataclass(frozen=True)
class Graph:
    """
    The nodes of a run in start order, the simulator among them.

    ``step0_topics``: what the simulator publishes at step 0, in the order the runner
    counts their readers. ``host``: the (package, executable) that holds several nodes in
    one process.
    """

    nodes: tuple
    simulator: str
    step0_topics: tuple
    host: tuple = ('ibvs_bringup', 'compose')

    def node(self, name: str) -> Node:
        """Return the :class:`Node` called ``name``."""
        return next(n for n in self.nodes if n.name == name)

    def paper_nodes(self) -> tuple[tuple[str, str], ...]:
        """Return (package, executable) of the paper's nodes, in start order."""
        return tuple((n.package, n.name) for n in self.nodes if n.paper)

    def processes(self) -> tuple[ProcessSpec, ...]:
        """
        Return the processes of a run (:class:`~.supervision.ProcessSpec`), in start order.

        A node of its own process starts where it stands in :attr:`nodes`; the nodes that
        share a process start together (``compose``, in their order) where the last of them
        stands. The simulator's process must come last, so that every subscriber is up
        before the first /joint_states.
        """
        out = []
        for i, n in enumerate(self.nodes):
            if not n.process:
                out.append(ProcessSpec(n.package, n.name))
            elif all(m.process != n.process for m in self.nodes[i + 1:]):
                members = self.shared(n.process)
                out.append(ProcessSpec(*self.host, members, members, n.process))
        if self.simulator not in out[-1].nodes:
            raise ValueError(f'the simulator {self.simulator} must start last')
        return tuple(out)

    def separate(self) -> 'Graph':
        """
        Return this graph with every node in a process of its own, as ``ros2 run`` starts them.

        The same nodes, remappings and start order; only the sharing of processes goes (and
        with it the direct delivery of messages between the nodes of one process,
        :mod:`ibvs_common.intra_process`): every message crosses DDS. A run of each must give
        the same streams (tests/test_composed_equivalence.py).
        """
        return replace(self, nodes=tuple(replace(n, process='') for n in self.nodes))

    def sim_side(self) -> tuple[str, ...]:
        """Return the names of the simulator's nodes (``Node.sim_side``), in start order."""
        return tuple(n.name for n in self.nodes if n.sim_side)

    def cell_nodes(self) -> tuple['Node', ...]:
        """Return the nodes that run beside a real cell: all but the simulator's."""
        return tuple(n for n in self.nodes if not n.sim_side)

    def shared(self, process: str) -> tuple[str, ...]:
        """Return the names of the nodes of the shared process ``process``, in order."""
        return tuple(n.name for n in self.nodes if n.process == process)

    def remaps(self, zed: bool = False, frame_states: bool = True
               ) -> dict[str, dict[str, str]]:
        """
        Return {node: {topic: remapped}}, with the ZED wrapper's names if ``zed``.

        ``frame_states`` False (free-running: the simulator publishes no
        /stereo/joint_states, as a real cell has none) leaves out :data:`FRAME_STATES`:
        those nodes read /joint_states and pair each frame by interpolation.
        """
        out = {n.name: {t: r for t, r in {**n.remaps, **(n.zed_remaps if zed else {})}.items()
                        if frame_states or FRAME_STATES.get(t) != r}
               for n in self.nodes}
        return {name: m for name, m in out.items() if m}

    def step0_readers(self, frame_states: bool = True) -> dict[str, tuple[str, ...]]:
        """
        Return {topic: nodes that must read it} for each topic of step 0.

        ``frame_states`` False: the readers of /stereo/joint_states read /joint_states
        (:meth:`remaps`) and /stereo/joint_states has none.
        """
        def reads(n, t):
            if frame_states:
                return t in n.step0_reads
            if t == contract.FRAME_JOINT_STATES:
                return False
            return t in n.step0_reads or (t == contract.JOINT_STATES
                                          and contract.FRAME_JOINT_STATES in n.step0_reads)
        return {t: tuple(n.name for n in self.nodes if reads(n, t)) for t in self.step0_topics}

    def compose_table(self) -> dict[str, tuple[str, str]]:
        """Return {node: (module, class)}: the nodes ``compose`` can hold."""
        return {n.name: (n.module, n.cls) for n in self.nodes}


#: The graph of docs/design.md §1, in start order. The paper's nodes run in one process
#: (``lockstep``, ibvs_bringup.compose), as gazebo_ros2_control runs the controllers inside
#: the simulator and as a component container holds a camera's pipeline: the lockstep's two
#: messages per physics step and a frame's images, features and q_feedback then pass as
#: objects (ibvs_common.intra_process; DDS still carries them to any reader in another
#: process), and at the paper's latency of 0 the chain render -> detection -> feedback ->
#: joint loop is serial anyway, so the hops DDS would add are pure cost. Each node keeps its
#: executable for ``ros2 run`` and a real cell, where the joint controller and the vision
#: run without the simulator. ibvs_viz's viz_node is not one of the paper's nodes: it gives
#: viewers (RViz, Foxglove) and the bag what a cell lacks (tool, camera and target frames on
#: /tf_static, /ibvs/markers), from the frames' joint states, so nothing in the lockstep
#: waits for it once it runs; it runs on its own, and the simulator's first step waits for
#: its subscriptions like any reader of step 0, so that its markers start at t = 0 in the
#: bag. ibvs_sim's robot_state_node is the simulated cell's robot_state_publisher
#: (abb_ros2's bringup starts one on a cell): the only publisher of /robot_description and
#: of the arm's link frames (ABB's, ibvs_model.abb_urdf), from the frames' joint states like
#: the viewers' node (its step-0 wait: /tf from t = 0); it is the simulator's
#: (``sim_side``), so it does not run beside a real cell, whose driver publishes those.
GRAPH = Graph(
    nodes=(
        Node('viz_node', 'ibvs_viz', 'ibvs_viz.viz_node', 'VizNode',
             remaps=FRAME_STATES, zed_remaps=ZED_INFO, paper=False,
             step0_reads=(contract.FRAME_JOINT_STATES, contract.LEFT_INFO,
                          contract.RIGHT_INFO),
             doc_module="pure: `ibvs_viz.scene`; not one of the paper's nodes, §12",
             doc_rate='one per frame (/tf_static: camera, tool, target frames); nothing '
                      'waits for it'),
        Node('robot_state_node', 'ibvs_sim', 'ibvs_sim.robot_state_node', 'RobotStateNode',
             remaps=FRAME_STATES, paper=False, sim_side=True,
             step0_reads=(contract.FRAME_JOINT_STATES,),
             doc_module="pure: `ibvs_model.abb_urdf`; the simulator's stand-in for "
                        'robot_state_publisher, §12',
             doc_rate="/robot_description (ABB's frames) once; /tf (base_link -> "
                      'link_1..link_6) one per frame; /tf_static (base, flange, tool0) '
                      'once; nothing waits for it'),
        Node('feature_node', 'ibvs_vision', 'ibvs_vision.feature_node', 'FeatureNode',
             process='lockstep', remaps=FRAME_STATES, zed_remaps=ZED_TOPICS,
             step0_reads=(contract.FRAME_JOINT_STATES, contract.LEFT_INFO,
                          contract.RIGHT_INFO),
             doc_module='pure: `detector`, `blend`',
             doc_rate='one message each per stereo frame'),
        Node('adaptive_feedback_node', 'ibvs_control', 'ibvs_control.adaptive_feedback_node',
             'AdaptiveFeedbackNode', process='lockstep', remaps=FRAME_STATES, zed_remaps=ZED_INFO,
             step0_reads=(contract.FRAME_JOINT_STATES, contract.LEFT_INFO,
                          contract.RIGHT_INFO),
             doc_module='pure: `controllers.AdaptiveFeedback`',
             doc_rate='one per frame'),
        Node('feedforward_node', 'ibvs_control', 'ibvs_control.feedforward_node',
             'FeedforwardNode', process='lockstep', step0_reads=(contract.JOINT_STATES,),
             doc_module='pure: `controllers.Feedforward`',
             doc_rate='once, then it unsubscribes'),
        Node('joint_controller_node', 'ibvs_control', 'ibvs_control.joint_controller_node',
             'JointControllerNode', process='lockstep', step0_reads=(contract.JOINT_STATES,),
             zed_remaps=ZED_INFO,
             doc_module='pure: `controllers.JointLoop`, `dynamics.RobotDynamics`',
             doc_rate='one per /joint_states'),
        Node('sim_node', 'ibvs_sim', 'ibvs_sim.sim_node', 'SimNode', process='lockstep',
             sim_side=True,
             doc_module='core: `ibvs_sim.simulator.Simulator`, `ibvs_sim.world.World`',
             doc_rate='one step per effort command (lockstep, §4); /joint_states every '
                      'physics step (`physics_rate_hz`, 1 kHz; free-running '
                      '`joint_state_rate_hz`, 250 Hz, §4.1); /ibvs/tool_path (the poses of '
                      'every step), /ibvs/joint_path (the /joint_states of every step) and '
                      '/clock: `clock_rate_hz` (10 Hz); /stereo/joint_states: every camera '
                      'frame (lockstep only); images and camera_info: every camera frame '
                      '(`camera_rate_hz`, 30 Hz); /stereo/pose: once'),
    ),
    simulator='sim_node',
    # The runner's recorder and monitor also read /ibvs/tool_path, and the recorder
    # /ibvs/joint_path (not /joint_states, which does not leave the simulator's process),
    # in the runner's own process.
    step0_topics=(contract.JOINT_STATES, contract.FRAME_JOINT_STATES, contract.LEFT_INFO,
                  contract.RIGHT_INFO, contract.TOOL_PATH, contract.JOINT_PATH),
)


def process_plan(params: Mapping[str, Any], graph: Graph = GRAPH
                 ) -> list[tuple[ProcessSpec, tuple[str, ...]]]:
    """
    Return [(ProcessSpec, its remapping arguments)] of a run with ``params``, in start order.

    The processes and remappings are the graph's (:mod:`ibvs_bringup.graph`), with the ZED
    wrapper's names when the simulator publishes them (``camera_topics: zed_wrapper``). In a
    process of several nodes a remapping names its node (``-r node:topic:=remapped``, the
    ROS 2 syntax of a node-specific rule), so that it leaves the others' topics alone.
    """
    run_remaps = graph.remaps(zed=uses_zed_names(params), frame_states=uses_frame_states(params))
    plan = []
    for spec in graph.processes():
        scope = len(spec.nodes) > 1
        plan.append((spec, tuple(arg for node in spec.nodes
                                 for topic, remapped in run_remaps.get(node, {}).items()
                                 for arg in ('-r', f'{node}:' * scope + f'{topic}:={remapped}'))))
    return plan


def uses_frame_states(params: Mapping[str, Any]) -> bool:
    """
    Whether the simulator of a run with ``params`` publishes /stereo/joint_states.

    In lockstep only (:func:`ibvs_common.shared_params.lockstep`): free-running
    (``command_interface: position``, a real cell's timing) it publishes none, as a real
    cell has none (docs/real_cell.md step 3).
    """
    return shared_params.lockstep(params)


def uses_zed_names(params: Mapping[str, Any]) -> bool:
    """Whether the simulator of a run with ``params`` publishes the ZED wrapper's names."""
    return params.get('camera_topics', 'ibvs') == 'zed_wrapper'
