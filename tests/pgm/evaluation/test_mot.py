"""Multi-object metrics: CLEAR / Identity / HOTA through the library, ignore regions."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pgm.core.errors import InputError
from pgm.evaluation.mot import (
    apply_ignore_regions,
    evaluate_mot,
    evaluate_mot_files,
    format_mot_table,
)
from pgm.io.annotations import MotTable, load_mot

# --------------------------------------------------------------------------- CLEAR / ID / HOTA


def _table(rows: list[tuple[int, int, float, float, float, float]],
           ignore: list[bool] | None = None) -> MotTable:
    a = np.array(rows, dtype=float).reshape(-1, 6)
    return MotTable(frames=a[:, 0], ids=a[:, 1], boxes=a[:, 2:6], conf=np.ones(len(a)),
                    ignore=ignore)


def _two_walkers(n: int = 10) -> list[tuple[int, int, float, float, float, float]]:
    rows = []
    for f in range(1, n + 1):
        rows.append((f, 1, 10.0 + 5 * f, 50.0, 40.0, 100.0))
        rows.append((f, 2, 300.0 - 5 * f, 60.0, 40.0, 100.0))
    return rows


def test_perfect_prediction() -> None:
    gt = _table(_two_walkers())
    pred = _table([(f, i + 10, x, y, w, h) for f, i, x, y, w, h in _two_walkers()])
    r = evaluate_mot(gt, pred)
    for key in ("mota", "motp", "idf1", "idp", "idr", "hota", "deta", "assa", "loca"):
        assert r[key] == pytest.approx(1.0, abs=1e-9), key
    assert (r["id_switches"], r["fragmentations"], r["fp"], r["fn"]) == (0, 0, 0, 0)
    assert (r["mostly_tracked"], r["mostly_lost"], r["num_gt"], r["num_pred"]) == (2, 0, 20, 20)
    assert r["ospa_50_1"] == 0.0 and r["ospa_100_2"] == 0.0 and r["ospa2"] == 0.0
    assert r["mean_abs_cardinality_error"] == 0.0
    json.dumps(r, allow_nan=False)
    assert all(type(v) in (int, float) for k, v in r.items() if k != "per_frame")


def test_identity_swap_counts() -> None:
    gt = _table(_two_walkers())
    # the two predicted identities swap objects from frame 6 on: both objects switch
    swapped = [(f, (3 - i if f >= 6 else i), x, y, w, h) for f, i, x, y, w, h in _two_walkers()]
    r = evaluate_mot(gt, _table(swapped))
    assert r["id_switches"] == 2
    assert r["mota"] == pytest.approx(1 - 2 / 20)
    assert r["idf1"] == pytest.approx(0.5)
    assert r["fp"] == 0 and r["fn"] == 0
    assert r["hota"] < 1.0 and r["deta"] == pytest.approx(1.0)
    # one track relabelled from frame 6 on: one switch
    relabelled = [(f, (7 if (i == 1 and f >= 6) else i), x, y, w, h)
                  for f, i, x, y, w, h in _two_walkers()]
    r = evaluate_mot(gt, _table(relabelled))
    assert r["id_switches"] == 1
    assert r["mota"] == pytest.approx(1 - 1 / 20)
    assert r["idf1"] == pytest.approx(15 / 20)


def test_misses_and_false_positives() -> None:
    gt = _table(_two_walkers(4))
    rows = [r for r in _two_walkers(4) if r[1] == 1] + [(2, 5, 600.0, 300.0, 20.0, 20.0)]
    r = evaluate_mot(gt, _table(rows))
    assert (r["fp"], r["fn"], r["tp"]) == (1, 4, 4)
    assert r["mota"] == pytest.approx(1 - 5 / 8)
    assert r["mostly_tracked"] == 1 and r["mostly_lost"] == 1
    # OSPA(50,1): each frame one object missing -> (0 + 50) / 2; in frame 2 the far
    # false positive is paired with the missed object instead, at the cut-off: same value
    assert r["ospa_50_1"] == pytest.approx(25.0)
    assert r["mean_abs_cardinality_error"] == pytest.approx((1 + 0 + 1 + 1) / 4)


def test_ignore_regions() -> None:
    # frame 1: a real person (id 1) and a flag-0 row (id 2, an ignore region)
    gt = _table([(1, 1, 0.0, 0.0, 40.0, 100.0), (1, 2, 200.0, 0.0, 40.0, 100.0)],
                ignore=[False, True])
    # a hit on the person, a prediction on the ignore region (IoU ~0.9)
    pred = _table([(1, 7, 1.0, 1.0, 40.0, 100.0), (1, 8, 202.0, 0.0, 40.0, 100.0)])
    r = evaluate_mot(gt, pred)
    assert (r["fp"], r["fn"], r["tp"]) == (0, 0, 1)
    assert r["num_gt"] == 1 and r["num_gt_ignored"] == 1
    assert r["num_pred"] == 1 and r["num_pred_ignored"] == 1
    assert r["mota"] == 1.0 and r["idf1"] == 1.0
    assert r["mean_abs_cardinality_error"] == 0.0
    # the ignore region alone, no prediction on it: not a miss
    r = evaluate_mot(gt, _table([(1, 7, 1.0, 1.0, 40.0, 100.0)]))
    assert (r["fp"], r["fn"]) == (0, 0)
    # a prediction overlapping the ignore region with IoU < 0.5 stays a false positive
    r = evaluate_mot(gt, _table([(1, 7, 0.0, 0.0, 40.0, 100.0),
                                 (1, 8, 225.0, 0.0, 40.0, 100.0)]))
    assert (r["fp"], r["num_pred_ignored"]) == (1, 0)


def test_ignore_matching_is_joint_with_real_boxes() -> None:
    # an ignore region overlapping a real person (IoU 2/3): a prediction exactly on the
    # person is matched to the person (Hungarian over all ground truth), so it is kept
    gt = _table([(1, 1, 0.0, 0.0, 10.0, 20.0), (1, 2, 2.0, 0.0, 10.0, 20.0)],
                ignore=[False, True])
    pred = _table([(1, 5, 0.0, 0.0, 10.0, 20.0)])
    g, p, dropped = apply_ignore_regions(gt, pred)
    assert (len(g), len(p), dropped) == (1, 1, 0)
    assert evaluate_mot(gt, pred)["tp"] == 1


def test_evaluate_mot_rejects_bad_input() -> None:
    gt = _table(_two_walkers(3))
    empty = _table([])
    with pytest.raises(InputError, match="nothing to score"):
        evaluate_mot(empty, empty)
    with pytest.raises(InputError, match="beyond"):
        evaluate_mot(gt, gt, num_frames=2)
    with pytest.raises(InputError, match="two boxes"):
        evaluate_mot(gt, _table([(1, 1, 0, 0, 5, 5), (1, 1, 50, 0, 5, 5)]))
    with pytest.raises(InputError, match="IoU"):
        evaluate_mot(gt, gt, iou=0.0)
    # an empty prediction over a fixed-length sequence scores (TrackEval: MOTA 0)
    r = evaluate_mot(gt, empty, num_frames=5)
    assert r["fn"] == 6 and r["ospa_50_1"] == pytest.approx(3 * 50 / 5)


def test_format_mot_table() -> None:
    res = {("TUD-Campus", "SORT"): {"mota": 0.4321, "idf1": 0.484, "hota": 0.3261,
                                    "id_switches": 19, "ospa_50_1": 28.84, "ospa_100_2": 62.2},
           ("TUD-Campus", "OC-SORT"): {"mota": 0.415, "idf1": 0.488, "hota": 0.305,
                                       "id_switches": 9, "ospa_50_1": 31.4}}
    text = format_mot_table(res).splitlines()
    assert text[0] == ("| sequence | tracker | MOTA | IDF1 | HOTA | ID switches | OSPA(50,1)"
                       " | OSPA(100,2) |")
    assert text[2] == "| TUD-Campus | SORT | 0.432 | 0.484 | 0.326 | 19 | 28.8 | 62.2 |"
    assert text[3] == "|  | OC-SORT | 0.415 | 0.488 | 0.305 | 9 | 31.4 | – |"
    one = format_mot_table({"run a": res[("TUD-Campus", "SORT")]}).splitlines()
    assert one[0].startswith("| run | MOTA") and one[2].startswith("| run a | 0.432")


# --------------------------------------------------------------------------- real data

# py-motmetrics 1.4.0, motmetrics/tests/test_metrics.py::test_motchallenge_files (same gt
# and test hypotheses): IDF1, IDP, IDR, FP, FN, IDSW, FM, MOTA, MOTP (= 1 - IoU), MT, ML.
MOTMETRICS_EXPECTED = {
    "TUD-Campus": dict(idf1=0.557659, idp=0.729730, idr=0.451253, fp=13, fn=150, idsw=7,
                       frag=7, mota=0.526462, motp=0.277201, mt=1, ml=1),
    "TUD-Stadtmitte": dict(idf1=0.644619, idp=0.819760, idr=0.531142, fp=45, fn=452, idsw=7,
                           frag=6, mota=0.564014, motp=0.345904, mt=5, ml=1),
}
# TrackEval 1.3.0 (PyPI ``trackeval``, installed with --no-deps outside the project):
# ``trackeval.metrics.HOTA().eval_sequence`` on the same data, averaged over alpha.
TRACKEVAL_HOTA = {
    "TUD-Campus": dict(hota=0.3913974378451139, deta=0.418047030142763,
                       assa=0.36912068120832836, loca=0.770052227022172),
    "TUD-Stadtmitte": dict(hota=0.3978490169927877, deta=0.3922675723693166,
                           assa=0.4088407518112996, loca=0.737521177178062),
}


def _seq_files(shared_data: Path, seq: str) -> tuple[Path, Path]:
    base = shared_data / seq
    return base / "gt" / "gt.txt", base / "extras" / "motmetrics_test_hypothesis.txt"


@pytest.mark.data
@pytest.mark.filterwarnings("ignore::DeprecationWarning")  # pandas, inside motmetrics.io
@pytest.mark.parametrize("seq", ["TUD-Campus", "TUD-Stadtmitte"])
def test_matches_motmetrics_and_trackeval(shared_data: Path, seq: str,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    gt_path, hyp_path = _seq_files(shared_data, seq)
    r = evaluate_mot_files(gt_path, hyp_path)
    assert r["num_gt_ignored"] == 0 and r["num_pred_ignored"] == 0
    assert r["num_frames"] == len(list((shared_data / seq / "img1").glob("*.jpg")))
    exp = MOTMETRICS_EXPECTED[seq]
    for ours, theirs in (("idf1", "idf1"), ("idp", "idp"), ("idr", "idr"), ("mota", "mota")):
        assert r[ours] == pytest.approx(exp[theirs], abs=1e-6), ours
    assert 1.0 - r["motp"] == pytest.approx(exp["motp"], abs=1e-6)
    assert (r["fp"], r["fn"], r["id_switches"], r["fragmentations"]) == (
        exp["fp"], exp["fn"], exp["idsw"], exp["frag"])
    assert (r["mostly_tracked"], r["mostly_lost"]) == (exp["mt"], exp["ml"])
    for key, value in TRACKEVAL_HOTA[seq].items():
        assert r[key] == pytest.approx(value, abs=1e-9), key

    # and py-motmetrics run here, as an independent implementation (its IoU helper calls
    # np.asfarray, removed in numpy 2: a one-line local shim for this test only)
    mm = pytest.importorskip("motmetrics")
    monkeypatch.setattr(np, "asfarray", lambda a, dtype=float: np.asarray(a, dtype=dtype),
                        raising=False)
    acc = mm.utils.compare_to_groundtruth(mm.io.loadtxt(str(gt_path)),
                                          mm.io.loadtxt(str(hyp_path)), "iou", distth=0.5)
    live = mm.metrics.create().compute(
        acc, metrics=["mota", "idf1", "num_switches", "num_false_positives", "num_misses"],
        return_dataframe=False)
    assert r["mota"] == pytest.approx(float(live["mota"]), abs=1e-12)
    assert r["idf1"] == pytest.approx(float(live["idf1"]), abs=1e-12)
    assert (r["id_switches"], r["fp"], r["fn"]) == (
        int(live["num_switches"]), int(live["num_false_positives"]), int(live["num_misses"]))


@pytest.mark.data
def test_ignore_regions_on_pets09(shared_data: Path) -> None:
    gt = load_mot(shared_data / "PETS09-S2L1" / "gt" / "gt.txt", kind="gt")
    assert gt.ignore.sum() == 170
    # a "tracker" that reports every ground-truth row, flag-0 ones included
    pred = MotTable(frames=gt.frames, ids=gt.ids + 1000 * gt.ignore, boxes=gt.boxes,
                    conf=np.ones(len(gt)))
    r = evaluate_mot(gt, pred, num_frames=240)
    assert r["num_pred_ignored"] == 170 and r["num_gt"] == len(gt) - 170
    assert (r["fp"], r["fn"], r["id_switches"]) == (0, 0, 0)
    assert r["mota"] == 1.0 and r["hota"] == pytest.approx(1.0, abs=1e-9)
    assert r["ospa_50_1"] == 0.0 and r["ospa2"] == 0.0


# --------------------------------------------------------------------------- MOT16/17 protocol
MOT16_GT = """\
1,1,11,11,20,40,1,1,1
1,2,101,11,20,40,0,8,1
1,3,201,11,20,40,0,9,0.5
1,4,301,11,20,40,1,7,1
1,5,401,11,20,40,0,1,0.2
2,1,13,11,20,40,1,1,1
"""
MOT16_PRED = """\
1,1,11,11,20,40,1,-1,-1,-1
1,2,101,11,20,40,1,-1,-1,-1
1,3,201,11,20,40,1,-1,-1,-1
1,4,301,11,20,40,1,-1,-1,-1
1,5,401,11,20,40,1,-1,-1,-1
1,6,601,11,20,40,1,-1,-1,-1
2,1,13,11,20,40,1,-1,-1,-1
"""


def test_mot16_ground_truth_is_read_with_its_classes(tmp_path):
    (tmp_path / "gt.txt").write_text(MOT16_GT)
    gt = load_mot(tmp_path / "gt.txt", kind="gt")
    assert gt.fmt == "mot16"
    np.testing.assert_array_equal(gt.classes, [1, 8, 9, 7, 1, 1])
    np.testing.assert_array_equal(gt.scored, [True, False, False, False, False, True])
    np.testing.assert_array_equal(gt.ignore, [False, True, False, True, False, False])
    np.testing.assert_allclose(gt.visibility, [1, 1, 0.5, 1, 0.2, 1])
    # MOT15 (10 columns) and a 9-column file that is not MOT16 keep the flag reading
    (tmp_path / "odd.txt").write_text("1,1,11,11,20,40,0,13,1\n1,2,11,11,20,40,1,1,1\n")
    odd = load_mot(tmp_path / "odd.txt", kind="gt")
    assert odd.fmt == "mot15" and odd.ignore.tolist() == [True, False]


def test_mot16_protocol_against_a_hand_worked_example(tmp_path):
    """Frame 1 holds a pedestrian (scored), a distractor (class 8) and a static person
    (class 7) — ignore regions —, an occluder (class 9) and a pedestrian with consider=0
    — neither. Predictions on the two ignore regions are removed; those on the occluder,
    on the unconsidered pedestrian and on empty background are false positives; the
    pedestrian is hit in both frames. So GT = 2, TP = 2, FP = 3, FN = 0, and
    MOTA = 1 − (FN + FP + IDSW) / GT = 1 − 3/2 = −0.5."""
    (tmp_path / "gt.txt").write_text(MOT16_GT)
    (tmp_path / "pred.txt").write_text(MOT16_PRED)
    m = evaluate_mot_files(tmp_path / "gt.txt", tmp_path / "pred.txt")
    assert (m["fp"], m["fn"], m["id_switches"]) == (3, 0, 0)
    assert m["num_pred_ignored"] == 2 and m["num_gt_ignored"] == 4
    assert m["mota"] == pytest.approx(-0.5)
