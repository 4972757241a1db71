"""
The fuzz harness: one node in a private Context, a driver, the three checks of a case.

The driver publishes on every topic the node subscribes; the checks are survival, counting
and recovery.

A node's subscriptions are found from the node itself (``node.subscriptions``), and each
one's callback is wrapped to count the messages handled, so that a case waits for the
node to have *handled* its message (a condition, not a wall-clock wait). The driver gets a
publisher of the subscription's own type and QoS on each topic.

Per case:

- **crash**: an exception escaped the node's callback (the executor re-raises it);
- **accepted silently**: the node's rejection count for the topic the case names
  (``rejected[<topic>: <reason>]`` on /diagnostics) grew by less than the number of bad
  messages the case sent;
- **stuck**: after the case the node did not act on the next valid input (the rig's
  :meth:`Rig.valid_step`) before a deadline that only guards a hang.

After all its cases, a rig that records the node's outputs checks that every one was
finite (:meth:`Rig.published_finite`).
"""

from collections import Counter
from dataclasses import dataclass, field
import time
from typing import Callable, List, Tuple

from builtin_interfaces.msg import Time
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

#: Deadline (s) of one wait on a condition: only a guard against a hang.
DEADLINE_S = 10.0
#: Where the per-node tables go for the end of the pytest session (tests/fuzz/conftest.py).
TABLES: List[str] = []


@dataclass
class Case:
    """Bad messages of one class, sent in order; ``counted`` of them must be rejected."""

    name: str
    topic: str
    messages: List[Tuple[str, object]]
    counted: int = None

    def __post_init__(self):
        """Count every message sent to ``topic`` unless told otherwise."""
        if self.counted is None:
            self.counted = sum(1 for topic, _ in self.messages if topic == self.topic)


@dataclass
class Outcome:
    """What became of one case."""

    case: Case
    crash: str = ''
    silent: bool = False
    stuck: bool = False
    rejected: Counter = field(default_factory=Counter)


def stamp(sec, nanosec=0):
    """Return a builtin_interfaces/Time, sec and nanosec as given (malformed ones too)."""
    return Time(sec=int(sec), nanosec=int(nanosec))


class Rig:
    """
    A node under fuzz, with a driver node and an executor of ``context``.

    ``diagnostics`` is the node's :class:`ibvs_common.diagnostics.Diagnostics`. Subclasses
    give :meth:`setup` (what the node needs before it acts) and :meth:`valid_step` (one
    valid input; returns a predicate that holds once the node acted on it).
    """

    def __init__(self, context, node, diagnostics):
        """Wrap the node's subscriptions, create the driver's publishers and the executor."""
        self.node = node
        self.diagnostics = diagnostics
        self.driver = Node('fuzz_driver', context=context)
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(node)
        self.executor.add_node(self.driver)
        self.handled = Counter()
        self.pubs = {}
        for sub in node.subscriptions:
            topic = sub.topic_name
            callback = sub.callback

            def counted(msg, topic=topic, callback=callback):
                try:
                    return callback(msg)
                finally:
                    self.handled[topic] += 1

            sub.callback = counted
            self.pubs[topic] = self.driver.create_publisher(sub.msg_type, topic,
                                                            sub.qos_profile)
        self.spin_until(lambda: all(p.get_subscription_count() > 0
                                    for p in self.pubs.values()), 'discovery')

    @property
    def topics(self):
        """Return every topic the node subscribes."""
        return sorted(self.pubs)

    def spin_until(self, condition, what='condition', deadline_s=DEADLINE_S):
        """Spin until ``condition()``; return False at the deadline (exceptions propagate)."""
        end = time.monotonic() + deadline_s
        while not condition():
            if time.monotonic() > end:
                return False
            self.executor.spin_once(timeout_sec=0.02)
        return True

    def deliver(self, topic, msg):
        """Publish ``msg`` on ``topic`` and spin until the node has handled it."""
        before = self.handled[topic]
        self.pubs[topic].publish(msg)
        assert self.spin_until(lambda: self.handled[topic] > before, f'{topic} handled'), \
            f'the node never handled a message on {topic}'

    def rejected(self, topic):
        """Return the rejections counted for ``topic``, all reasons, as /diagnostics says."""
        prefix = f'rejected[{topic}: '
        return sum(int(kv.value) for kv in self.diagnostics.status().values
                   if kv.key.startswith(prefix))

    def reasons(self, topic):
        """Return the ``rejected[<topic>: <reason>]`` counts of ``topic`` by reason."""
        prefix = f'rejected[{topic}: '
        return Counter({kv.key[len(prefix):-1]: int(kv.value)
                        for kv in self.diagnostics.status().values
                        if kv.key.startswith(prefix)})

    def setup(self):
        """Send what the node needs before it acts on valid input (subclasses)."""

    def valid_step(self) -> Callable[[], bool]:
        """Send one valid input; return a predicate true once the node acted on it."""
        raise NotImplementedError

    def published_finite(self):
        """Return whether every output the rig recorded is finite (subclasses that record)."""
        return True

    def recovered(self):
        """Return whether the node acts on the next valid input."""
        return self.spin_until(self.valid_step(), 'the node acting on valid input')

    def run_case(self, case):
        """Send ``case``; return its :class:`Outcome` (the three checks of the docstring)."""
        outcome = Outcome(case)
        before = self.reasons(case.topic)
        try:
            for topic, msg in case.messages:
                self.deliver(topic, msg)
        except Exception as exc:  # what escaped a callback: the node would have died
            outcome.crash = f'{type(exc).__name__}: {exc}'
            return outcome
        outcome.rejected = self.reasons(case.topic) - before
        outcome.silent = sum(outcome.rejected.values()) < case.counted
        try:
            outcome.stuck = not self.recovered()
        except Exception as exc:
            outcome.crash = f'after the case, {type(exc).__name__}: {exc}'
        return outcome

    def close(self):
        """Shut the executor down and destroy both nodes."""
        self.executor.shutdown()
        self.driver.destroy_node()
        self.node.destroy_node()


def table(name, rig, outcomes):
    """Return the node's row of the fuzz table and the lines of each failed case."""
    crashes = [o for o in outcomes if o.crash]
    stuck = [o for o in outcomes if o.stuck]
    silent = [o for o in outcomes if o.silent]
    covered = {o.case.topic for o in outcomes}
    lines = [f'{name:32s} {len(outcomes):5d} {len(crashes):7d} {len(stuck):5d} '
             f'{len(silent):17d}   topics {len(covered)}/{len(rig.topics)}']
    for o in crashes + stuck + silent:
        lines.append(f'    {o.case.topic} {o.case.name}: '
                     f"{o.crash or ('stuck' if o.stuck else 'accepted silently')}"
                     f' (rejected {dict(o.rejected)})')
    return lines


def run_all(name, rig, makers):
    """Run every case on ``rig``, each made as it runs; record the table; return outcomes."""
    outcomes = [rig.run_case(make()) for make in makers]
    TABLES.extend(table(name, rig, outcomes))
    return outcomes


def assert_clean(rig, outcomes):
    """Assert 0 crashes / 0 stuck / 0 accepted silently, and every topic covered."""
    failed = [o for o in outcomes if o.crash or o.stuck or o.silent]
    assert not failed, '\n'.join(
        f'{o.case.topic} {o.case.name}: crash={o.crash!r} stuck={o.stuck} '
        f'silent={o.silent} rejected={dict(o.rejected)}' for o in failed)
    uncovered = set(rig.topics) - {o.case.topic for o in outcomes}
    assert not uncovered, f'topics without a fuzz case: {sorted(uncovered)}'
