"""The nodes-alone bench's measures from their records (pure; no bag, no rclpy)."""

import subprocess
import sys

from ibvs_experiments.nodes_bench import (latency_stats, process_cpu_s, Recording, segment,
                                          segment_bounds)
import numpy as np
import pytest

MS = 1_000_000


def test_latency_runs_from_the_first_image_to_the_first_command_that_uses_the_frame():
    sent = {n * 33 * MS: 10**18 + n * 33 * MS + 2 * MS for n in range(40)}  # published 2 ms late
    commands = []
    for n, stamp in enumerate(sorted(sent)):
        if n % 10 == 9:
            continue  # a frame the nodes skipped: no command of its own
        first = sent[stamp] + (10 + n % 5) * MS
        commands += [(first + 4 * MS, stamp), (first, stamp)]  # a later command, then the first
    since = sent[5 * 33 * MS]
    stats = latency_stats(sent, commands, since)
    used = [n for n in range(5, 40) if n % 10 != 9]
    delays = np.array([10 + n % 5 for n in used], dtype=float)
    assert stats['frames_sent'] == 35 and stats['frames_used'] == len(used)
    assert stats['latency_mean_ms'] == pytest.approx(delays.mean())
    assert stats['latency_p95_ms'] == pytest.approx(np.percentile(delays, 95))
    assert stats['latency_max_ms'] == pytest.approx(14.0)


def test_a_command_is_the_frame_s_whose_stamp_is_nearest_its_exposure():
    # The feature node stamps its output with the exposure: the stamp less its stamp offset
    # estimate, a fraction of a millisecond either way about the replay's zero.
    sent = {n * 33 * MS: 10**18 + n * 33 * MS for n in range(10)}
    commands = [(sent[t] + 6 * MS, t + (-1) ** n * 400_000) for n, t in enumerate(sorted(sent))]
    commands.append((10**18 + 99 * MS, 4 * 33 * MS + 17 * MS))  # half a period off: no frame's
    stats = latency_stats(sent, commands, 0)
    assert stats['frames_used'] == 10 and stats['latency_max_ms'] == pytest.approx(6.0)


def test_a_run_s_servo_part_is_its_longest_run_of_detectable_frames_and_lost_what_precedes():
    detectable = [False, True, False, False, True, True, True, False, True, True, True, True]
    assert segment_bounds(detectable, 'servo') == (8, 12)
    assert segment_bounds(detectable, 'lost') == (0, 8)
    assert segment_bounds(detectable, 'all') == (0, 12)
    assert segment_bounds([False] * 5, 'servo')[1] - segment_bounds([False] * 5, 'servo')[0] == 0
    with pytest.raises(ValueError, match='segment'):
        segment_bounds(detectable, 'slew')


def test_a_part_of_a_recording_takes_its_joint_path_from_its_first_frame_s_exposure():
    n = 40
    rec = Recording(frames=list(range(n)), joint_t=np.arange(0.0, 2.0, 0.004),
                    joint_q=np.zeros((500, 6)), joint_qd=np.zeros((500, 6)), latched={},
                    params={}, size=(8, 8), rate_hz=30.0, joint_offset_s=0.01,
                    exposures_s=0.01 + np.arange(n) / 30.0)
    detectable = [i >= 18 for i in range(n)]
    servo = segment(rec, 'servo', detectable)
    assert servo.frames == list(range(18, n)) and servo.first_frame == 18
    assert servo.joint_offset_s == pytest.approx(0.01 + 18 / 30.0)
    assert segment(rec, 'lost', detectable).frames == list(range(18))
    assert segment(rec, 'all', detectable) is rec
    with pytest.raises(ValueError, match='longer run'):
        segment(rec, 'servo', [False] * n)


def test_no_command_no_latency():
    stats = latency_stats({0: 5 * MS}, [(9 * MS, 33 * MS)], 0)  # a command of another frame
    assert stats == {'frames_sent': 1, 'frames_used': 0}


def test_cpu_of_a_process_group_grows_with_its_work():
    # A group of its own (this test's group is make test's: its other processes come and
    # go, and the CPU of one that ended leaves the sum).
    child = subprocess.Popen(
        [sys.executable, '-c', 'import sys, time\nend = time.process_time() + 0.3\n'
         'while time.process_time() < end:\n    pass\nprint("done", flush=True)\n'
         'sys.stdin.read()'],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        assert child.stdout.readline().strip() == 'done'
        assert process_cpu_s(child.pid) >= 0.25
    finally:
        child.stdin.close()
        child.wait(timeout=30)
    assert process_cpu_s(2 ** 22 + 12345) == 0.0  # no such group
