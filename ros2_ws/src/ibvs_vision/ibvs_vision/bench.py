"""
Cost of the detector per stereo pair, for ``make bench`` (``ibvs_experiments.bench``).

``run(report)`` calls ``report(name, seconds_list)`` with the wall time of
:meth:`StereoDetector.detect` per stereo pair, OpenCV on one thread, at HD720 and VGA:

- full search (no prior: Hough over every part of the image where a marker colour shows)
  and tracking (prior = the last measurement: windows around it first), on frames rendered
  by the simulator's renderer at random in-view poses (``make bench`` passes it in:
  :func:`ibvs_sim.bench.stereo_frames`; ``python -m ibvs_vision.bench`` alone has none);
- the same on synthetic frames (ibvs_vision.synthetic: shaded spheres on a cluttered,
  noisy background, a harder scene than the simulator's);
- a frame without markers (scenario 2/3 start), searched in full every frame;
- one fit of the camera's stamp offset (:func:`.stamp_offset.fit_stamp_offset`) over a
  1 s window of 30 frames of a rest-to-rest move, the joint states in a
  :class:`ibvs_common.sync.JointTrack` at 250 Hz as the feature node keeps them: the node
  fits every 10 measured frames, so a tenth of it falls on each frame on average.

``python -m ibvs_vision.bench`` prints median and p95 of each. No ROS involved.

``python -m ibvs_vision.bench --calibrate`` measures the cost model of the detector's budget
(:data:`ibvs_vision.detector.budget.COSTS`) again: on synthetic frames and on the hostile
images of the fuzz classes (noise, checkerboard, many circles) at HD720, the wall time of each kind
of step against what the model in use prices it (a ratio: 1 or less where the model is
not too cheap), median and largest; then the wall time of whole detections against their
estimated cost.
"""

import argparse
import math
import time

import cv2
from ibvs_common.bench import print_timing
from ibvs_model import (CameraRobotModel, fiducial_points, inverse_kinematics, IRB4600,
                        look_at, paper, scene, StereoCamera, StereoIntrinsics)
import numpy as np

from . import synthetic
from .detector import budget, StereoDetector
from .detector.refine import refine_circle, window_half
from .stamp_offset import fit_stamp_offset

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


def run(report, render=None):
    """
    Time the detection of one stereo pair; see the module docstring.

    ``render(camera, poses, empty_q)``: ``(frames, empty frame, renderer name)``, the stereo
    pairs of a renderer at each joint vector of ``poses`` and at ``empty_q`` (no marker in
    view), or None to time synthetic frames only. ibvs_vision does not import the simulator
    (docs/design.md §2): ``make bench`` passes :func:`ibvs_sim.bench.stereo_frames`.
    """
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        for resolution, count in FRAMES.items():
            model = _model(resolution)
            detector = StereoDetector(model.camera.intrinsics)
            rng = np.random.default_rng(1)
            poses = scene.in_view_poses(model, count, rng)
            if render is not None:
                frames, empty, renderer = render(
                    model.camera, poses, inverse_kinematics(paper.scenario_start_pose(2)))
                for tracking, how in ((False, 'full search'), (True, 'tracking')):
                    report(f'vision: detect pair {resolution} ({how}, {renderer})',
                           _time_detection(detector, frames, tracking))
                report(f'vision: no marker {resolution} (full search, {renderer})',
                       _time_detection(detector, [empty] * count, False))
            synth = [synthetic.render_stereo(model.camera, fiducial_points(q), rng)
                     for q in poses]
            for tracking, how in ((False, 'full search'), (True, 'tracking')):
                report(f'vision: detect pair {resolution} ({how}, synthetic)',
                       _time_detection(detector, synth, tracking))
    finally:
        cv2.setNumThreads(threads)
    report('vision: stamp offset fit (1 s window, 30 frames; one every 10 frames)',
           _time_offset_fit())


def _time_offset_fit(repeat=10):
    """Time :func:`.stamp_offset.fit_stamp_offset` as the feature node calls it."""
    from ibvs_common.sync import JointTrack
    model = _model('HD720')
    q0 = inverse_kinematics(paper.target_pose())
    move = np.array([0.5, 0.15, -0.1, 0.2, 0.1, 0.3])

    def q_of(t_s):
        x = min(max((t_s - 0.2) / 0.8, 0.0), 1.0)
        return q0 + move * (x * x * (3.0 - 2.0 * x))
    track = JointTrack(horizon_ns=2_000_000_000)
    for t_ns in range(0, 1_500_000_000, 4_000_000):
        track.add(t_ns, q_of(t_ns * 1e-9))
    stamps = [int(e * 1e9) + 33_000_000 for e in np.arange(0.2, 1.2, 1 / 30)]
    features = np.array([model.features(q_of(t * 1e-9 - 0.033)) for t in stamps])
    out = []
    for _ in range(repeat):
        start = time.perf_counter()
        fit_stamp_offset(stamps, features, lambda t: track.at(t)[0], model.features_batch)
        out.append(time.perf_counter() - start)
    return out


def _best_of(repeat, func, *args):
    """Return (the least wall time of ``repeat`` calls, s; the last result)."""
    best, out = math.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        out = func(*args)
        best = min(best, time.perf_counter() - start)
    return best, out


