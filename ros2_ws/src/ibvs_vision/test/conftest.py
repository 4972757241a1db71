"""Fixtures of the ibvs_vision tests: the shared ones (ibvs_common.testing) and model F."""

from ibvs_common.testing import context, default_camera, executor_of, world  # noqa: F401
from ibvs_model import CameraRobotModel, IRB4600
import pytest


@pytest.fixture(scope='module')
def hd_model():
    """Return F (eq. 30) of the paper's robot and the ZED 2 at HD720."""
    return CameraRobotModel(default_camera('HD720'), IRB4600)


@pytest.fixture(scope='module')
def vga_model():
    """Return F (eq. 30) of the paper's robot and the ZED 2 at VGA."""
    return CameraRobotModel(default_camera('VGA'), IRB4600)
