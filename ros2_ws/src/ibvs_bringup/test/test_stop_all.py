"""The runner stops a run's processes together, escalating only for those that linger."""

import sys

from ibvs_bringup.supervision import NodeProcess, stop_all

#: A process that, on SIGINT, says so in ``<dir>/<name>`` and exits 0 once every process of
#: the group has said so, or exits 1 if that does not happen within 20 s. Stopped one after
#: the other, the first one waits for a signal its peers only get after it has exited.
PEER = r"""
import os, pathlib, signal, sys, time
here, name, peers = pathlib.Path(sys.argv[1]), sys.argv[2], sys.argv[3:]
def stop(*_):
    (here / name).touch()
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline:
        if all((here / p).exists() for p in peers):
            sys.exit(0)
        time.sleep(0.02)
    sys.exit(1)
signal.signal(signal.SIGINT, stop)
(here / f'{name}.ready').touch()
while True:
    time.sleep(0.05)
"""

#: A process that ignores SIGINT and SIGTERM: only SIGKILL ends it.
STUBBORN = r"""
import pathlib, signal, sys, time
signal.signal(signal.SIGINT, signal.SIG_IGN)
signal.signal(signal.SIGTERM, signal.SIG_IGN)
pathlib.Path(sys.argv[1]).touch()
while True:
    time.sleep(0.05)
"""


def _wait_for(paths):
    import time
    deadline = time.monotonic() + 30.0
    while not all(p.exists() for p in paths):
        assert time.monotonic() < deadline, f'not started: {paths}'
        time.sleep(0.02)


def test_every_process_gets_sigint_before_any_is_waited_for(tmp_path):
    names = ['a', 'b', 'c']
    procs = [NodeProcess.of_command([sys.executable, '-c', PEER, str(tmp_path), name, *names],
                                    name, tmp_path / f'{name}.log') for name in names]
    _wait_for([tmp_path / f'{name}.ready' for name in names])
    assert stop_all(procs) == {'a': 0, 'b': 0, 'c': 0}


def test_a_process_that_ignores_sigint_and_sigterm_is_killed(tmp_path):
    proc = NodeProcess.of_command([sys.executable, '-c', STUBBORN, str(tmp_path / 'up')],
                                  'stubborn', tmp_path / 'stubborn.log')
    _wait_for([tmp_path / 'up'])
    assert stop_all([proc], timeout_s=0.5) == {'stubborn': -9}
    assert proc.stop() == -9  # stopping a stopped process again is harmless
