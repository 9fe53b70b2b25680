"""Reliability diagram, ECE and Brier on a hand-worked example."""

import numpy as np
import pytest

from pgm.evaluation.calibration import confidence_outcomes, reliability, video_weights


def test_hand_worked_reliability():
    # bin [0.1, 0.2): two frames at 0.15, one hit -> gap |0.15 - 0.5| = 0.35
    # bin [0.8, 0.9): four frames at 0.85, three hits -> gap |0.85 - 0.75| = 0.10
    # bin [0.9, 1.0]: two frames at 1.0, two hits -> gap 0
    c = [0.15, 0.15, 0.85, 0.85, 0.85, 0.85, 1.0, 1.0]
    y = [1, 0, 1, 1, 1, 0, 1, 1]
    r = reliability(c, y)
    assert [b["n"] for b in r["bins"]] == [2, 4, 2]
    assert r["bins"][0]["lo"] == pytest.approx(0.1) and r["bins"][2]["hi"] == 1.0
    assert r["ece"] == pytest.approx((2 * 0.35 + 4 * 0.10 + 0) / 8)
    brier = (0.85**2 + 0.15**2 + 3 * 0.15**2 + 0.85**2 + 0 + 0) / 8
    assert r["brier"] == pytest.approx(brier)
    assert r["hit_rate"] == pytest.approx(6 / 8)


def test_a_calibrated_forecaster_has_a_small_ece():
    rng = np.random.default_rng(0)
    c = rng.uniform(0, 1, 20000)
    y = rng.uniform(0, 1, 20000) < c
    r = reliability(c, y)
    # per bin the hit rate's standard error is about sqrt(0.25 / 2000) ~ 0.011
    assert r["ece"] < 0.03
    assert reliability(np.full(20000, 0.9), y)["ece"] == pytest.approx(0.9 - y.mean())


def test_weights_count_every_video_equally():
    """Hand-worked: video A has four frames at 0.9, all hits; video B one frame at 0.9,
    a miss. Frames pooled: hit rate 4/5, gap 0.1. Videos weighted equally (1/4 per frame
    of A, 1 for B's): hit rate 1/2, gap 0.4 — and weights of 1 give the unweighted
    diagram."""
    c = np.full(5, 0.9)
    y = np.array([1, 1, 1, 1, 0])
    assert reliability(c, y)["ece"] == pytest.approx(0.1)
    r = reliability(c, y, weights=[0.25, 0.25, 0.25, 0.25, 1.0])
    assert r["hit_rate"] == pytest.approx(0.5) and r["ece"] == pytest.approx(0.4)
    assert r["brier"] == pytest.approx(0.5 * 0.01 + 0.5 * 0.81)
    assert r["n"] == 5 and r["bins"][0]["n"] == 5 and r["bins"][0]["share"] == pytest.approx(1)
    rng = np.random.default_rng(1)
    c, y = rng.uniform(0, 1, 50), rng.uniform(0, 1, 50) < 0.5
    assert reliability(c, y, weights=np.ones(50)) == reliability(c, y)
    for bad in ([1.0] * 4, [1.0, 1.0, 1.0, -1.0, 1.0], [0.0] * 5, [np.nan] * 5):
        with pytest.raises(ValueError, match="weights"):
            reliability(np.full(5, 0.9), [1, 1, 1, 1, 0], weights=bad)


def test_video_weights_give_every_video_the_same_total():
    """Three frames of one video and one of another: each video's weights sum to the
    same total, and the weights average 1 (a fit's L2 penalty keeps its strength)."""
    w = video_weights(np.array(["long", "long", "long", "short"]))
    np.testing.assert_allclose(w, [2 / 3, 2 / 3, 2 / 3, 2.0])
    np.testing.assert_allclose(w[:3].sum(), w[3:].sum())
    np.testing.assert_allclose(w.mean(), 1.0)
    with pytest.raises(ValueError, match="no frames"):
        video_weights(np.array([], dtype=str))


def test_confidence_outcomes_pair_the_scored_frames():
    """Confidence on frames 1-4; truth scored on frames 2, 4 and 5 (IoU 0.6, no box,
    0.3): frames 2 and 4 pair, a hit and a miss; frame 5 has no confidence."""
    c, hit = confidence_outcomes([1, 2, 3, 4], [0.9, 0.8, 0.7, 0.6], [2, 4, 5],
                                 [0.6, np.nan, 0.3])
    np.testing.assert_array_equal(c, [0.8, 0.6])
    np.testing.assert_array_equal(hit, [True, False])
    with pytest.raises(ValueError, match="3 confidences for 4 frames"):
        confidence_outcomes([1, 2, 3, 4], [0.9, 0.8, 0.7], [2], [0.6])
    with pytest.raises(ValueError, match="1 IoUs for 2 scored frames"):
        confidence_outcomes([1], [0.9], [1, 2], [0.6])


def test_bad_input_is_refused():
    for c, y in (([0.5], [1, 0]), ([1.5], [1]), ([np.nan], [1]), ([0.5], [2]), ([], [])):
        with pytest.raises(ValueError):
            reliability(c, y)
