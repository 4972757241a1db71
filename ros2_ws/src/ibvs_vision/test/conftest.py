"""Fixtures shared by the ibvs_vision tests: the default ZED 2 stereo camera and model F."""

from ibvs_model import CameraRobotModel, IRB4600, look_at, paper, StereoCamera, StereoIntrinsics
import pytest


def make_camera(resolution):
    """Return the ZED 2 at ``resolution`` at the default pose (docs/design.md §5)."""
    return StereoCamera(StereoIntrinsics.zed2(resolution),
                        look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT))


@pytest.fixture(scope='module')
def hd_model():
    """Return F (eq. 30) of the paper's robot and the ZED 2 at HD720."""
    return CameraRobotModel(make_camera('HD720'), IRB4600)


@pytest.fixture(scope='module')
def vga_model():
    """Return F (eq. 30) of the paper's robot and the ZED 2 at VGA."""
    return CameraRobotModel(make_camera('VGA'), IRB4600)
