"""
The stamp-ordered buffers (ibvs_common.sync) by property, without rclpy.

Lookups do not depend on arrival order, memory stays bounded, and stale or duplicate
stamps are rejected with a reason. Plain functions without fixtures, so that the first test
can run them all in a process where rclpy is never imported.
"""

import itertools

from ibvs_common.sync import PendingQueue, Rejection, StampHistory
from ibvs_testing.plain import run_without_rclpy

MS = 1_000_000
DT = MS                 # 1 kHz physics


def test_buffer_tests_run_without_rclpy():
    """Acceptance (issue 12): sync.py and these tests load and pass with no rclpy imported."""
    assert run_without_rclpy(__file__, 'test_buffer_tests_run_without_rclpy') > 0


# -- StampHistory ----------------------------------------------------------------------------

def test_history_finds_the_first_stamp_at_or_after_a_time():
    history = StampHistory()
    for t in (0, 33 * MS, 34 * MS, 66 * MS):
        assert history.add(t, f'q{t}') is None
    assert history.at_or_after(0) == (0, 'q0')
    assert history.at_or_after(1) == (33 * MS, f'q{33 * MS}')
    assert history.at_or_after(34 * MS) == (34 * MS, f'q{34 * MS}')
    assert history.at_or_after(66 * MS + 1) is None
    assert history.newest == 66 * MS and 33 * MS in history and MS not in history


def test_strict_history_rejects_stale_and_duplicate_stamps():
    history = StampHistory()
    history.add(5, 'a')
    assert history.add(5, 'b') == Rejection('stale stamp', '5 ns after 5 ns')
    assert history.add(4, 'b') == Rejection('stale stamp', '4 ns after 5 ns')
    assert len(history) == 1 and history.at_or_after(0) == (5, 'a')


def test_loose_history_does_not_depend_on_arrival_order():
    stamps = [0, 3, 7, 8, 12]
    contents = set()
    for order in itertools.permutations(stamps):
        history = StampHistory(strict=False)
        for t in order:
            assert history.add(t, t * 10) is None
        contents.add(tuple(history.at_or_after(t) for t in range(14)))
    assert len(contents) == 1


def test_history_stays_within_its_count_and_its_horizon():
    counted = StampHistory(max_len=50)
    timed = StampHistory(horizon_ns=20 * MS, strict=False)
    for k in range(5000):
        counted.add(k * DT, k)
        timed.add(k * DT, k)
        timed.prune(k * DT)
        assert len(counted) <= 50 and len(timed) <= 21
    assert counted.at_or_after(0) == (4950 * DT, 4950)
    assert timed.at_or_after(0) == (4979 * DT, 4979)


# -- PendingQueue ----------------------------------------------------------------------------

def test_pending_queue_keeps_stamp_order_and_answers_each_once():
    queue = PendingQueue(3, full_note='waiting for the camera model')
    assert queue.offer(10, 'a') is None and queue.offer(20, 'b') is None
    assert queue.offer(20, 'c') == Rejection('stale stamp', '20 ns, not after 20 ns')
    assert queue.offer(15, 'c') == Rejection('stale stamp', '15 ns, not after 20 ns')
    assert queue.offer(30, 'c') is None
    assert queue.offer(40, 'd') == Rejection(
        'buffer full', '40 ns dropped: waiting for the camera model')
    assert [queue.pop() for _ in range(3)] == [(10, 'a'), (20, 'b'), (30, 'c')]
    # once answered, a stamp cannot come back
    assert queue.offer(30, 'again').reason == 'stale stamp' and len(queue) == 0
