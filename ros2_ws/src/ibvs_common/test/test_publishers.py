"""Who publishes on a topic against who is expected to (ibvs_common.publishers), pure."""

from types import SimpleNamespace

from ibvs_common.publishers import (describe, ExpectedPublishers, from_infos, newcomers,
                                    node_name, Publisher)
import pytest

SIM = Publisher('/sim_node', (1,))
ROGUE = Publisher('/rogue', (2,))
ME = Publisher('/joint_controller_node', (3,))


def info(name, namespace='/', gid=(0,)):
    """Return a TopicEndpointInfo as rclpy gives it (only the fields the rule reads)."""
    return SimpleNamespace(node_name=name, node_namespace=namespace, endpoint_gid=list(gid))


def test_the_graphs_endpoint_infos_are_read_by_fully_qualified_name_in_a_stable_order():
    found = from_infos([info('zed_node', '/zed', (9, 1)), info('sim_node', '/', (4,)),
                        info('sim_node', '/', (2,))])
    assert found == [Publisher('/sim_node', (2,)), Publisher('/sim_node', (4,)),
                     Publisher('/zed/zed_node', (9, 1))]
    assert node_name('x', '/a/b/') == '/a/b/x' and str(found[2]) == '/zed/zed_node'


def test_by_name_every_entry_beyond_its_names_number_is_a_newcomer():
    assert newcomers([SIM], ['/sim_node']) == []
    assert newcomers([SIM, ROGUE], ['/sim_node']) == [ROGUE]
    assert newcomers([ROGUE], ['/sim_node']) == [ROGUE]
    twin = Publisher('/sim_node', (7,))  # the same name twice: one too many
    assert newcomers([SIM, twin], ['/sim_node']) == [twin]
    assert newcomers([SIM, twin], {'/sim_node': 2}) == []
    assert newcomers([], ['/sim_node']) == []  # one missing is not a newcomer


def test_by_count_none_is_named_until_there_are_too_many_then_all_are():
    assert newcomers([SIM], 1) == []
    assert newcomers([SIM, ROGUE], 1) == [SIM, ROGUE]  # which one is ours cannot be told
    assert newcomers([SIM, ROGUE], 2) == []
    with pytest.raises(ValueError, match='>= 0'):
        newcomers([SIM], -1)


def test_the_asking_nodes_own_entry_is_left_out_once():
    assert newcomers([ME], 0, own=ME.node) == []
    assert newcomers([ME, ROGUE], 0, own=ME.node) == [ROGUE]
    impostor = Publisher(ME.node, (8,))  # a stranger under our name is one entry too many
    assert newcomers([ME, impostor], 0, own=ME.node) == [impostor]
    assert newcomers([ROGUE], 0, own=ME.node) == [ROGUE]  # ours not there (yet)


def test_a_count_is_learned_from_the_first_publishers_seen_and_kept():
    topic = ExpectedPublishers(1)
    assert topic.look([]) == [] and not topic.settled  # nobody yet: nothing learned
    assert topic.look([SIM]) == [] and topic.known == {'/sim_node': 1} and topic.settled
    assert topic.look([SIM, ROGUE]) == [ROGUE]
    assert topic.look([SIM]) == []
    assert topic.look([ROGUE]) == [ROGUE], 'a stranger after ours left is still a stranger'
    assert topic.look([Publisher('/sim_node', (5,))]) == [], 'ours restarted (a new gid)'


def test_two_at_the_first_look_are_both_named_until_one_is_gone():
    topic = ExpectedPublishers(1)
    assert topic.look([SIM, ROGUE]) == [SIM, ROGUE] and not topic.known
    assert topic.look([SIM]) == [] and topic.known == {'/sim_node': 1}


def test_given_names_are_not_learned_and_a_command_topic_expects_only_its_own():
    topic = ExpectedPublishers(['/sim_node'])
    assert topic.look([ROGUE]) == [ROGUE] and topic.known == {'/sim_node': 1}
    command = ExpectedPublishers(0, own=ME.node)
    assert topic.settled and command.settled
    assert command.look([ME]) == [] and command.look([ME, ROGUE]) == [ROGUE]
    assert command.look([ME]) == []
    with pytest.raises(ValueError, match='>= 0'):
        ExpectedPublishers(-1)


def test_an_endpoint_of_a_node_the_graph_does_not_know_is_left_out():
    """Discovery's placeholder, or a gone node's writer still listed: never named, learned."""
    ghost = from_infos([info('_NODE_NAME_UNKNOWN_', '_NODE_NAMESPACE_UNKNOWN_', (6,))])[0]
    assert not ghost.named and SIM.named
    assert newcomers([SIM, ghost], ['/sim_node']) == [] and newcomers([ghost], 0) == []
    topic = ExpectedPublishers(1)
    assert topic.look([ghost]) == [] and not topic.settled
    assert topic.look([ghost, SIM]) == [] and topic.known == {'/sim_node': 1}


def test_the_words_name_the_topic_and_each_node():
    assert describe('/joint_states', [ROGUE, SIM]) == \
        'second publisher on /joint_states: /rogue, /sim_node'
