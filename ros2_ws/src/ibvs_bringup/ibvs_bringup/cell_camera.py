"""
What ``ibvs cell`` checks of the camera_info it receives before any node starts (no ROS).

The topic check (:func:`.cell_checks.wait_for_topics`) finds the ZED wrapper's topics; what
is on them can still be another camera than the cell's. zed-ros2-wrapper's defaults change it:
up to v5.2.2 ``general.pub_resolution: 'CUSTOM'`` with ``general.pub_downscale_factor:
2.0`` publishes HD720 as 640 x 360 (NATIVE the default from v5.3.1;
``zed_wrapper/config/common_stereo.yaml`` L28-39 at 33dfefa), which halves the focal
length in pixels and doubles the depth error a tenth of a pixel of disparity makes. The
nodes would run on it (they build the camera from its camera_info), a taught target or a
calibration made at the native size would not hold. So one left and one right camera_info
are read and :func:`camera_problems` asks for a rectified stereo pair
(:func:`ibvs_common.conversions.intrinsics_from_infos`: sizes, rows, the right lens's
P[3] = -f_x b) at one of the ZED 2's native sizes (:data:`ibvs_model.camera.ZED2_RESOLUTIONS`).
"""

from typing import Any

from ibvs_common.conversions import InputError, intrinsics_from_infos
from ibvs_model.camera import ZED2_RESOLUTIONS

#: What to do about a camera published at another size than its native one.
NATIVE_HINT = ('launch zed-ros2-wrapper with general.pub_resolution:=NATIVE (its '
               "'CUSTOM' with general.pub_downscale_factor 2.0, the default up to v5.2.2, "
               'publishes HD720 as 640 x 360)')


def native_mode(width: int, height: int) -> str | None:
    """Return the ZED 2 mode whose native size is ``width`` x ``height``, else None."""
    for mode, size in ZED2_RESOLUTIONS.items():
        if size == (width, height):
            return mode
    return None


def camera_problems(left: Any, right: Any, left_topic: str, right_topic: str
                    ) -> tuple[list[str], str]:
    """
    Return (the problems of a left and right CameraInfo, a line that describes them).

    Problems: the pair is not a rectified stereo pair (the reason and detail of
    :func:`ibvs_common.conversions.intrinsics_from_infos`), or its size is none of the
    ZED 2's native sizes (naming ``general.pub_resolution``: :data:`NATIVE_HINT`).
    """
    try:
        intrinsics = intrinsics_from_infos(left, right)
    except InputError as exc:
        return [f'{left_topic} and {right_topic}: {exc.reason}: {exc.detail}'], ''
    width, height = intrinsics.width, intrinsics.height
    mode = native_mode(width, height)
    line = (f'camera_info {width} x {height}' + (f' ({mode}, native)' if mode else '')
            + f', f_x {intrinsics.fu:.1f} px, baseline {intrinsics.baseline:.4f} m')
    if mode is None:
        sizes = ', '.join(f'{m} {w} x {h}' for m, (w, h) in ZED2_RESOLUTIONS.items())
        return [f"{left_topic}: {width} x {height} is none of the ZED 2's native sizes "
                f'({sizes}): {NATIVE_HINT}'], line
    return [], line
