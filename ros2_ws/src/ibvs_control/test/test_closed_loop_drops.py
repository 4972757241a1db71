"""The model loop's lost frames and taught-target noise (the benchmark's imperfections)."""

from ibvs_control.closed_loop import LoopConfig, simulate
import numpy as np
import pytest


def test_without_drops_or_target_noise_the_loop_is_unchanged():
    config = LoopConfig(target_features_source='taught')
    a = simulate(config, 0.4, feature_noise_px=0.1, seed=3)
    b = simulate(config, 0.4, feature_noise_px=0.1, seed=3, frame_drop_probability=0.0,
                 target_noise_px=0.0)
    np.testing.assert_array_equal(a.q, b.q)
    assert a.dropped_frames == b.dropped_frames == 0


def test_a_lost_frame_holds_the_feedback_and_is_counted():
    config = LoopConfig()
    full = simulate(config, 1.0)
    lossy = simulate(config, 1.0, frame_drop_probability=0.3, seed=5)
    frames = full.frame_t.size
    assert lossy.dropped_frames + lossy.frame_t.size == frames
    assert 0.15 * frames < lossy.dropped_frames < 0.45 * frames
    assert not np.array_equal(full.q, lossy.q)
    # seeded: the same frames are lost again
    again = simulate(config, 1.0, frame_drop_probability=0.3, seed=5)
    np.testing.assert_array_equal(again.q, lossy.q)
    with pytest.raises(ValueError, match='frame_drop_probability'):
        simulate(config, 0.1, frame_drop_probability=1.0)


def test_the_taught_target_gets_its_noise_once():
    config = LoopConfig(target_features_source='taught')
    clean = simulate(config, 0.1)
    noisy = simulate(config, 0.1, target_noise_px=0.05, seed=2)
    offset = noisy.p_target - clean.p_target
    assert 0.0 < np.abs(offset).max() < 0.3
    np.testing.assert_array_equal(simulate(config, 0.1, target_noise_px=0.05,
                                           seed=2).p_target, noisy.p_target)
    assert simulate(LoopConfig(), 0.1, target_noise_px=0.05).p_target is not None


def test_the_envelope_counts_reach_the_result():
    on = simulate(LoopConfig(safety_envelope=True), 0.3)
    assert on.interventions and all(isinstance(k, int) for k in on.interventions)
    assert simulate(LoopConfig(), 0.3).interventions == {}
