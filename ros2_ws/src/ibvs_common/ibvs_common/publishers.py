"""
Who publishes on a topic against who is expected to: the rule, without ROS.

Each input and each command topic of the graph has the publishers the graph expects: the
simulator or the arm's driver on /joint_states, the feedback node on /ibvs/q_feedback, the
joint controller alone on its command topic. A second one (a forgotten ``ros2 topic pub``,
a teleop node, a second graph on the domain) moves the arm or corrupts the loop with
messages that are each well formed, so no input check sees it. :func:`newcomers` compares
what the graph shows (rclpy's ``Node.get_publishers_info_by_topic``: each
``TopicEndpointInfo`` has ``node_name``, ``node_namespace`` and ``endpoint_gid``; read by
:func:`from_infos`) with what is expected, by node name: a node's name is what an operator
can find and stop, and a publisher restarted under the same name (a simulator, a driver)
is the same one again. :class:`ExpectedPublishers` holds one topic's expectation, and
learns it from the first publishers seen when only their number is known (the name of a
cell's driver is not ours to know).

A node that publishes on the topic itself (the joint controller on its command topic) has
one entry there under its own name: ``own`` drops it. rclpy (Jazzy) gives no gid of its own
publishers, so the entry is known by the node's name; a stranger under the same name is one
entry too many, and still named.

An entry whose node the graph does not know (rmw_dds_common's ``_NODE_NAME_UNKNOWN_``: a
writer whose participant's node list has not come yet, or has gone while the writer is still
listed, as a destroyed context's can be for seconds) is left out: it can be neither named
nor stopped by name, and every ROS tool that publishes (rclpy, rclcpp, ``ros2 topic pub``)
has a node. A bare DDS writer is therefore not seen (a known limit).
"""

from collections import Counter
from collections.abc import Iterable, Mapping
from typing import Any, NamedTuple

#: The name rmw gives an endpoint whose node is not known, with the namespace
#: ``_NODE_NAMESPACE_UNKNOWN_`` (rmw_dds_common 014b736
#: ``rmw_dds_common/src/graph_cache.cpp``, ``__get_entities_info_by_topic``).
UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'


class Publisher(NamedTuple):
    """One publisher seen on a topic: its node's fully qualified name and its gid."""

    node: str
    gid: tuple[int, ...] = ()

    def __str__(self) -> str:
        """Return the node's name: what the operator looks for."""
        return self.node

    @property
    def named(self) -> bool:
        """Return whether the graph knows its node (module docstring)."""
        return not self.node.endswith('/' + UNKNOWN_NODE)


def node_name(name: str, namespace: str = '/') -> str:
    """Return a node's fully qualified name: ``/ns/name``, ``/name`` in the root namespace."""
    return f'{namespace.rstrip("/")}/{name}'


def from_infos(infos: Iterable[Any]) -> list[Publisher]:
    """
    Return the publishers of rclpy's TopicEndpointInfo list, in a stable order.

    Each info needs ``node_name``, ``node_namespace`` and ``endpoint_gid`` (a sequence of
    ints); sorted by node name and gid, so that what is named does not depend on the order
    the graph returned them in.
    """
    return sorted(Publisher(node_name(i.node_name, i.node_namespace),
                            tuple(int(b) for b in i.endpoint_gid)) for i in infos)


def newcomers(observed: Iterable[Publisher], expected: int | Iterable[str] | Mapping[str, int],
              own: str | None = None) -> list[Publisher]:
    """
    Return the publishers of ``observed`` that are not expected, in ``observed``'s order.

    Parameters
    ----------
    observed : iterable of Publisher
        What the graph shows on the topic (:func:`from_infos`).
    expected : int, iterable of str, or mapping of str to int
        The publishers the topic is to have besides ``own``: their node names (a name
        given twice, or mapped to 2, is expected twice), or only how many. With names,
        every entry beyond its name's number is a newcomer; with a number, none are while
        there are at most that many, and every one is when there are more (which are
        the expected ones cannot be told).
    own : str, optional
        The fully qualified name of the node asking, when it publishes on the topic: one
        entry of that name is its own publisher, left out.

    Returns
    -------
    list of Publisher
        The newcomers, empty when the topic has what is expected. An entry of a node the
        graph does not know is never one, nor counted (module docstring).

    """
    others = [p for p in observed if p.named]
    if own is not None:
        mine = next((i for i, p in enumerate(others) if p.node == own), None)
        if mine is not None:
            del others[mine]
    if isinstance(expected, int):
        if expected < 0:
            raise ValueError(f'expected publishers must be >= 0, got {expected}')
        return others if len(others) > expected else []
    room = Counter(expected)
    out = []
    for p in others:
        if room[p.node] > 0:
            room[p.node] -= 1
        else:
            out.append(p)
    return out


class ExpectedPublishers:
    """
    One topic's expected publishers, and its newcomers at each look.

    Parameters
    ----------
    expected : int or iterable of str
        The node names expected (fixed), or how many (then the first ones seen, at most
        that many together, are taken as the expected ones, and for good: a publisher of
        another name that comes after one that left is a newcomer all the same).
    own : str, optional
        The asking node's name, when it publishes on the topic itself (:func:`newcomers`).

    """

    def __init__(self, expected: int | Iterable[str] = 1, own: str | None = None) -> None:
        """Take the expectation; nothing seen yet."""
        self.learns = isinstance(expected, int)
        if self.learns and expected < 0:
            raise ValueError(f'expected publishers must be >= 0, got {expected}')
        #: The names taken as expected (given, or learned so far).
        self.known: Counter = Counter() if self.learns else Counter(expected)
        self.count = expected if self.learns else sum(self.known.values())
        self.own = own

    @property
    def settled(self) -> bool:
        """Return whether every expected publisher is known (given, or seen)."""
        return sum(self.known.values()) == self.count

    def look(self, observed: Iterable[Publisher]) -> list[Publisher]:
        """Return the newcomers among ``observed`` (learning the expected ones first)."""
        found = newcomers(observed, self.known, self.own)
        if self.learns and found and sum(self.known.values()) + len(found) <= self.count:
            self.known.update(p.node for p in found)
            return []
        return found


def describe(topic: str, found: Iterable[Publisher]) -> str:
    """Return the words for ``found`` on ``topic``: 'second publisher on T: /a, /b'."""
    return f'second publisher on {topic}: {", ".join(str(p) for p in found)}'
