"""Fixtures of the ibvs_sim tests: the shared ones (ibvs_common.testing), and a collector."""

import gc

from ibvs_common.testing import camera, context, domain_id, executor_of, world  # noqa: F401
import pytest


@pytest.fixture(scope='module', autouse=True)
def collect_garbage():
    """
    Finalise this module's leftovers (rclpy handles, PyBullet clients) in this process.

    Linters later in the same pytest run fork worker processes; an rclpy object finalised
    by the garbage collector in such a child crashes it (seen: flake8 worker segfault).
    """
    yield
    gc.collect()
