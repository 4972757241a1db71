"""Fixtures shared by the ibvs_sim tests: PyBullet worlds and the default stereo camera."""

import gc
import os

from ibvs_model import look_at, paper, StereoCamera, StereoIntrinsics
from ibvs_sim.world import World
import pytest


@pytest.fixture(scope='session')
def domain_id():
    """Return a ROS domain for this test process, so parallel runs do not talk to each other."""
    return int(os.environ.get('IBVS_TEST_DOMAIN_ID', 1 + os.getpid() % 200))


@pytest.fixture(scope='module')
def world():
    """Yield the paper's robot in a PyBullet world with the default renderer ('auto')."""
    w = World()
    try:
        yield w
    finally:
        w.close()


@pytest.fixture(scope='module')
def camera():
    """Return the ZED 2 at HD720 at the default pose (docs/design.md §5)."""
    return StereoCamera(StereoIntrinsics.zed2('HD720'),
                        look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT))


@pytest.fixture(scope='module', autouse=True)
def collect_garbage():
    """
    Finalise this module's leftovers (rclpy handles, PyBullet clients) in this process.

    Linters later in the same pytest run fork worker processes; an rclpy object finalised
    by the garbage collector in such a child crashes it (seen: flake8 worker segfault).
    """
    yield
    gc.collect()
