"""A young lock file is judged by the processes of its owner, the only ones that can make it."""

import os
from pathlib import Path

from ibvs_bringup import shm
import pytest


@pytest.mark.skipif(os.geteuid() != 0, reason='giving a process folder another owner takes root')
def test_unreadable_processes_of_another_user_do_not_hide_ones_own(tmp_path, monkeypatch):
    shm_dir, proc = tmp_path / 'shm', tmp_path / 'proc'
    shm_dir.mkdir()
    (proc / '100' / 'fd').mkdir(parents=True)  # one's own, holding nothing
    (proc / '200' / 'fd').mkdir(parents=True)  # another user's: its descriptors unreadable
    other = os.getuid() + 1000
    os.chown(proc / '200', other, -1)
    listdir = os.listdir

    def guarded(path):
        if Path(path) == proc / '200' / 'fd':
            raise PermissionError(13, 'Permission denied', str(path))
        return listdir(path)

    monkeypatch.setattr(shm.os, 'listdir', guarded)
    assert shm.open_files(shm_dir, proc)[1] is False  # not every process seen
    assert shm.open_files(shm_dir, proc, uid=os.getuid()) == (set(), True)
    assert shm.open_files(shm_dir, proc, uid=other)[1] is False
