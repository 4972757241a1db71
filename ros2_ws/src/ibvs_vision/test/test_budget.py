"""
The detector's budget per stereo pair (detector.budget): pure, no ROS, no clock.

Every test judges the budget by the work it counts and prices, never by the wall clock: a
full-size noisy pair, a checkerboard and a crowd of circles each stop within the budget of a
30 Hz frame, and every Hough transform and refinement that ran was paid for first (the
calls are recorded at OpenCV and where each circle's object is found, and priced again
here). The search near a prediction finds what the whole-image search finds, and a budget
that is not exhausted changes no result.
"""

import math

import cv2
from ibvs_model import fiducial_points, scene
from ibvs_vision import synthetic
from ibvs_vision.detector import budget as budget_module, Reason, StereoDetector
from ibvs_vision.detector import stereo as stereo_module
from ibvs_vision.detector.budget import hough_cost_ms, OverBudget, pass_cost_ms, WorkBudget
import numpy as np
import pytest

#: What the feature node gives a pair at 30 Hz by default (detection_budget_share 0.5).
BUDGET_MS = 0.5 * 1e3 / 30.0


class Recorder:
    """Record each Hough transform and refinement the detector runs, and price it."""

    def __init__(self, monkeypatch, canny_high):
        self.hough_ms = []
        self.refine_ms = []
        hough, refine = cv2.HoughCircles, stereo_module.find_object

        def recorded_hough(image, *args, **kwargs):
            edges = cv2.countNonZero(cv2.Canny(image, max(1.0, 0.5 * canny_high),
                                               canny_high))
            self.hough_ms.append(hough_cost_ms(edges, image.size))
            return hough(image, *args, **kwargs)

        def recorded_refine(image, encoding, k, u, v, r, *args):
            side = 2 * int(math.ceil(2.0 * r + 6.0)) + 1
            self.refine_ms.append(pass_cost_ms('refine', side * side))
            return refine(image, encoding, k, u, v, r, *args)

        monkeypatch.setattr(cv2, 'HoughCircles', recorded_hough)
        monkeypatch.setattr(stereo_module, 'find_object', recorded_refine)


def test_a_budget_pays_until_a_step_would_overrun_it_and_spends_nothing_on_that_one():
    budget = WorkBudget(10.0)
    budget.pay(4.0, 'first')
    budget.pay(6.0, 'second')  # exactly the limit
    with pytest.raises(OverBudget, match='third would cost 0.50 ms with 10.00 of 10.00'):
        budget.pay(0.5, 'third')
    assert budget.spent_ms == 10.0 and budget.steps == 2
    assert budget.refused.startswith('third')
    unlimited = WorkBudget()
    unlimited.pay(1e9, 'anything')
    assert unlimited.spent_ms == 1e9
    for bad in (0.0, -1.0, float('nan'), float('inf')):
        with pytest.raises(ValueError, match='limit_ms'):
            WorkBudget(bad)


def test_the_hough_price_grows_with_the_edge_pixels_to_the_power_one_and_a_half():
    """Four times the edge pixels cost eight times as much (the centres' stage, measured)."""
    base = hough_cost_ms(1000, 0)
    assert hough_cost_ms(4000, 0) == pytest.approx(8.0 * base)
    assert budget_module.HOUGH_EXPONENT == 1.5
    # The pixels of the window add a little.
    assert hough_cost_ms(1000, 10_000) > base


@pytest.mark.parametrize('kind', synthetic.HOSTILE_KINDS)
def test_a_hostile_full_size_pair_stops_within_the_budget(kind, hd_model, monkeypatch):
    """
    Noise, a checkerboard, a crowd of circles: the pair stops within its budget, unmeasured.

    Unbounded, one noisy HD720 pair's Hough search lasts many frame periods. Searched in full
    (no prediction) and near a prediction, the pair ends with Reason.OVER_BUDGET, its
    estimated cost within the budget, and the Hough transforms and refinements that did
    run cost, priced again here, no more than what the detector paid.
    """
    rng = np.random.default_rng(5)
    k = hd_model.camera.intrinsics
    left, right = (synthetic.hostile_image(kind, k.width, k.height, rng) for _ in range(2))
    detector = StereoDetector(k)
    prediction = np.array([400.0, 370.0, 300.0, 420.0, 390.0, 330.0])
    for prior in (None, prediction):
        recorder = Recorder(monkeypatch, detector.config.hough_canny_high)
        result = detector.detect(left, right, prior=prior, budget_ms=BUDGET_MS)
        assert result.reason is Reason.OVER_BUDGET, (kind, prior, result.detail)
        assert 'would cost' in result.detail
        assert 0.0 < result.cost_ms <= BUDGET_MS
        ran = sum(recorder.hough_ms) + sum(recorder.refine_ms)
        assert ran <= result.cost_ms + 1e-9, (kind, ran, result.cost_ms)


