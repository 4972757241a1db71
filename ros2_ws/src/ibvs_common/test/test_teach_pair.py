"""The taught pair's rule: the pixelwise mean of 8-bit pairs, rounded to 8 bits."""

from ibvs_common.teach import FrameMean
import numpy as np
import pytest


def test_the_mean_of_pairs_is_the_rounded_pixelwise_mean_in_any_order():
    rng = np.random.default_rng(1)
    pairs = [tuple(rng.integers(0, 256, (4, 5, 3), dtype=np.uint8) for _ in range(2))
             for _ in range(7)]
    mean = FrameMean()
    for pair in pairs:
        mean.add(pair)
    backwards = FrameMean()
    for pair in reversed(pairs):
        backwards.add(pair)
    expected = [np.rint(np.mean([p[i].astype(float) for p in pairs], axis=0)).astype(np.uint8)
                for i in range(2)]
    got = mean.mean()
    assert mean.count == 7 and all(g.dtype == np.uint8 for g in got)
    for g, b, e in zip(got, backwards.mean(), expected):
        assert np.array_equal(g, e) and np.array_equal(b, e)


def test_one_frame_is_itself_and_no_frame_or_another_size_is_refused():
    image = np.arange(60, dtype=np.uint8).reshape(4, 5, 3)
    mean = FrameMean()
    with pytest.raises(ValueError, match='no frame'):
        mean.mean()
    mean.add((image, image))
    assert all(np.array_equal(m, image) for m in mean.mean())
    with pytest.raises(ValueError, match='shapes'):
        mean.add((image, image[:2]))
