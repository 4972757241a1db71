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

Every message the node publishes, on any topic (its publishers are found on the node and
wrapped, as its subscriptions are), is scanned for a NaN or inf in its numeric fields, and a
number written as text in a /diagnostics value (:func:`non_finite_fields`): the table's
**non-finite outputs** counts them, and any is a failure. A rig that records the node's
outputs also checks that they came (:meth:`Rig.published_finite`).

A case may carry its own check of what must become of a valid but costly input
(``answered``: e.g. a full-size noise pair is published or dropped with a count, never
left pending): one that fails it counts as accepted silently.
"""

from collections import Counter
from dataclasses import dataclass, field
import math
import time
from typing import Callable, List, Optional, Tuple

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
    #: For a valid input: a predicate, called after the case, true when the node answered
    #: it as it must (published, or counted); None: the rejection count is the check.
    answered: Optional[Callable[[], bool]] = None

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
    #: The messages the node published with a non-finite number during the case.
    non_finite: int = 0


def _base_type(field_type):
    """Return the element type of a rosidl field type: 'sequence<double, 3>' -> 'double'."""
    if field_type.startswith('sequence<'):
        field_type = field_type[len('sequence<'):-1].split(',')[0]
    return field_type.split('[')[0]


def non_finite_fields(msg, path=''):
    """
    Return the paths of the fields of ``msg`` that hold a NaN or inf (empty: all finite).

    Every float and double, alone, in an array or a sequence, of ``msg`` and of every message
    in it; and each diagnostic_msgs/KeyValue value that reads as a non-finite float
    ('nan', 'inf'): /diagnostics carries its numbers as text. Integers, strings and bytes
    cannot hold one.
    """
    found = []
    for name, field_type in msg.get_fields_and_field_types().items():
        value = getattr(msg, name)
        base = _base_type(field_type)
        many = base != field_type
        if base in ('float', 'double'):
            values = list(value) if many else [value]
            if not all(math.isfinite(v) for v in values):
                found.append(path + name)
        elif '/' in base:
            for i, item in enumerate(value if many else [value]):
                found += non_finite_fields(item, f'{path}{name}{f"[{i}]" if many else ""}.')
        elif base == 'string' and name == 'value' and type(msg).__name__ == 'KeyValue':
            try:
                number = float(value)
            except ValueError:
                continue
            if not math.isfinite(number):
                found.append(path + name)
    return found


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
        #: (topic, field paths) of every message the node published with a NaN or inf.
        self.non_finite = []
        self.published = Counter()
        self._scanned = set()
        self.scan_publishers()
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

    def scan_publishers(self):
        """Wrap each publisher of the node not yet wrapped: every message it sends is scanned."""
        for pub in self.node.publishers:
            if id(pub) in self._scanned:
                continue
            self._scanned.add(id(pub))
            publish, topic = pub.publish, pub.topic_name

            def scanned(msg, publish=publish, topic=topic):
                self.published[topic] += 1
                if not isinstance(msg, bytes):
                    fields = non_finite_fields(msg)
                    if fields:
                        self.non_finite.append((topic, fields))
                return publish(msg)

            pub.publish = scanned

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
        self.scan_publishers()  # one created since (none of our nodes does, but it could)
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
        non_finite = len(self.non_finite)
        try:
            for topic, msg in case.messages:
                self.deliver(topic, msg)
        except Exception as exc:  # what escaped a callback: the node would have died
            outcome.crash = f'{type(exc).__name__}: {exc}'
            return outcome
        outcome.rejected = self.reasons(case.topic) - before
        outcome.silent = sum(outcome.rejected.values()) < case.counted
        if case.answered is not None:
            outcome.silent = outcome.silent or not self.spin_until(case.answered, 'answered')
        try:
            outcome.stuck = not self.recovered()
        except Exception as exc:
            outcome.crash = f'after the case, {type(exc).__name__}: {exc}'
        outcome.non_finite = len(self.non_finite) - non_finite
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
    covered = {o.case.topic for o in outcomes} & set(rig.topics)  # a command's: not read
    lines = [f'{name:32s} {len(outcomes):5d} {len(crashes):7d} {len(stuck):5d} '
             f'{len(silent):17d} {len(rig.non_finite):18d}   '
             f'topics {len(covered)}/{len(rig.topics)}']
    for o in crashes + stuck + silent:
        lines.append(f'    {o.case.topic} {o.case.name}: '
                     f"{o.crash or ('stuck' if o.stuck else 'accepted silently')}"
                     f' (rejected {dict(o.rejected)})')
    for topic, fields in rig.non_finite[:10]:
        lines.append(f'    published on {topic} non-finite {", ".join(fields[:5])}')
    return lines


def run_all(name, rig, makers):
    """Run every case on ``rig``, each made as it runs; record the table; return outcomes."""
    outcomes = [rig.run_case(make()) for make in makers]
    TABLES.extend(table(name, rig, outcomes))
    return outcomes


def assert_clean(rig, outcomes):
    """Assert 0 crashes / stuck / accepted silently / non-finite outputs; every topic covered."""
    failed = [o for o in outcomes if o.crash or o.stuck or o.silent or o.non_finite]
    assert not failed, '\n'.join(
        f'{o.case.topic} {o.case.name}: crash={o.crash!r} stuck={o.stuck} '
        f'silent={o.silent} rejected={dict(o.rejected)} non-finite outputs={o.non_finite}'
        for o in failed)
    assert not rig.non_finite, f'non-finite outputs: {rig.non_finite[:10]}'
    assert sum(rig.published.values()) > 0, 'the node published nothing: nothing was scanned'
    uncovered = set(rig.topics) - {o.case.topic for o in outcomes}
    assert not uncovered, f'topics without a fuzz case: {sorted(uncovered)}'
