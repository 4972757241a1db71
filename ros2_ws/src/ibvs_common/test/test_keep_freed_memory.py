"""ibvs_common.process.keep_freed_memory: a frame's freed buffers are not faulted in again."""

import subprocess
import sys

import pytest

# A process that allocates and frees six HD720-sized buffers a "frame" (as the simulator's
# process does with a stereo frame's images, messages and the detector's arrays), and prints
# the minor page faults of a frame once warm.
FRAMES = """
import resource, sys
import numpy as np
from ibvs_common.process import keep_freed_memory
if sys.argv[1] == 'kept':
    assert keep_freed_memory()
def faults():
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt
def frame():
    buffers = [np.ones(1280 * 720 * 3, np.uint8) for _ in range(6)]
    del buffers
for _ in range(3):
    frame()
before = faults()
for _ in range(20):
    frame()
print((faults() - before) / 20)
"""


def faults_per_frame(mode):
    out = subprocess.run([sys.executable, '-c', FRAMES, mode], check=True,
                         capture_output=True, text=True)
    return float(out.stdout)


@pytest.mark.skipif(not sys.platform.startswith('linux'), reason="glibc's mallopt")
def test_freed_buffers_stay_in_the_heap():
    # By default glibc gives the freed megabytes back and faults them in again, page by
    # page (6 x 675 pages a frame); kept, a warm frame faults in nothing.
    assert faults_per_frame('default') > 1000
    assert faults_per_frame('kept') < 50
