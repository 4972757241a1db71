"""
Cost of the simulator's hot paths, for ``make bench`` (``ibvs_experiments.bench``).

``run(report)`` calls ``report(name, seconds_list)`` with per-iteration wall times of: one
physics step (torque control at 1 kHz, computed torque from PyBullet's inverse dynamics
included), and one stereo pair rendered at HD720 and at VGA by the simulator's renderer
(:mod:`ibvs_sim.gl_renderer`, on the device it chose: printed), with one sample per pixel,
with 2 x 2, and as the simulator renders by default (one sample per pixel, 8 x 8 in the
windows around the markers). No ROS involved.
``python -m ibvs_sim.bench`` prints median and p95 of each.
"""

from collections.abc import Callable, Sequence
import time

from ibvs_common.bench import print_timing
from ibvs_model import inverse_kinematics, look_at, paper, StereoCamera, StereoIntrinsics
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .world import DEFAULT_FOCUS_SUPERSAMPLING, DEFAULT_SUPERSAMPLING, RendererError, World

PHYSICS_STEPS = 2000
RENDERS = {'HD720': 20, 'VGA': 40}
#: The renderer's name in the timings' labels (ibvs_experiments.bench reads them).
RENDERER = 'opengl'
SUPERSAMPLING = sorted({1, 2, DEFAULT_SUPERSAMPLING})


def stereo_frames(camera: StereoCamera, poses: Sequence[ArrayLike], empty_q: ArrayLike
                  ) -> tuple[list[tuple[NDArray[np.uint8], NDArray[np.uint8]]],
                             tuple[NDArray[np.uint8], NDArray[np.uint8]], str]:
    """
    Return (a stereo pair at each joint vector of ``poses``, the pair at ``empty_q``, RENDERER).

    As the simulator renders them by default (:meth:`.world.World.render_stereo`), through
    ``camera``; for the detector's timings (``ibvs_vision.bench.run``'s ``render``).
    """
    world = World()
    try:
        frames = []
        for q in poses:
            world.reset(q)
            frames.append(world.render_stereo(camera))
        world.reset(empty_q)
        return frames, world.render_stereo(camera), RENDERER
    finally:
        world.close()


def _time(func, count):
    out = []
    for _ in range(count):
        start = time.perf_counter()
        func()
        out.append(time.perf_counter() - start)
    return out


def _bench_world(world, report, renders, physics):
    world.reset(inverse_kinematics(paper.target_pose()))
    if physics:
        def step():
            q, qd = world.joint_state()
            world.step(world.inverse_dynamics(q, qd, np.zeros(6)))
        step()  # warm-up
        report('sim: physics step (computed torque, 1 kHz)', _time(step, PHYSICS_STEPS))
    for resolution, count in renders.items():
        camera = StereoCamera(StereoIntrinsics.zed2(resolution),
                              look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT))
        for factor in SUPERSAMPLING:
            world.render_stereo(camera, factor)  # warm-up (shader and mesh caches)
            # Fewer repetitions of the dearer supersampled renders (cost ~ factor^2).
            repeats = max(3, count // factor ** 2)
            report(f'sim: stereo pair {resolution} ({RENDERER}, {factor}x{factor} '
                   'samples/px)',
                   _time(lambda c=camera, f=factor: world.render_stereo(c, f), repeats))
        spheres = world.marker_spheres()
        report(f'sim: stereo pair {resolution} ({RENDERER}, simulator default: '
               f'{DEFAULT_SUPERSAMPLING}x{DEFAULT_SUPERSAMPLING} samples/px, '
               f'{DEFAULT_FOCUS_SUPERSAMPLING}x{DEFAULT_FOCUS_SUPERSAMPLING} around the markers)',
               _time(lambda c=camera: world.render_stereo(
                   c, DEFAULT_SUPERSAMPLING, spheres, DEFAULT_FOCUS_SUPERSAMPLING), count))


def run(report: Callable[[str, list[float]], None]) -> None:
    """Time one physics step and one stereo pair at HD720 and VGA; see the module docstring."""
    try:
        world = World()
    except RendererError as exc:
        print(f'  sim: the renderer cannot start here ({exc})')
        return
    try:
        print(f'  sim: renderer {world.renderer}')
        _bench_world(world, report, RENDERS, physics=True)
    finally:
        world.close()


def main() -> None:
    """Print median and p95 of each timing (``python -m ibvs_sim.bench``)."""
    run(print_timing)


if __name__ == '__main__':
    main()