def _calibration_images(model, rng):
    k = model.camera.intrinsics
    images = {f'synthetic {i}': synthetic.render_stereo(model.camera, fiducial_points(q), rng)[0]
              for i, q in enumerate(scene.in_view_poses(model, 3, rng))}
    for kind in synthetic.HOSTILE_KINDS:
        images[kind] = synthetic.hostile_image(kind, k.width, k.height, rng)
    noisy = images['synthetic 0'].astype(float) + rng.normal(0.0, 0.1 * 255.0,
                                                             images['synthetic 0'].shape)
    images['synthetic 0, noise 0.1'] = np.clip(np.round(noisy), 0, 255).astype(np.uint8)
    return images


def calibrate(max_hough_edges: int = 6000) -> dict[str, list[float]]:
    """
    Measure the detector's cost model again and print it (module docstring).

    Hough windows with more than ``max_hough_edges`` edge pixels are left out (seconds
    each). Returns, per kind of COSTS, the measured wall time of each step over its price.
    """
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        model = _model('HD720')
        detector = StereoDetector(model.camera.intrinsics)
        rng = np.random.default_rng(3)
        measured = {kind: [] for kind in ('score', 'hot', 'edges', 'hough', 'refine')}
        whole = []
        for name, image in _calibration_images(model, rng).items():
            pixels = image.shape[0] * image.shape[1]
            seconds, scores = _best_of(REPEAT, detector._selective, image, 'rgb8')
            measured['score'].append(seconds * 1e3 / budget.pass_cost_ms('score', pixels))
            for k in range(2):
                seconds, regions = _best_of(REPEAT, detector._hot_regions, scores[k])
                measured['hot'].append(seconds * 1e3 / budget.pass_cost_ms('hot', pixels))
                size = 129  # a window of the search near a prediction (roi_margin_px 40)
                y0, x0 = (int(rng.integers(0, n - size)) for n in image.shape[:2])
                windows = [(x0, y0, x0 + size, y0 + size)] + list(regions)
                for x0, y0, x1, y1 in windows:
                    window = np.ascontiguousarray(scores[k][y0:y1, x0:x1])
                    _calibrate_window(detector, image, k, window, (x0, y0, x1, y1),
                                      measured, max_hough_edges)
            seconds, result = _best_of(1, detector.detect, image, image)
            whole.append((name, seconds * 1e3, result.cost_ms))
        print(f'{"kind":8s} {"ns/unit, ns/call in use":>24s} {"median":>8s} {"largest":>8s}'
              '   wall time over price')
        for kind, values in measured.items():
            per_unit, per_call = budget.COSTS[kind]
            print(f'{kind:8s} {per_unit:14.2f} {per_call:9.0f} {np.median(values):8.2f} '
                  f'{np.max(values):8.2f}   ({len(values)} steps)')
        print('whole detections (left image as both, full search): wall / estimated ms')
        for name, wall_ms, cost_ms in whole:
            print(f'  {name:28s} {wall_ms:9.2f} / {cost_ms:9.2f}')
        return measured
    finally:
        cv2.setNumThreads(threads)


def _calibrate_window(detector, image, k, window, bounds, measured, max_hough_edges):
    """Time the edges, the Hough transform and the refinements of one search window."""
    cfg = detector.config
    pixels = window.size

    def edges(w):
        blurred = cv2.GaussianBlur(w, (3, 3), 0)
        return blurred, cv2.countNonZero(cv2.Canny(blurred, max(1.0, 0.5 * cfg.hough_canny_high),
                                                   cfg.hough_canny_high))

    seconds, (blurred, count) = _best_of(REPEAT, edges, window)
    measured['edges'].append(seconds * 1e3 / budget.pass_cost_ms('edges', pixels))
    if count == 0 or count > max_hough_edges:
        return
    seconds, circles = _best_of(1, cv2.HoughCircles, blurred, cv2.HOUGH_GRADIENT, 1,
                                max(4.0, 2.0 * cfg.hough_min_radius_px), None,
                                cfg.hough_canny_high, cfg.hough_votes,
                                cfg.hough_min_radius_px, cfg.hough_max_radius_px)
    measured['hough'].append(seconds * 1e3 / budget.hough_cost_ms(count, pixels))
    if circles is None:
        return
    for u, v, r in circles[0, :cfg.max_candidates]:
        side = 2 * window_half(r) + 1
        seconds, _ = _best_of(REPEAT, refine_circle, image, 'rgb8', k, float(u + bounds[0]),
                              float(v + bounds[1]), float(r), bounds, cfg,
                              detector.intrinsics)
        measured['refine'].append(seconds * 1e3 / budget.pass_cost_ms('refine', side ** 2))


def main():
    """Print median and p95 of each timing, or the cost model with ``--calibrate``."""
    parser = argparse.ArgumentParser(prog='python -m ibvs_vision.bench',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('--calibrate', action='store_true',
                        help="measure the detector budget's cost model again")
    if parser.parse_args().calibrate:
        calibrate()
    else:
        run(print_timing)


if __name__ == '__main__':
    main()
