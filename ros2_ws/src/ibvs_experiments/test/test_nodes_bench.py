"""The nodes-alone bench's measures from their records (pure; no bag, no rclpy)."""

import subprocess
import sys

from ibvs_experiments.nodes_bench import latency_stats, process_cpu_s
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
