"""Tests for pgm.evaluation.single_object (OTB single-object metrics)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from pgm.core.boxes import iou_xywh
from pgm.core.errors import InputError
from pgm.evaluation.single_object import (
    PRECISION_THRESHOLDS,
    SUCCESS_THRESHOLDS,
    precision_at,
    single_object_metrics,
    success_auc,
)
from pgm.io.annotations import SingleTrack


def _gt(n: int = 5) -> SingleTrack:
    frames = np.arange(1, n + 1)
    boxes = np.column_stack([10.0 * frames, np.full(n, 5.0), np.full(n, 20.0),
                             np.full(n, 40.0)])
    return SingleTrack(frames=frames, boxes=boxes)


def test_iou_of_known_boxes() -> None:
    a = np.array([[0.0, 0.0, 10.0, 10.0]])
    assert iou_xywh(a, np.array([[5.0, 0.0, 10.0, 10.0]]))[0] == pytest.approx(50 / 150)
    assert iou_xywh(a, np.array([[5.0, 5.0, 10.0, 10.0]]))[0] == pytest.approx(25 / 175)
    assert iou_xywh(a, np.array([[10.0, 0.0, 10.0, 10.0]]))[0] == 0.0
    assert iou_xywh(a, np.array([[2.0, 2.0, 5.0, 5.0]]))[0] == pytest.approx(25 / 100)


def test_thresholds() -> None:
    assert SUCCESS_THRESHOLDS.shape == (21,) and SUCCESS_THRESHOLDS[0] == 0.0
    assert SUCCESS_THRESHOLDS[-1] == 1.0 and SUCCESS_THRESHOLDS[3] == 0.15
    np.testing.assert_array_equal(PRECISION_THRESHOLDS, np.arange(51))


def test_perfect_prediction_is_20_over_21() -> None:
    gt = _gt()
    m = single_object_metrics(gt, gt.frames, gt.boxes)
    # strict IoU > t with t = 1 included: OTB's convention caps the AUC at 20/21
    assert m["success_auc"] == pytest.approx(20 / 21, abs=1e-15)
    assert m["success_curve"] == [1.0] * 20 + [0.0]
    assert m["precision_at_20"] == 1.0 and m["mean_iou"] == 1.0
    assert m["mean_centre_error"] == 0.0 and m["median_centre_error"] == 0.0
    assert m["n_frames"] == 5 and m["n_missing"] == 0
    assert len(m["precision_curve"]) == 51 and m["precision_curve"][0] == 1.0
    assert m["thresholds"]["success"] == [k / 20 for k in range(21)]
    json.dumps(m, allow_nan=False)  # plain, strictly JSON-serialisable


def test_perfect_prediction_with_awkward_floats() -> None:
    # (x + w) - x != w in floating point: IoU must still be clipped to 1
    box = [636.9616873214543, 606.9953714589552, 1.4406385815360345, 4.844360818834428]
    gt = SingleTrack(frames=[1, 2], boxes=[box, [10.0, 20.0, 30.0, 40.0]])
    assert iou_xywh(gt.boxes, gt.boxes)[0] == 1.0  # unclipped, this one would exceed 1
    m = single_object_metrics(gt, gt.frames, gt.boxes)
    assert m["success_auc"] == pytest.approx(20 / 21, abs=1e-15)
    assert max(m["ious"]) <= 1.0


def test_precision_with_known_offset() -> None:
    gt = _gt(4)
    pred = gt.boxes.copy()
    pred[:, 0] += [0.0, 12.0, 20.0, 25.0]        # centre errors 0, 12, 20, 25
    pred[1, 1] += 16.0                           # frame 2: sqrt(12^2 + 16^2) = 20
    m = single_object_metrics(gt, gt.frames, pred)
    np.testing.assert_allclose(m["centre_errors"], [0.0, 20.0, 20.0, 25.0])
    assert m["precision_at_20"] == 0.75          # <= 20 counts
    assert m["mean_centre_error"] == pytest.approx(65 / 4)
    assert m["median_centre_error"] == pytest.approx(20.0)
    assert precision_at([0.0, 20.0, 20.0, 25.0], 19.9) == 0.25
    assert m["precision_curve"][25] == 1.0 and m["precision_curve"][19] == 0.25


def test_missing_prediction() -> None:
    gt = _gt(4)
    keep = [0, 2, 3]                                  # frame 2 not predicted
    pred_frames = np.append(gt.frames[keep], 99)      # an extra, unannotated frame
    pred_boxes = np.vstack([gt.boxes[keep], [[0, 0, 1, 1]]])
    m = single_object_metrics(gt, pred_frames[::-1], pred_boxes[::-1])  # any order
    assert m["n_frames"] == 4 and m["n_missing"] == 1
    assert m["ious"] == [1.0, 0.0, 1.0, 1.0]
    assert m["centre_errors"] == [0.0, None, 0.0, 0.0]
    assert m["precision_at_20"] == 0.75
    assert m["mean_centre_error"] == 0.0              # inf left out of the mean
    assert m["mean_iou"] == 0.75
    assert m["success_auc"] == pytest.approx(0.75 * 20 / 21)
    json.dumps(m, allow_nan=False)


def test_no_prediction_at_all() -> None:
    m = single_object_metrics(_gt(3), np.zeros(0, dtype=int), np.zeros((0, 4)))
    assert m["n_missing"] == 3 and m["success_auc"] == 0.0 and m["precision_at_20"] == 0.0
    assert m["mean_centre_error"] is None and m["median_centre_error"] is None
    json.dumps(m, allow_nan=False)


def test_non_finite_prediction_is_missing() -> None:
    gt = _gt(2)
    pred = gt.boxes.copy()
    pred[1] = np.nan
    m = single_object_metrics(gt, gt.frames, pred)
    assert m["n_missing"] == 1 and m["ious"] == [1.0, 0.0]


def test_bad_inputs() -> None:
    gt = _gt(3)
    with pytest.raises(InputError):
        single_object_metrics(gt, [1, 1], gt.boxes[:2])
    with pytest.raises(InputError):
        single_object_metrics(gt, [1, 2], gt.boxes)
    with pytest.raises(InputError):
        single_object_metrics(SingleTrack(np.zeros(0), np.zeros((0, 4))), [1], gt.boxes[:1])
    with pytest.raises(InputError):
        success_auc([])


def test_success_auc_small_cases() -> None:
    assert success_auc([0.0]) == 0.0
    assert success_auc([1.0]) == pytest.approx(20 / 21)
    assert success_auc([0.5]) == pytest.approx(10 / 21)    # passes t = 0 .. 0.45
    assert success_auc([0.51]) == pytest.approx(11 / 21)


_unit = st.floats(min_value=0.0, max_value=1.0, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(hnp.arrays(float, st.integers(1, 40), elements=_unit))
def test_auc_property(ious: np.ndarray) -> None:
    auc = success_auc(ious)
    assert 0.0 <= auc <= 1.0
    # exact: each frame passes #{k : iou > k/20} of the 21 thresholds
    passes = [sum(1 for k in range(21) if u > k / 20) for u in ious.tolist()]
    assert auc == pytest.approx(sum(passes) / (21 * len(passes)), abs=1e-12)
    # IoU-derived bound: that count is ceil(20 u), so 20 u <= count < 20 u + 1
    mean_iou = float(np.mean(ious))
    assert 20 / 21 * mean_iou - 1e-9 <= auc < 20 / 21 * mean_iou + 1 / 21 + 1e-9


_coord = st.floats(min_value=-50.0, max_value=50.0, allow_nan=False)
_size = st.floats(min_value=0.5, max_value=40.0, allow_nan=False)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(_coord, _coord, _size, _size, _coord, _coord, _size, _size),
                min_size=1, max_size=20))
def test_metrics_property_random_boxes(rows: list[tuple[float, ...]]) -> None:
    arr = np.array(rows)
    frames = np.arange(1, len(rows) + 1)
    gt = SingleTrack(frames=frames, boxes=arr[:, :4])
    m = single_object_metrics(gt, frames, arr[:, 4:])
    ious = np.clip(iou_xywh(arr[:, :4], arr[:, 4:]), 0, 1)
    assert 0.0 <= m["success_auc"] <= 1.0
    assert m["success_auc"] == pytest.approx(success_auc(ious), abs=1e-12)
    assert m["mean_iou"] == pytest.approx(float(np.mean(ious)), abs=1e-12)
    assert 0.0 <= m["precision_at_20"] <= 1.0
    assert np.all(np.diff(m["success_curve"]) <= 0)
    assert np.all(np.diff(m["precision_curve"]) >= 0)
