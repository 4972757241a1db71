"""Fixtures of the ibvs_vision tests: the shared ones (ibvs_testing), the world, model F."""

from ibvs_model import CameraRobotModel, default_camera, IRB4600
from ibvs_sim.world import World  # a test dependency: the rendered images
from ibvs_testing.fixtures import closed_after_module, context, executor_of  # noqa: F401
import pytest

world = closed_after_module(World, "The paper's robot in a PyBullet world drawn by its renderer.")


@pytest.fixture(scope='module')
def hd_model():
    """Return F (eq. 30) of the paper's robot and the ZED 2 at HD720."""
    return CameraRobotModel(default_camera('HD720'), IRB4600)


@pytest.fixture(scope='module')
def vga_model():
    """Return F (eq. 30) of the paper's robot and the ZED 2 at VGA."""
    return CameraRobotModel(default_camera('VGA'), IRB4600)