def test_without_a_budget_the_same_noisy_search_would_cost_seconds(hd_model):
    """The budget is what bounds the search: the price of what it refused is seconds."""
    rng = np.random.default_rng(5)
    k = hd_model.camera.intrinsics
    image = synthetic.hostile_image('noise', k.width, k.height, rng)
    detector = StereoDetector(k)
    with pytest.raises(OverBudget) as refused:
        detector.detect_image(image, budget=WorkBudget(BUDGET_MS))
    cost_ms = float(str(refused.value).split(' would cost ')[1].split(' ms')[0])
    assert cost_ms > 1000.0, refused.value


@pytest.fixture(scope='module')
def frames(hd_model):
    rng = np.random.default_rng(11)
    out = []
    for q in scene.in_view_poses(hd_model, 12, rng):
        points = fiducial_points(q)
        out.append((hd_model.camera.project(points).reshape(6),
                    synthetic.render_stereo(hd_model.camera, points, rng)))
    return out


def test_the_search_near_the_prediction_finds_what_the_whole_images_give(frames, hd_model):
    """
    Around a prediction a few pixels off, the windows give the full search's p_I, cheaper.

    The prediction is the truth moved by up to 10 px (a model error, a frame's motion).
    """
    detector = StereoDetector(hd_model.camera.intrinsics)
    rng = np.random.default_rng(3)
    for truth, (left, right) in frames:
        full = detector.detect(left, right, budget_ms=BUDGET_MS)
        assert full.ok and full.search == 'full', full.detail
        prior = truth + np.repeat(rng.uniform(-10.0, 10.0, (2, 2)), [2, 1], axis=1).ravel()
        near = detector.detect(left, right, prior=prior, budget_ms=BUDGET_MS)
        assert near.ok and near.search == 'roi', near.detail
        assert np.allclose(near.features, full.features, atol=1e-6), near.features - full.features
        assert near.cost_ms < full.cost_ms


def test_a_budget_not_exhausted_changes_no_result(frames, hd_model):
    """The budget only counts: with or without it, the same features to the bit."""
    detector = StereoDetector(hd_model.camera.intrinsics)
    for truth, (left, right) in frames[:4]:
        for prior in (None, truth):
            free = detector.detect(left, right, prior=prior)
            bounded = detector.detect(left, right, prior=prior, budget_ms=BUDGET_MS)
            assert np.array_equal(free.features, bounded.features)
            assert free.cost_ms == bounded.cost_ms <= BUDGET_MS


def test_a_noisy_pair_whose_markers_are_where_predicted_is_measured_within_budget(hd_model):
    """
    The search near the prediction comes first and costs less than the whole images'.

    A noisy pair (0.05 of the range) that both searches measure without a limit; with a
    budget between the two costs, the whole images are refused and the windows around
    the prediction still measure the markers.
    """
    rng = np.random.default_rng(2)
    q = scene.in_view_poses(hd_model, 1, rng)[0]
    points = fiducial_points(q)
    truth = hd_model.camera.project(points).reshape(6)
    left, right = synthetic.render_stereo(hd_model.camera, points, rng, clutter=0,
                                          noise_sigma=0.05 * 255.0)
    detector = StereoDetector(hd_model.camera.intrinsics)
    full = detector.detect(left, right)
    near = detector.detect(left, right, prior=truth)
    assert full.ok and near.ok and near.search == 'roi'
    assert near.cost_ms < full.cost_ms
    budget_ms = 0.5 * (near.cost_ms + full.cost_ms)
    assert detector.detect(left, right, budget_ms=budget_ms).reason is Reason.OVER_BUDGET
    bounded = detector.detect(left, right, prior=truth, budget_ms=budget_ms)
    assert np.array_equal(bounded.features, near.features)
    assert np.abs(near.features - truth).max() < 0.1
