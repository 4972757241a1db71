"""The film's progress and its summary count the same things by the same names."""

from ibvs_analysis import video
import numpy as np


def test_progress_counts_camera_frames_and_the_summary_names_both_counts():
    stamps = list(np.arange(91) / 30.0)  # a 3 s run's camera frames
    film = sum(video.film_frames(stamps, 3.0, video.DEFAULT_TIME_MAP))
    last = video.progress_line(len(stamps), len(stamps), 12.0)
    assert last.startswith('  video: camera frame 91/91  100.0 %')
    summary = video.summary_line(len(stamps), film)
    assert summary == (f'  video: 91 camera frames, shown as {film} film frames '
                       f'({film / video.FPS:.1f} s at {video.FPS} fps)')
    assert film > len(stamps)  # slowed at the start: the two counts differ, both are named
