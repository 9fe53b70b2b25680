"""Tests for pgm.evaluation.mot (OSPA, OSPA(2), cardinality, CLEAR / Identity / HOTA)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pgm.core.errors import InputError
from pgm.evaluation.mot import (
    apply_ignore_regions,
    evaluate_mot,
    evaluate_mot_files,
    foot_points,
    format_mot_table,
)
from pgm.evaluation.set_distances import cardinality_error, ospa, ospa2, ospa_components
from pgm.io.annotations import MotTable, load_mot

# --------------------------------------------------------------------------- OSPA


def test_ospa_identical_sets_is_zero() -> None:
    X = np.array([[0.0, 0.0], [10.0, 5.0], [-3.0, 7.0]])
    for p in (1, 2):
        assert ospa(X, X, 50, p) == 0.0
        assert ospa(X, X[::-1], 50, p) == pytest.approx(0.0, abs=1e-12)


def test_ospa_empty_sets() -> None:
    X = np.array([[1.0, 2.0], [3.0, 4.0]])
    assert ospa(np.zeros((0, 2)), np.zeros((0, 2)), 50, 1) == 0.0
    assert ospa([], [], 50, 2) == 0.0
    assert ospa(X, np.zeros((0, 2)), 50, 1) == 50.0
    assert ospa([], X, 100, 2) == 100.0
    assert ospa_components(X, [], 50, 1) == (50.0, 0.0, 50.0)


def test_ospa_cardinality_term() -> None:
    # one point matched at distance 5, one unmatched point: (5 + c) / 2 with c = 10
    X = np.array([[0.0, 0.0]])
    Y = np.array([[3.0, 4.0], [100.0, 0.0]])
    d, loc, card = ospa_components(X, Y, 10, 1)
    assert d == pytest.approx(7.5)
    assert loc == pytest.approx(2.5)
    assert card == pytest.approx(5.0)
    assert ospa(Y, X, 10, 1) == pytest.approx(7.5)
    # the cut-off: the matched distance 5 is cut to 4
    assert ospa(X, Y, 4, 1) == pytest.approx((4 + 4) / 2)


def test_ospa_p2_by_hand() -> None:
    X = np.array([[0.0, 0.0], [10.0, 0.0]])
    Y = np.array([[10.0, 4.0], [0.0, 3.0]])  # optimal pairing: 3 and 4
    assert ospa(X, Y, 100, 2) == pytest.approx(math.sqrt((9 + 16) / 2))
    assert ospa(X, Y, 3.5, 2) == pytest.approx(math.sqrt((9 + 3.5**2) / 2))
    d, loc, card = ospa_components(X, Y[:1], 5, 2)   # 10 ↔ (10, 4): 4; one missing: c
    assert d == pytest.approx(math.sqrt((16 + 25) / 2))
    assert d**2 == pytest.approx(loc**2 + card**2)


def test_ospa_uses_the_optimal_assignment() -> None:
    X = np.array([[0.0], [1.0]])
    Y = np.array([[1.1], [0.1]])
    assert ospa(X, Y, 10, 1) == pytest.approx(0.1)


def test_ospa_rejects_bad_input() -> None:
    X = np.zeros((2, 2))
    with pytest.raises(InputError, match="cut-off"):
        ospa(X, X, 0, 1)
    with pytest.raises(InputError, match="order"):
        ospa(X, X, 10, 0.5)
    with pytest.raises(InputError, match="dimension"):
        ospa(X, np.zeros((2, 3)), 10, 1)
    with pytest.raises(InputError, match="shape"):
        ospa(np.zeros(2), X, 10, 1)
    with pytest.raises(InputError, match="non-finite"):
        ospa(np.array([[np.nan, 0.0]]), X, 10, 1)


_coord = st.floats(-60, 60, allow_nan=False, allow_infinity=False)
_set = st.lists(st.tuples(_coord, _coord), min_size=0, max_size=4).map(
    lambda pts: np.array(pts, dtype=float).reshape(-1, 2))


@settings(max_examples=150, deadline=None)
@given(_set, _set, _set, st.sampled_from([1.0, 2.0, 3.0]), st.sampled_from([5.0, 50.0]))
def test_ospa_is_a_metric(X: np.ndarray, Y: np.ndarray, Z: np.ndarray, p: float,
                          c: float) -> None:
    dxy, dyx = ospa(X, Y, c, p), ospa(Y, X, c, p)
    assert dxy == pytest.approx(dyx, abs=1e-9)
    assert 0.0 <= dxy <= c + 1e-9
    assert ospa(X, Z, c, p) <= dxy + ospa(Y, Z, c, p) + 1e-9
    comps = ospa_components(X, Y, c, p)
    assert comps.distance**p == pytest.approx(comps.localisation**p + comps.cardinality**p,
                                              abs=1e-9)


# --------------------------------------------------------------------------- OSPA(2)


def _track(frames: range, point: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    f = np.array(list(frames))
    return f, np.tile(np.array(point, dtype=float), (f.size, 1))


def test_ospa2_identical_tracks_is_zero() -> None:
    rng = np.random.default_rng(1)
    tracks = {i: (np.arange(i, i + 12), rng.normal(size=(12, 2)) * 30) for i in range(4)}
    res = ospa2(tracks, dict(tracks), 50, 1, 5)
    assert res.frames.tolist() == list(range(0, 15))
    assert np.all(res.values == 0.0)
    assert res.mean == 0.0


def test_ospa2_by_hand() -> None:
    # true A at (0, 0) in frames 1..10, true C far away in 8..10; estimate B at (3, 4)
    # (5 px from A) in frames 1..5 only. c = 50, p = 1.
    gt = {"A": _track(range(1, 11), (0.0, 0.0)), "C": _track(range(8, 11), (500.0, 500.0))}
    est = {"B": _track(range(1, 6), (3.0, 4.0))}
    res = ospa2(gt, est, 50, 1, 10, frames=range(1, 22))
    v = dict(zip(res.frames.tolist(), res.values.tolist(), strict=True))
    # window truncated at the start: frames 1..k
    for k in range(1, 6):
        assert v[k] == pytest.approx(5.0)
    assert v[6] == pytest.approx((5 * 5 + 50) / 6)
    assert v[7] == pytest.approx((5 * 5 + 2 * 50) / 7)
    # frame 10: d(A, B) = (5*5 + 5*50) / 10 = 27.5; C has no partner: (27.5 + 50) / 2
    assert v[10] == pytest.approx((27.5 + 50) / 2)
    # frame 12, window 3..12: d(A, B) = (3*5 + 5*50) / 8; d(C, B) = 50 (no common frame)
    assert v[12] == pytest.approx(((3 * 5 + 5 * 50) / 8 + 50) / 2)
    # frame 16, window 7..16: no estimated track left -> c; frame 21: both empty -> 0
    assert v[16] == 50.0
    assert v[21] == 0.0
    assert res.mean == pytest.approx(np.mean(res.values))
    # p = 2 at frame 10: sqrt((27.5^2 + 50^2) / 2)
    r2 = ospa2(gt, est, 50, 2, 10, frames=[10])
    assert r2.values[0] == pytest.approx(math.sqrt((27.5**2 + 50**2) / 2))


def test_ospa2_rejects_bad_input() -> None:
    gt = {1: _track(range(1, 4), (0.0, 0.0))}
    with pytest.raises(InputError, match="window"):
        ospa2(gt, gt, 50, 1, 0)
    with pytest.raises(InputError, match="twice"):
        ospa2({1: (np.array([1, 1]), np.zeros((2, 2)))}, gt, 50, 1)
    with pytest.raises(InputError, match="points"):
        ospa2({1: (np.array([1, 2]), np.zeros((3, 2)))}, gt, 50, 1)
    assert ospa2({}, {}, 50, 1).mean == 0.0


# --------------------------------------------------------------------------- cardinality


def test_cardinality_error() -> None:
    err = cardinality_error([3, 3, 0, 2], [3, 1, 1, 2])
    assert err.per_frame.tolist() == [0, -2, 1, 0]
    assert err.mean_abs == pytest.approx(0.75)
    with pytest.raises(InputError):
        cardinality_error([1, 2], [1])
    with pytest.raises(InputError):
        cardinality_error([-1], [1])


def test_foot_points() -> None:
    assert foot_points(np.array([[10.0, 20.0, 4.0, 30.0]])).tolist() == [[12.0, 50.0]]


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
    assert all(type(v) in (int, float) for v in r.values())


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
