"""
compose: several nodes of the graph in one process, one executor.

``ros2 run ibvs_bringup compose sim_node joint_controller_node --ros-args ...`` builds the
named nodes in that order and spins them together until SIGINT/SIGTERM
(:func:`ibvs_common.node_main.run`): what an rclcpp component container does, for rclpy
nodes. The ``--ros-args`` (parameter files, ``-p``, ``-r``) apply to every node of the
process; a parameter a node does not declare is ignored by it.

Why. The lockstep passes two messages per physics step between the simulator and the joint
controller. Between two processes such a round trip costs 0.2-0.3 ms on two cores (two
wake-ups, two copies through shared memory); between two nodes of one process, Fast DDS
delivers in the process and the executor runs the answer next: 0.04 ms (measured with
JointState ping-pong, one recorder listening in a third process: 0.10 against 0.22 ms).
``ibvs run`` therefore runs the simulator and the joint controller in one process, as
gazebo_ros2_control runs the controllers inside the simulator; each node still has its own
executable for ``ros2 run`` and for a real cell, where the joint controller runs without the
simulator.
"""

from collections.abc import Sequence
import importlib
import sys

from ibvs_common.node_main import run
import rclpy.utilities

from .graph import GRAPH

#: The nodes this executable can hold: name -> (module, class), every node of the graph.
NODES = GRAPH.compose_table()

USAGE = ('usage: ros2 run ibvs_bringup compose NODE [NODE ...] [--ros-args ...]\n'
         f'  NODE: one of {", ".join(NODES)}, each at most once')


def node_classes(names: Sequence[str]) -> list[type]:
    """Return the node classes of ``names``; ValueError names what is wrong."""
    if not names:
        raise ValueError('no node named')
    unknown = [n for n in names if n not in NODES]
    if unknown:
        raise ValueError(f'unknown node(s) {", ".join(unknown)}')
    if len(set(names)) != len(names):
        raise ValueError('a node named twice')
    return [getattr(importlib.import_module(NODES[n][0]), NODES[n][1]) for n in names]


def main(args: list[str] | None = None) -> None:
    """Run the nodes named on the command line in one process (module docstring)."""
    argv = sys.argv if args is None else args
    names = rclpy.utilities.remove_ros_args(argv)[1:]
    try:
        classes = node_classes(names)
    except ValueError as exc:
        print(f'compose: {exc}\n{USAGE}', file=sys.stderr)
        sys.exit(2)
    run(classes, args=argv)


if __name__ == '__main__':
    main()
