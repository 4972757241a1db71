"""
ibvs run and ibvs cell write only into a folder of their own, and one run at a time.

A symbolic link as ``-o`` and a folder of other files are refused with exit code 2 and left
as they are; a previous run's folder is run into again; a second run into a folder that a
live run holds is refused, naming the first, which completes.
"""

import os
from pathlib import Path
import subprocess
import sys
import time

from ibvs_bringup import domains
from ibvs_experiments import cli
from ibvs_experiments.output_dir import MARKER


def test_ibvs_run_refuses_a_link_and_a_folder_of_other_files(capsys, tmp_path):
    target = tmp_path / 'elsewhere'
    (target / 'bag').mkdir(parents=True)
    (target / 'bag' / 'x').write_text('precious')
    (tmp_path / 'link').symlink_to(target)
    for out in (tmp_path / 'link', target):
        code = cli.main(['run', 'scenario1', '--duration', '0.1', '-o', str(out)])
        err = capsys.readouterr().err
        assert code == 2 and 'run not started' in err and 'Traceback' not in err, err
        assert (target / 'bag' / 'x').read_text() == 'precious'
    assert sorted(os.listdir(target)) == ['bag']


def test_ibvs_cell_says_why_it_cannot_make_its_folder_and_leaves_none(capsys, tmp_path,
                                                                      monkeypatch):
    code = cli.main(['cell', '-o', '/proc/x'])
    err = capsys.readouterr().err
    assert code == 2 and 'cannot create or read the output folder /proc/x' in err, err
    assert 'Errno' not in err and 'Traceback' not in err, err
    # A refused start (its ROS domain held by another run) makes no session folder.
    domain, lock = domains.lock_domain(*domains.pool())
    try:
        monkeypatch.setenv(domains.DOMAIN_ENV, str(domain))
        monkeypatch.delenv(domains.HELD_ENV, raising=False)
        code = cli.main(['cell', '-o', str(tmp_path / 'session')])
    finally:
        lock.close()
    err = capsys.readouterr().err
    assert code == 2 and 'cell not started' in err, err
    assert not (tmp_path / 'session').exists()


def test_a_second_run_into_a_live_runs_folder_is_refused_and_the_first_completes(
        installed_workspace, tmp_path):
    out = tmp_path / 'run'
    cmd = [sys.executable, '-m', 'ibvs_experiments.cli', 'run', 'scenario1', '-o', str(out),
           '--duration', '1', '--no-figures']
    first = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120.0  # a hang guard: the run writes it at its start
        while not (out / 'logs' / 'lockstep.log').exists():
            assert first.poll() is None, first.communicate()
            assert time.monotonic() < deadline, 'the first run never started its nodes'
            time.sleep(0.1)
        second = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
        out_text, err = first.communicate(timeout=300)
    finally:
        if first.poll() is None:
            first.kill()
            first.communicate()
    assert second.returncode == 2, (second.stdout, second.stderr)
    assert f'in use by another run (pid {first.pid}, command line: ' in second.stderr
    assert ' '.join(cmd[1:]) in second.stderr and 'Traceback' not in second.stderr
    assert first.returncode == 0, (out_text, err)
    assert (out / 'metrics.json').is_file() and (out / MARKER).is_file()
    # The same command again runs into its own folder, replacing its bag.
    bag = (out / 'bag' / 'bag.mcap').stat()
    again = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, (again.stdout, again.stderr)
    assert (out / 'bag' / 'bag.mcap').stat().st_ino != bag.st_ino or \
        (out / 'bag' / 'bag.mcap').stat().st_mtime_ns != bag.st_mtime_ns
    assert Path(out / 'metrics.json').is_file()
