"""
Cost of the detector per stereo pair, for ``make bench`` (``ibvs_experiments.bench``).

``run(report)`` calls ``report(name, seconds_list)`` with the wall time of
:meth:`StereoDetector.detect` per stereo pair, OpenCV on one thread, at HD720 and VGA:

- full search (no prior: Hough over every part of the image where a marker colour shows)
  and tracking (prior = the last measurement: windows around it first), on frames rendered
  by the simulator's PyBullet world (ibvs_sim, when it imports) at random in-view poses;
- the same on synthetic frames (ibvs_vision.synthetic: shaded spheres on a cluttered,
  noisy background, a harder scene than the simulator's);
- a frame without markers (scenario 2/3 start), searched in full every frame.

``python -m ibvs_vision.bench`` prints median and p95 of each. No ROS involved.
"""

import time

import cv2
from ibvs_common.bench import print_timing
from ibvs_model import (CameraRobotModel, fiducial_points, inverse_kinematics, IRB4600,
                        look_at, paper, scene, StereoCamera, StereoIntrinsics)
import numpy as np

from . import synthetic
from .detector import StereoDetector

FRAMES = {'HD720': 20, 'VGA': 20}
REPEAT = 3


def _model(resolution):
    return CameraRobotModel(StereoCamera(StereoIntrinsics.zed2(resolution),
                                         look_at(paper.CAMERA_EYE, paper.CAMERA_LOOK_AT)),
                            IRB4600)


def _time_detection(detector, frames, tracking):
    out = []
    for left, right in frames:
        prior = detector.detect(left, right).features if tracking else None  # warm-up too
        for _ in range(REPEAT):
            start = time.perf_counter()
            detector.detect(left, right, prior=prior)
            out.append(time.perf_counter() - start)
    return out


def _rendered(model, poses):
    try:
        from ibvs_sim.world import World
    except ImportError:
        return None, None
    world = World()
    try:
        frames = []
        for q in poses:
            world.reset(q)
            frames.append(world.render_stereo(model.camera))
        world.reset(inverse_kinematics(paper.scenario_start_pose(2)))
        empty = world.render_stereo(model.camera)
        return frames, (empty, world.renderer)
    finally:
        world.close()


def run(report):
    """Time the detection of one stereo pair; see the module docstring."""
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        for resolution, count in FRAMES.items():
            model = _model(resolution)
            detector = StereoDetector(model.camera.intrinsics)
            rng = np.random.default_rng(1)
            poses = scene.in_view_poses(model, count, rng)
            frames, empty = _rendered(model, poses)
            if frames is not None:
                renderer = empty[1]
                for tracking, how in ((False, 'full search'), (True, 'tracking')):
                    report(f'vision: detect pair {resolution} ({how}, {renderer})',
                           _time_detection(detector, frames, tracking))
                report(f'vision: no marker {resolution} (full search, {renderer})',
                       _time_detection(detector, [empty[0]] * count, False))
            synth = [synthetic.render_stereo(model.camera, fiducial_points(q), rng)
                     for q in poses]
            for tracking, how in ((False, 'full search'), (True, 'tracking')):
                report(f'vision: detect pair {resolution} ({how}, synthetic)',
                       _time_detection(detector, synth, tracking))
    finally:
        cv2.setNumThreads(threads)


def main():
    """Print median and p95 of each timing (``python -m ibvs_vision.bench``)."""
    run(print_timing)


if __name__ == '__main__':
    main()
