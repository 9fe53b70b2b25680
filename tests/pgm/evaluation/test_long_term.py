"""Absent frames and the long-term measures (pgm.io.annotations, pgm.evaluation.single_object):
UAV123's NaN rows read as "absent" (not "unannotated"); tracking precision, recall and
F-score (Lukežič et al.) against a direct per-threshold computation; the absence signal."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pgm.core.boxes import iou_xywh
from pgm.core.errors import InputError
from pgm.evaluation.single_object import (
    absence_signal,
    long_term_metrics,
    single_object_metrics,
)
from pgm.io.annotations import SingleTrack, load_single_gt


def test_nan_rows_are_absent_and_zero_rows_unannotated(tmp_path: Path) -> None:
    p = tmp_path / "groundtruth_rect.txt"
    p.write_bytes(b"10\t20\t30\t40\r\nNaN,NaN,NaN,NaN\r\n0 0 0 0\r\n11,21,30,40\r\n")
    gt = load_single_gt(p)
    assert gt.frames.tolist() == [1, 4] and gt.absent.tolist() == [2]
    np.testing.assert_array_equal(gt.boxes[0], [9.0, 19.0, 30.0, 40.0])  # 1-based -> 0-based
    assert gt.until(1).absent.size == 0 and gt.since(2).absent.tolist() == [2]
    with pytest.raises(ValueError, match="both"):
        SingleTrack([1], [[0, 0, 1, 1]], absent=[1])
    (tmp_path / "all_nan.txt").write_text("NaN,NaN,NaN,NaN\n")
    with pytest.raises(InputError, match="no annotated box"):
        load_single_gt(tmp_path / "all_nan.txt", "otb")


def _direct(gt: SingleTrack, frames, boxes, conf) -> float:
    """The F-score by its definition: every threshold, every frame, one at a time."""
    best = 0.0
    by_frame = dict(zip(frames.tolist(), zip(boxes.tolist(), conf.tolist(), strict=True),
                        strict=True))
    truth = dict(zip(gt.frames.tolist(), gt.boxes.tolist(), strict=True))
    scored = sorted(set(truth) | set(gt.absent.tolist()))
    for tau in sorted(set(conf.tolist())):
        hits, reported = 0.0, 0
        for t in scored:
            if t in by_frame and by_frame[t][1] >= tau:
                reported += 1
                if t in truth:
                    hits += float(iou_xywh(np.array([truth[t]]), np.array([by_frame[t][0]]))[0])
        pr = hits / reported if reported else 0.0
        re = hits / len(truth)
        best = max(best, 2 * pr * re / (pr + re) if pr + re > 0 else 0.0)
    return best


def test_long_term_f_score_is_its_definition() -> None:
    rng = np.random.default_rng(7)
    for _ in range(20):
        n = 40
        absent = np.sort(rng.choice(np.arange(1, n + 1), 12, replace=False))
        visible = np.setdiff1d(np.arange(1, n + 1), absent)
        gt_boxes = np.column_stack([rng.uniform(0, 100, (visible.size, 2)),
                                    rng.uniform(10, 30, (visible.size, 2))])
        gt = SingleTrack(visible, gt_boxes, absent=absent)
        frames = np.arange(1, n + 1)[rng.random(n) > 0.1]  # some frames without a box
        boxes = np.column_stack([rng.uniform(0, 100, (frames.size, 2)),
                                 rng.uniform(10, 30, (frames.size, 2))])
        near = np.isin(frames, visible)
        idx = np.searchsorted(visible, frames[near])
        boxes[near] = gt_boxes[idx] + rng.normal(0, 3, (near.sum(), 4)) * [1, 1, 0.2, 0.2]
        conf = np.round(rng.random(frames.size), 1)  # ties between thresholds
        got = long_term_metrics(gt, frames[::-1], boxes[::-1], conf[::-1])  # any order
        assert got["f_score"] == pytest.approx(_direct(gt, frames, boxes, conf), abs=1e-12)
        assert got["n_visible"] == visible.size and got["n_absent"] == 12


def test_reporting_absence_pays_in_precision_not_recall() -> None:
    """A tracker that reports a box on the absent frames too loses precision only; one
    whose confidence drops there reaches F = 1 at the right threshold."""
    gt = SingleTrack([1, 2, 3], [[0, 0, 10, 10]] * 3, absent=[4, 5, 6])
    frames, boxes = np.arange(1, 7), np.array([[0, 0, 10, 10]] * 6, float)
    always = long_term_metrics(gt, frames, boxes)
    assert always["precision"] == pytest.approx(0.5) and always["recall"] == pytest.approx(1.0)
    assert always["threshold"] is None and always["n_reported"] == 6
    knows = long_term_metrics(gt, frames, boxes, [0.9, 0.8, 0.9, 0.1, 0.2, 0.1])
    assert knows["f_score"] == pytest.approx(1.0) and knows["threshold"] == pytest.approx(0.8)
    m = single_object_metrics(gt, frames, boxes, [0.9, 0.8, 0.9, 0.1, 0.2, 0.1])
    assert m["n_frames"] == 3 and m["n_absent"] == 3 and m["long_term"] == knows
    assert m["absence"]["precision"] == 1.0 and m["absence"]["recall"] == 1.0
    a = absence_signal(gt, frames, [0.9, 0.3, 0.9, 0.1, 0.6, 0.1], threshold=0.5)
    assert (a["flagged"], a["absent"]) == (3, 3)
    assert a["precision"] == pytest.approx(2 / 3) and a["recall"] == pytest.approx(2 / 3)
    no_absent = single_object_metrics(SingleTrack([1, 2], [[0, 0, 10, 10]] * 2),
                                      [1, 2], [[0, 0, 10, 10]] * 2)
    assert "long_term" not in no_absent and "absence" not in no_absent


def test_the_shared_sequences_read_as_their_sources_say(shared_data: Path) -> None:
    """UAV10-group3: 90 boxes and 35 NaN rows, absent on lines 31-65; Girl: tab-separated
    with CRLF, 500 boxes; Biker and MotorRolling: commas."""
    uav = load_single_gt(shared_data / "UAV10-group3" / "groundtruth_rect.txt")
    assert len(uav) == 90 and uav.absent.tolist() == list(range(31, 66))
    np.testing.assert_array_equal(uav.boxes[29], [459.0, 374.0, 14.0, 25.0])  # line 30
    assert len(load_single_gt(shared_data / "Girl" / "groundtruth_rect.txt")) == 500
    for name, n in (("Biker", 142), ("MotorRolling", 164)):
        g = load_single_gt(shared_data / name / "groundtruth_rect.txt")
        assert len(g) == n and g.absent.size == 0


def test_pgm_track_reports_the_long_term_measures(shared_data: Path, tmp_path: Path,
                                                   capsys) -> None:
    """On UAV10-group3 through the absence: metrics.json has the long-term measures and
    the absence signal (at --lost-below), and the summary prints them."""
    import json

    from cli_run import run_cli

    code, out, err = run_cli(capsys, "track", shared_data / "UAV10-group3", "--out", tmp_path,
                             "--no-video", "--max-frames", "45", "--lost-below", "0.4")
    assert code == 0, err
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["n_frames"] == 30 and m["n_absent"] == 15  # frames 31-45 absent
    lt, ab = m["long_term"], m["absence"]
    assert lt["n_visible"] == 30 and lt["n_absent"] == 15 and 0.0 <= lt["f_score"] <= 1.0
    assert ab["threshold"] == 0.4 and ab["absent"] == 15
    assert "long-term F-score" in out and "absence flagged (conf < 0.4)" in out


def test_a_result_file_reports_absence_by_a_nan_row_or_no_row(tmp_path: Path, capsys) -> None:
    """``pgm eval``: a tracker's row of NaN (or no row) for a frame says the target is
    absent there — left out of the boxes, flagged by the absence signal; other
    non-finite boxes stay an error."""
    import json

    from cli_run import run_cli

    from pgm.io.annotations import load_tracks

    gt = tmp_path / "groundtruth_rect.txt"
    gt.write_text("11,11,5,5\nNaN,NaN,NaN,NaN\nNaN,NaN,NaN,NaN\n12,11,5,5\n")
    pred = tmp_path / "tracks.txt"
    pred.write_text("1,1,11,11,5,5,1,-1,-1,-1\n2,1,NaN,NaN,NaN,NaN,1,-1,-1,-1\n"
                    "4,1,12,11,5,5,1,-1,-1,-1\n")  # frame 3: no row
    assert load_tracks(pred).frames.tolist() == [1, 4]
    code, out, err = run_cli(capsys, "eval", "--gt", gt, "--pred", pred, "--json")
    assert code == 0, err
    m = json.loads(out)
    assert m["absence"]["flagged"] == 2 and m["absence"]["precision"] == 1.0
    assert m["absence"]["recall"] == 1.0 and m["long_term"]["f_score"] == pytest.approx(1.0)
    half = tmp_path / "half.txt"
    half.write_text("1,1,11,11,NaN,5,1,-1,-1,-1\n")
    code, _, err = run_cli(capsys, "eval", "--gt", gt, "--pred", half)
    assert code != 0 and "not finite" in err
