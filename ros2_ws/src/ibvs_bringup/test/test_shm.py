"""The shared memory of dead Fast DDS participants is reclaimed."""

import fcntl
import os
import time

from ibvs_bringup import shm


def _files(tmp_path, *names, age_s=60.0):
    old = time.time() - age_s
    for name in names:
        (tmp_path / name).write_bytes(b'x' * 1000)
        os.utime(tmp_path / name, (old, old))


def test_dead_segments_go_live_ones_and_ports_stay(tmp_path):
    dead, live = 'fastrtps_0123456789abcdef', 'fastrtps_fedcba9876543210'
    port = ['fastrtps_port7411', 'fastrtps_port7411_el', 'sem.fastrtps_port7411_mutex']
    _files(tmp_path, dead, f'{dead}_el', live, f'{live}_el', *port, 'unrelated')
    with open(tmp_path / f'{live}_el', 'rb') as holder:  # its owner is alive
        fcntl.flock(holder, fcntl.LOCK_EX)
        count, freed = shm.clean(tmp_path)
        assert count == 2 and freed == 2000
        left = sorted(os.listdir(tmp_path))
    # A port is shared by its domain's participants: another graph may be opening it.
    assert left == sorted([live, f'{live}_el', *port, 'unrelated'])


def test_young_files_are_left_and_new_since_keeps_what_was_there(tmp_path):
    old = 'fastrtps_00000000000000aa'
    _files(tmp_path, old, f'{old}_el')
    before = shm.names(tmp_path)
    new = 'fastrtps_00000000000000cc'
    _files(tmp_path, new, f'{new}_el')
    young = 'fastrtps_00000000000000bb'  # another graph's participant may be starting:
    _files(tmp_path, young, f'{young}_el', age_s=0.0)
    with open(tmp_path / f'{young}_el', 'rb'):  # created, not yet locked
        assert shm.zombies(tmp_path) == [tmp_path / f'{old}_el', tmp_path / old,
                                         tmp_path / f'{new}_el', tmp_path / new]
        assert shm.clean(tmp_path, new_since=before) == (2, 2000)
        assert sorted(os.listdir(tmp_path)) == sorted([old, f'{old}_el', young, f'{young}_el'])


def test_a_young_file_nobody_has_open_is_a_dead_owners(tmp_path):
    """What a run killed in its first seconds left goes at the next run's start."""
    young = 'fastrtps_00000000000000dd'
    _files(tmp_path, young, f'{young}_el', age_s=0.0)
    held_open, complete = shm.open_files(tmp_path)
    assert f'{young}_el' not in held_open
    with open(tmp_path / f'{young}_el', 'rb'):
        assert f'{young}_el' in shm.open_files(tmp_path)[0]
    if complete:  # every process's descriptors seen (root): age does not matter
        assert shm.zombies(tmp_path) == [tmp_path / f'{young}_el', tmp_path / young]
    else:  # some processes' descriptors unseen: a young file is left, as before
        assert shm.zombies(tmp_path) == []
