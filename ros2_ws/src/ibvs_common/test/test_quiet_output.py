"""ibvs_common.process.quiet_output: what C code writes meanwhile stays off the terminal."""

import ctypes
import os
import subprocess
import sys

from ibvs_common.process import quiet_output


def test_writes_to_both_descriptors_are_dropped_and_the_rest_kept(capfd):
    print('before', flush=True)
    with quiet_output():
        os.write(1, b'banner one\n')
        os.write(2, b'banner two\n')
        ctypes.CDLL(None).printf(b'banner three\n')  # C's buffered stdout
    print('after', flush=True)
    os.write(2, b'error after\n')
    out, err = capfd.readouterr()
    assert 'banner' not in out + err
    assert out == 'before\nafter\n' and err == 'error after\n'


def test_pybullets_build_time_banner_is_not_written_by_our_imports():
    # The banner comes from PyBullet's C module as it loads (on standard error).
    code = ('import ibvs_control.dynamics, ibvs_sim.world\n'
            'import sys; print("imported", file=sys.stderr)\n')
    done = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert 'pybullet build time' not in done.stdout + done.stderr
    assert done.stderr.strip().endswith('imported')
