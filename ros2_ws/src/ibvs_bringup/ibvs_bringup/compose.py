"""
compose: several nodes of the graph in one process, one executor.

``ros2 run ibvs_bringup compose sim_node joint_controller_node --ros-args ...`` builds the
named nodes in that order and spins them together until SIGINT/SIGTERM
(:func:`ibvs_common.node_main.run`): what an rclcpp component container does, for rclpy
nodes. The ``--ros-args`` (parameter files, ``-p``, ``-r``) apply to every node of the
process (a remapping ``-r node:topic:=other`` only to that node); a parameter a node does not
declare is ignored by it, but one that no node of the process declares is refused at start
(:func:`ibvs_common.node_main.check_arguments`; those under ``/**`` in a parameter file
excepted: the graph's file gives every node the parameters of all).

Why. The lockstep passes two messages per physics step between the simulator and the joint
controller, and each camera frame goes simulator -> feature node -> feedback -> joint
controller. Between two processes a message costs two wake-ups and two copies through
shared memory; between two nodes of one process rclpy still serialises it through DDS, so
the nodes pass such messages as objects (:mod:`ibvs_common.intra_process`, delivered by the
spin loop of :func:`ibvs_common.node_main.run`; DDS still carries them to readers in other
processes). ``ibvs run`` therefore runs the paper's five nodes in one process
(:data:`ibvs_bringup.graph.GRAPH`), as gazebo_ros2_control runs the controllers inside the
simulator; each node still has its own executable for ``ros2 run`` and for a real cell,
where the joint controller runs without the simulator.
"""

from collections.abc import Sequence
import importlib
import sys

from ibvs_common.node_main import run
from ibvs_common.process import exit_now
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
    # Every node is destroyed and rclpy shut down. Release the DDS participant now (its
    # peers hear that it left, and do not keep its nodes in their graph until its lease
    # ends), then skip the interpreter's teardown: with PyBullet, EGL, OpenCV and SciPy
    # loaded it is slow, and every run's stop would wait for it.
    rclpy.utilities.get_default_context().destroy()
    exit_now(0)


if __name__ == '__main__':
    main()
