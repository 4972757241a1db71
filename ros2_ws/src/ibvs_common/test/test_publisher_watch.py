"""Every node's watch on who publishes on its inputs and commands (kit.PublisherWatch)."""

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from ibvs_common import contract, kit
from ibvs_common.diagnostics import Diagnostics
from ibvs_testing.fixtures import spin_until
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray


class Graph:
    """A node with its Diagnostics, the source of its input, and room for a rogue."""

    def __init__(self, context):
        self.context = context
        self.node = Node('reader', context=context)
        self.diagnostics = Diagnostics(self.node, 'reader')
        self.watch = self.diagnostics.publishers
        self.source = Node('source', context=context)
        self.listener = Node('listener', context=context)
        self.statuses = []
        self.listener.create_subscription(DiagnosticArray, contract.DIAGNOSTICS,
                                          lambda m: self.statuses.extend(m.status), 10)
        self.executor = SingleThreadedExecutor(context=context)
        for n in (self.node, self.source, self.listener):
            self.executor.add_node(n)
        self.rogues = []

    def rogue(self, topic, kind=JointState):
        rogue = Node('rogue', context=self.context)
        rogue.create_publisher(kind, topic, contract.RELIABLE)
        self.rogues.append(rogue)
        return rogue

    def until(self, condition, what):
        spin_until(self.executor, condition, what=what)

    def close(self):
        self.executor.shutdown()
        for n in [self.node, self.source, self.listener, *self.rogues]:
            n.destroy_node()


def test_a_second_publisher_on_an_input_is_named_counted_and_cleared(context):
    graph = Graph(context)
    try:
        kit.subscription(graph.node, JointState, contract.JOINT_STATES, lambda m: None,
                         contract.RELIABLE)
        graph.source.create_publisher(JointState, contract.JOINT_STATES, contract.RELIABLE)
        expected = lambda: graph.watch.expected.get(contract.JOINT_STATES)  # noqa: E731
        graph.until(lambda: expected() is not None and expected().settled,
                    "the source's publisher learned")
        assert graph.watch.look() == {} and 'second_publishers' not in graph.diagnostics.values
        rogue = graph.rogue(contract.JOINT_STATES)
        words = f'second publisher on {contract.JOINT_STATES}: /rogue'
        graph.until(lambda: any(s.level == DiagnosticStatus.WARN and s.message == words
                                for s in graph.statuses), 'the newcomer on /diagnostics')
        assert graph.diagnostics.values['second_publishers'] == words
        assert graph.diagnostics.values['second_publishers_seen'] == 1
        graph.rogues.remove(rogue)
        rogue.destroy_node()
        graph.until(lambda: graph.diagnostics.values['second_publishers'] == 'none',
                    'the newcomer gone')
        assert graph.diagnostics.status().level == DiagnosticStatus.OK
        graph.rogue(contract.JOINT_STATES)  # it comes again: counted again
        graph.until(lambda: graph.diagnostics.values['second_publishers_seen'] == 2,
                    'the second coming counted')
    finally:
        graph.close()


def test_a_topic_opened_later_is_watched_and_a_command_expects_only_its_own(context):
    graph = Graph(context)
    changes = []
    try:
        own = kit.publisher(graph.node, Float64MultiArray, contract.POSITION_COMMANDS,
                            contract.RELIABLE)
        graph.watch.command(own.topic_name, changes.append)
        assert graph.watch.look() == {} and not changes, 'its own publisher is no newcomer'
        kit.subscription(graph.node, JointState, '/late', lambda m: None, contract.RELIABLE)
        graph.rogue(contract.POSITION_COMMANDS, Float64MultiArray)
        graph.until(lambda: changes and contract.POSITION_COMMANDS in changes[-1],
                    'the second commander')
        assert [str(p) for p in changes[-1][contract.POSITION_COMMANDS]] == ['/rogue']
        assert '/late' in graph.watch.expected
        # The node's own level is kept; the alert is said beside its message.
        graph.diagnostics.set_level(DiagnosticStatus.ERROR, 'broken')
        status = graph.diagnostics.status()
        assert status.level == DiagnosticStatus.ERROR
        assert status.message == ('broken; second publisher on '
                                  f'{contract.POSITION_COMMANDS}: /rogue')
    finally:
        graph.close()
