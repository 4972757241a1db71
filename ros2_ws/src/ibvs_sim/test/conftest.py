"""Fixtures of the ibvs_sim tests: the shared ones (ibvs_testing), the world, the camera."""

import gc

from ibvs_model import default_camera
from ibvs_sim.world import World
from ibvs_testing.fixtures import (closed_after_module, context, domain_id,  # noqa: F401
                                   executor_of)
import pytest

world = closed_after_module(World, "The paper's robot in a PyBullet world, drawn by its renderer.")


@pytest.fixture(scope='module')
def camera():
    """Return the ZED 2 at HD720 at the default pose (docs/design.md §5)."""
    return default_camera('HD720')


@pytest.fixture(scope='module', autouse=True)
def collect_garbage():
    """
    Finalise this module's leftovers (rclpy handles, PyBullet clients) in this process.

    Linters later in the same pytest run fork worker processes; an rclpy object finalised
    by the garbage collector in such a child crashes it (seen: flake8 worker segfault).
    """
    yield
    gc.collect()
