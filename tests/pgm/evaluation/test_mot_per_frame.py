"""Per-frame series of :func:`pgm.evaluation.mot.evaluate_mot` (``per_frame``)."""

import json

import numpy as np
import pytest

from pgm.evaluation.mot import evaluate_mot, round_significant
from pgm.io.annotations import MotTable


def _table(rows):
    a = np.array(rows, dtype=float).reshape(-1, 6)
    return MotTable(frames=a[:, 0], ids=a[:, 1], boxes=a[:, 2:6], conf=np.ones(len(a)))


def _walkers(n):
    return [r for f in range(1, n + 1) for r in ((f, 1, 10.0 + 5 * f, 50.0, 40.0, 100.0),
                                                 (f, 2, 300.0 - 5 * f, 60.0, 40.0, 100.0))]


def test_hand_checked_series():
    """Two walkers; the prediction keeps walker 1 exactly in frames 1-3, nothing in 4."""
    gt = _table(_walkers(4))
    pred = _table([(f, 9, x, y, w, h) for f, i, x, y, w, h in _walkers(3) if i == 1])
    r = evaluate_mot(gt, pred)
    pf = r["per_frame"]
    assert pf["frames"] == [1, 2, 3, 4]
    # one of two missed: c (n - m) / n = 50 / 2; all missed: c
    assert pf["ospa_50_1"] == [25.0, 25.0, 25.0, 50.0]
    # ((0 + 100^2) / 2)^(1/2) = 70.71 (4 significant digits), then 100
    assert pf["ospa_100_2"] == [70.71, 70.71, 70.71, 100.0]
    assert pf["gt_cardinality"] == [2, 2, 2, 2] and pf["pred_cardinality"] == [1, 1, 1, 0]
    assert r["ospa_50_1"] == pytest.approx(31.25)
    assert np.mean(pf["ospa_50_1"]) == pytest.approx(r["ospa_50_1"], abs=0)
    assert len(pf["ospa2"]) == 4
    json.dumps(r, allow_nan=False)


def test_series_agree_with_the_means():
    rng = np.random.default_rng(3)
    gt_rows = _walkers(30)
    pred_rows = [(f, i, x + rng.normal(0, 8), y + rng.normal(0, 8), w, h)
                 for f, i, x, y, w, h in gt_rows if rng.random() > 0.2]
    pred_rows += [(f, 50 + f, rng.uniform(0, 500), rng.uniform(0, 300), 40.0, 100.0)
                  for f in range(1, 31) if rng.random() < 0.3]
    r = evaluate_mot(_table(gt_rows), _table(pred_rows), num_frames=32,
                     ospa_params=((50, 1), (100, 2), (20, 1)))
    pf = r["per_frame"]
    assert pf["frames"] == list(range(1, 33))
    for key in ("ospa_50_1", "ospa_100_2", "ospa_20_1", "ospa2"):
        assert len(pf[key]) == 32
        # 4 significant digits: each value within a relative 5e-4, so is the mean
        assert np.mean(pf[key]) == pytest.approx(r[key], rel=5e-4), key
    diff = np.abs(np.array(pf["pred_cardinality"]) - np.array(pf["gt_cardinality"]))
    assert diff.mean() == r["mean_abs_cardinality_error"]
    assert sum(pf["gt_cardinality"]) == r["num_gt"]
    assert sum(pf["pred_cardinality"]) == r["num_pred"]
    assert pf["gt_cardinality"][-2:] == [0, 0]  # frames past the last box are scored
    # the series are left out on request; the other keys are unchanged
    flat = evaluate_mot(_table(gt_rows), _table(pred_rows), num_frames=32,
                        ospa_params=((50, 1), (100, 2), (20, 1)), per_frame=False)
    assert "per_frame" not in flat
    assert flat == {k: v for k, v in r.items() if k != "per_frame"}


def test_round_significant():
    assert round_significant([123456.0, 0.000123456, 1.0, np.nan, np.inf, 0.0]) == \
        [123500.0, 0.0001235, 1.0, None, None, 0.0]
    assert round_significant(2 / 3, digits=2) == [0.67]
