"""The film's parts without a bag: its time map, its frame counts and its magnifier."""

import math

from ibvs_analysis import video
import numpy as np
import pytest


def test_time_map_slows_the_first_second_then_plays_in_real_time():
    m = video.TimeMap.parse('0.25@1,1')
    assert m == video.DEFAULT_TIME_MAP
    assert m.film_s(0.5) == pytest.approx(2.0)
    assert m.film_s(1.0) == pytest.approx(4.0)
    assert m.film_s(3.0) == pytest.approx(6.0)
    assert m.speed_at(0.2) == 0.25 and m.speed_at(1.0) == 1.0
    assert m.describe() == '0.25x real time to 1 s, then 1x'
    fast = video.TimeMap.parse('0.5@0.2,2@1,4')
    assert fast.film_s(2.0) == pytest.approx(0.4 + 0.4 + 0.25)
    assert video.TimeMap.parse('1').segments == ((math.inf, 1.0),)


@pytest.mark.parametrize('text', ['', '0.25@1', '0@1,1', 'fast', '1@2,1@1,1', '1,1',
                                  '-1', 'nan'])
def test_time_map_refuses_malformed_text(text):
    with pytest.raises(ValueError):
        video.TimeMap.parse(text)


def test_film_frames_cover_the_whole_run():
    stamps = np.arange(90) / 30.0  # a 3 s run's camera frames
    counts = video.film_frames(list(stamps), 3.0, video.DEFAULT_TIME_MAP)
    assert sum(counts) == round(6.0 * video.FPS)
    assert counts[:3] == [4, 4, 4]  # a quarter of real time: each frame 4 film frames
    assert set(counts[40:]) == {1}
    faster = video.film_frames(list(stamps), 3.0, video.TimeMap.parse('4'))
    assert abs(sum(faster) - 0.75 * video.FPS) <= 1 and 0 in faster  # the last: one at least


def test_magnifier_enlarges_the_pixels_not_the_drawing():
    image = np.full((720, 1280, 3), 90, np.uint8)
    image[438:443, 638:643] = (200, 40, 40)  # 5 px square in the region, off the crosses
    features = np.array([600.0, 590.0, 400.0, 620.0, 610.0, 420.0])
    panel = video.camera_panel(image, 0, features, features, raw=True)
    inset = panel[-video.INSET_PX - 6:-6, -video.INSET_PX - 6:-6]
    zoom = video.INSET_PX / (2 * video.ZOOM_HALF_PX)
    # the marker's square is enlarged: about 5 * zoom px of its red
    red = np.all(inset == (200, 40, 40), axis=2)
    assert red.any(axis=1).sum() == pytest.approx(5 * zoom, abs=2)
    # the crosses are drawn after: their lines stay 1-2 px thick, not zoom times that
    green = np.all(inset == video.FEATURE_RGB[1], axis=2)
    rows = np.flatnonzero(green.sum(axis=1) >= 10)  # the + of marker 2: its horizontal arm
    assert 1 <= len(rows) <= 2
