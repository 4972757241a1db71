"""What ibvs cell checks of the camera_info it receives (ibvs_bringup.cell_camera)."""

from ibvs_bringup.cell_camera import camera_problems, native_mode
from ibvs_common.conversions import camera_infos
from ibvs_model.camera import StereoIntrinsics

LEFT = '/zed/zed_node/left/color/rect/camera_info'
RIGHT = '/zed/zed_node/right/color/rect/camera_info'


def test_a_zed2_at_a_native_size_passes_and_is_described():
    for mode in ('HD720', 'VGA', 'HD1080', 'HD2K'):
        left, right = camera_infos(StereoIntrinsics.zed2(mode), 0)
        problems, line = camera_problems(left, right, LEFT, RIGHT)
        assert problems == [] and f'({mode}, native)' in line and 'baseline 0.1200 m' in line


def test_the_wrappers_downscaled_default_is_refused_naming_pub_resolution():
    left, right = camera_infos(StereoIntrinsics.zed2('HD720', downscale=2.0), 0)
    assert (left.width, left.height) == (640, 360)
    problems, line = camera_problems(left, right, LEFT, RIGHT)
    assert len(problems) == 1 and problems[0].startswith(f'{LEFT}: 640 x 360 is none of')
    assert 'general.pub_resolution:=NATIVE' in problems[0]
    assert line.startswith('camera_info 640 x 360, f_x')
    assert native_mode(640, 360) is None and native_mode(1280, 720) == 'HD720'


def test_a_pair_that_is_not_a_rectified_stereo_pair_is_refused_with_the_reason():
    left, right = camera_infos(StereoIntrinsics.zed2('HD720'), 0)
    problems, _ = camera_problems(left, left, LEFT, RIGHT)  # the left twice: no baseline
    assert len(problems) == 1 and 'baseline out of range' in problems[0]
    problems, _ = camera_problems(right, left, LEFT, RIGHT)  # swapped
    assert len(problems) == 1 and 'left lens with a baseline' in problems[0]
