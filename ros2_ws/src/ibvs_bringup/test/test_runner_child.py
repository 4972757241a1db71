"""A node the runner starts sees the runner's signals, whatever its parent blocked."""

import signal
import subprocess

from ibvs_common.process import supervised_child


def _blocked_mask(preexec_fn):
    out = subprocess.run(['grep', 'SigBlk', '/proc/self/status'], capture_output=True,
                         text=True, check=True, preexec_fn=preexec_fn).stdout
    return int(out.split()[1], 16)


def test_a_child_does_not_inherit_a_blocked_sigint():
    # A Ray worker blocks SIGINT, and a blocked mask survives exec: then the nodes of a
    # study's run ignored the runner's stop for 10 s each.
    old = signal.pthread_sigmask(signal.SIG_BLOCK, [signal.SIGINT])
    try:
        assert _blocked_mask(None) & (1 << (signal.SIGINT - 1))  # the check can fail
        assert _blocked_mask(supervised_child) == 0
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)
