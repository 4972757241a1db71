"""
The stamp-ordered buffers (ibvs_common.sync) by property, without rclpy.

Lookups do not depend on arrival order, memory stays bounded, and stale or duplicate
stamps are rejected with a reason. Plain functions without fixtures, so that the first test
can run them all in a process where rclpy is never imported.
"""

import itertools

from ibvs_common.sync import JointTrack, lerp, PendingQueue, Rejection, StampHistory
from ibvs_testing.plain import run_without_rclpy
import numpy as np

MS = 1_000_000
DT = MS                 # 1 kHz physics


def test_buffer_tests_run_without_rclpy():
    """These tests and sync.py load and pass with no rclpy imported."""
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


# -- JointTrack ------------------------------------------------------------------------------

def true_q(t_ns):
    """Return a smooth joint motion (rad) of six joints, about 0.6 rad/s at most."""
    t = t_ns * 1e-9
    return 0.3 * np.sin(2.0 * t + np.arange(6)) + 0.05 * t


def true_qd(t_ns):
    t = t_ns * 1e-9
    return 0.6 * np.cos(2.0 * t + np.arange(6)) + 0.05


def test_a_state_at_the_stamp_is_the_state_itself():
    """The lockstep publishes a frame's state at its stamp: read back to the bit."""
    track = JointTrack(strict=True)
    values = {t: (true_q(t), true_qd(t)) for t in range(0, 200 * MS, 33 * MS)}
    for t, v in values.items():
        track.add(t, v)
    for t, v in values.items():
        got, why = track.at(t)
        assert why is None and got is v


def test_250_hz_states_on_their_own_cycle_give_each_30_hz_frame_its_state():
    """
    Give each 30 Hz frame its state from 250 Hz joint states on an unaligned cycle.

    joint_state_broadcaster stamps on the controller manager's cycle (4 ms), offset from the
    camera's and jittered by +-0.5 ms: every frame after the first state gets the state at
    its stamp within 1e-4 rad (positions) and 1e-3 rad/s (velocities).
    """
    rng = np.random.default_rng(34)
    track = JointTrack(horizon_ns=2000 * MS, strict=True)
    stamps = (1_234_567 + 4 * MS * np.arange(2600)
              + rng.uniform(-0.5 * MS, 0.5 * MS, 2600)).astype(np.int64)
    frames = [round(n * 1e9 / 30) for n in range(1, 300)]
    got = {}
    pending = list(frames)
    for t in stamps:
        assert track.add(int(t), (true_q(t), true_qd(t))) is None
        while pending:
            value, why = track.at(pending[0])
            if value is None and why is None:
                break
            got[pending.pop(0)] = (value, why)
    assert len(got) == len(frames)
    used = [t for t, (value, why) in got.items() if why is None]
    assert len(used) >= 0.98 * len(frames)
    for t in used:
        q, qd = got[t][0]
        assert np.max(np.abs(q - true_q(t))) < 1e-4
        assert np.max(np.abs(qd - true_qd(t))) < 1e-3
    assert 240 < 1e9 / track.period_ns() < 260


def test_a_gap_wider_than_the_measured_rate_allows_is_refused_and_says_so():
    track = JointTrack()
    for k in range(10):
        track.add(k * 4 * MS, float(k))
    track.add(60 * MS, 15.0)     # 24 ms after 36 ms: six periods of 4 ms
    value, why = track.at(50 * MS)
    assert value is None and 'more than 10.000 ms' in why and '250.0 Hz' in why
    # one lost message (8 ms) is still interpolated over
    track.add(68 * MS, 17.0)
    assert track.at(64 * MS) == (16.0, None)


def test_a_rejected_state_refuses_its_own_stamp_and_is_lost_elsewhere():
    track = JointTrack()
    track.add(0, 0.0)
    track.add_bad(4 * MS, 'NaN')
    assert track.at(4 * MS) == (None, 'joint state of the image rejected (NaN)')
    assert track.at(3 * MS) == (None, None)       # as if lost: the next one may come
    track.add(8 * MS, 8.0)
    assert track.at(6 * MS) == (6.0, None)
    assert track.at(4 * MS) == (None, 'joint state of the image rejected (NaN)')


def test_no_state_yet_waits_and_none_before_refuses():
    track = JointTrack()
    assert track.at(5) == (None, None)
    track.add(10, 1.0)
    assert track.at(12) == (None, None)           # the state after it may still come
    value, why = track.at(5)
    assert value is None and 'nothing to interpolate from' in why


def test_lerp_of_arrays_and_tuples_keeps_the_ends_to_the_bit():
    a, b = (np.array([0.1, 0.2]), np.array([1.0])), (np.array([0.3, 0.6]), np.array([3.0]))
    assert lerp(a, b, 0.0) is a and lerp(a, b, 1.0) is b
    mid = lerp(a, b, 0.5)
    np.testing.assert_allclose(mid[0], [0.2, 0.4]) and np.testing.assert_allclose(mid[1], [2.0])


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


# -- after the clock jumped back -------------------------------------------------------------

def test_every_buffer_takes_the_new_time_line_after_forget():
    """A jump back of the clock: what each buffer held would refuse every fresh stamp."""
    history, track, queue = StampHistory(), JointTrack(), PendingQueue(4)
    for t in (5_000 * MS, 5_001 * MS):
        assert history.add(t, 'x') is None and track.add(t, np.zeros(6)) is None
    assert queue.offer(5_001 * MS, 'y') is None
    queue.pop()
    assert history.add(0, 'x').reason == 'stale stamp'
    assert queue.offer(0, 'y').reason == 'stale stamp'
    for buffer in (history, track, queue):
        buffer.forget()
    assert len(history) == len(track) == len(queue) == 0 and queue.newest_ns is None
    assert history.add(0, 'x') is None and queue.offer(0, 'y') is None
    assert track.add(0, np.zeros(6)) is None and track.add(DT, np.ones(6)) is None
    np.testing.assert_allclose(track.at(DT // 2)[0], 0.5)
