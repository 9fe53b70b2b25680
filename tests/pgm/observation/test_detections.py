"""Per-frame detections: public det.txt lookup, the MOG2 blob detector, make_detector."""

from types import SimpleNamespace

import numpy as np
import pytest

from pgm.core.boxes import iou_xywh
from pgm.core.errors import InputError
from pgm.io.annotations import load_mot
from pgm.io.video import open_source
from pgm.observation.detections import (
    Detections,
    DetectionSource,
    MatchCounts,
    MOG2Detector,
    PublicDetections,
    make_detector,
    match_detections,
    pair_boxes,
)

# 1-based MOT rows: frame, id, x, y, w, h, score, wx, wy, wz
DET_ROWS = """\
1,-1,11,21,30,80,55.5,-1,-1,-1
1,-1,101,51,20,60,3.25,-1,-1,-1
3,-1,201,101,40,90,90,-1,-1,-1
2,-1,1,1,10,20,-0.4,-1,-1,-1
"""


@pytest.fixture
def det_file(tmp_path):
    p = tmp_path / "det.txt"
    p.write_text(DET_ROWS)
    return p


# --------------------------------------------------------------------------- container


def test_detections_properties_and_empty():
    d = Detections([[10.0, 20.0, 30.0, 80.0], [0.0, 0.0, 4.0, 6.0]], [0.5, 0.9])
    assert len(d) == 2 and d.boxes.shape == (2, 4) and d.scores.shape == (2,)
    np.testing.assert_allclose(d.foot_points, [[25.0, 100.0], [2.0, 6.0]])
    np.testing.assert_allclose(d.centres, [[25.0, 60.0], [2.0, 3.0]])
    assert not d.boxes.flags.writeable and not d.scores.flags.writeable
    e = Detections.empty()
    assert len(e) == 0 and e.boxes.shape == (0, 4) and e.scores.shape == (0,)
    assert e.foot_points.shape == (0, 2) and e.centres.shape == (0, 2)
    assert len(d.select(d.scores > 0.6)) == 1
    with pytest.raises(ValueError):
        Detections(np.zeros((2, 4)), np.zeros(3))


def test_detections_do_not_freeze_the_callers_array():
    boxes = np.ones((1, 4))
    Detections(boxes, [1.0])
    boxes[0, 0] = 5.0  # still writeable


# --------------------------------------------------------------------------- public


def test_public_round_trip(det_file):
    pub = PublicDetections(det_file)
    assert isinstance(pub, DetectionSource) and pub.name == "public"
    d1 = pub(1, None)
    np.testing.assert_allclose(d1.boxes, [[10, 20, 30, 80], [100, 50, 20, 60]])  # 0-based
    np.testing.assert_allclose(d1.scores, [55.5, 3.25])
    np.testing.assert_allclose(d1.foot_points, [[25, 100], [110, 110]])
    d3 = pub(3, np.zeros((4, 4, 3), np.uint8))  # the image is ignored
    np.testing.assert_allclose(d3.boxes, [[200, 100, 40, 90]])
    for frame in (4, 1000):  # frames without rows: empty, shape (0, 4)
        e = pub(frame, None)
        assert len(e) == 0 and e.boxes.shape == (0, 4) and e.scores.shape == (0,)
    assert pub.score_range == (-0.4, 90.0)
    # any order (stateless), and a table works as well as a path
    assert len(pub(2, None)) == 1 and len(pub(1, None)) == 2
    table_src = PublicDetections(load_mot(det_file, kind="det"))
    np.testing.assert_array_equal(table_src(1, None).boxes, d1.boxes)


@pytest.mark.parametrize("from_table", [False, True])
def test_public_min_score_in_file_units(det_file, from_table):
    arg = load_mot(det_file, kind="det") if from_table else det_file
    pub = PublicDetections(arg, min_score=50)
    assert pub.name == "public:50"
    np.testing.assert_allclose(pub(1, None).scores, [55.5])
    assert len(pub(2, None)) == 0 and len(pub(3, None)) == 1
    assert len(PublicDetections(arg, min_score=-1)(2, None)) == 1
    with pytest.raises(InputError, match="min_score"):
        PublicDetections(arg, min_score="high")
    with pytest.raises(InputError, match="min_score"):
        PublicDetections(arg, min_score=float("nan"))


def test_a_detection_file_without_a_detection_is_a_warning(tmp_path, det_file, caplog):
    """An empty detection file (or one whose every score is below ``min_score``) would run
    to a score of zero in silence: it is said once, naming the file."""
    import logging

    empty = tmp_path / "empty_det.txt"
    empty.write_text("")
    with caplog.at_level(logging.WARNING, logger="pgm"):
        assert len(PublicDetections(empty)(1, None)) == 0
    assert str(empty) in caplog.text and "holds no detection:" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="pgm"):
        PublicDetections(det_file, min_score=1000)
        assert "scored at least 1000" in caplog.text
        n = len(caplog.records)
        PublicDetections(det_file)
    assert n == 1 and len(caplog.records) == 1


def test_public_missing_or_malformed_file_names_it(tmp_path):
    missing = tmp_path / "nope" / "det.txt"
    with pytest.raises(InputError, match="det.txt"):
        PublicDetections(missing)
    bad = tmp_path / "bad_det.txt"
    bad.write_text("1,-1,10,20,30,40,0.5\n2,-1,ten,20,30,40,0.5\n")
    with pytest.raises(InputError, match=r"bad_det\.txt:2"):
        PublicDetections(bad)
    short = tmp_path / "short_det.txt"
    short.write_text("1,-1,10,20\n")
    with pytest.raises(InputError, match="short_det.txt"):
        PublicDetections(short)


# --------------------------------------------------------------------------- MOG2


def _synthetic_video(n=45, start=21, size=(240, 320), seed=0):
    """Static textured background + sensor noise; a 24x60 rectangle moves right 4 px per
    frame from frame ``start``. Yields ``(frame_number, image, box or None)``."""
    rng = np.random.default_rng(seed)
    h, w = size
    coarse = rng.integers(40, 200, size=(h // 8 + 1, w // 8 + 1, 3))
    background = np.kron(coarse, np.ones((8, 8, 1)))[:h, :w].astype(float)
    background += rng.normal(0, 6, size=background.shape)  # fine texture
    for k in range(1, n + 1):
        img = background + rng.normal(0, 2, size=background.shape)
        box = None
        if k >= start:
            x, y = 20 + 4 * (k - start), 90
            box = np.array([x, y, 24, 60], dtype=float)
            img[y:y + 60, x:x + 24] = (230, 20, 240)
        yield k, np.clip(img, 0, 255).astype(np.uint8), box


def test_mog2_finds_the_moving_rectangle():
    det = MOG2Detector()
    assert isinstance(det, DetectionSource) and det.name == "mog2"
    checked = 0
    for k, img, box in _synthetic_video():
        d = det(k, img)
        if box is None:
            assert len(d) == 0, f"frame {k}: {d.boxes}"  # static scene: no blob
        elif k >= 25:
            assert len(d) == 1, f"frame {k}: {d.boxes}"
            assert iou_xywh(d.boxes[0], box) > 0.5
            assert 0 < d.scores[0] <= 1  # fill ratio
            assert det.mask is not None and det.mask.shape == img.shape[:2]
            checked += 1
    assert checked == 21


def test_mog2_is_deterministic_and_warmup_suppresses():
    a, b = MOG2Detector(), MOG2Detector(warmup=30)
    out_a, out_b = [], []
    for k, img, _ in _synthetic_video(n=40):
        out_a.append(a(k, img))
        out_b.append(b(k, img))
    assert all(len(d) == 0 for d in out_b[:30])
    for da, db in zip(out_a[30:], out_b[30:], strict=True):  # same model after warm-up
        np.testing.assert_array_equal(da.boxes, db.boxes)
    a.reset()
    again = [a(k, img) for k, img, _ in _synthetic_video(n=40)]
    for d1, d2 in zip(out_a, again, strict=True):
        np.testing.assert_array_equal(d1.boxes, d2.boxes)
        np.testing.assert_array_equal(d1.scores, d2.scores)


def test_mog2_shape_filters():
    frames = list(_synthetic_video(n=30))
    for kwargs in (dict(min_area=2000), dict(min_height=70), dict(max_aspect=2.0),
                   dict(min_aspect=3.0)):
        det = MOG2Detector(**kwargs)
        found = [len(det(k, img)) for k, img, _ in frames]
        assert sum(found) == 0, kwargs


def test_mog2_must_be_called_in_order():
    det = MOG2Detector()
    img = np.zeros((50, 60, 3), np.uint8)
    det(1, img)
    det(3, img)  # gaps are fine
    with pytest.raises(InputError, match="increasing order"):
        det(3, img)
    with pytest.raises(InputError, match="shape"):
        det(4, np.zeros((40, 60, 3), np.uint8))
    with pytest.raises(InputError, match="image"):
        det(5, None)
    det.reset()
    det(1, np.zeros((40, 60), np.uint8))  # greyscale works too


@pytest.mark.parametrize("kwargs, needle", [
    (dict(var_threshold=0), "var_threshold"), (dict(history=0), "history"),
    (dict(min_area=-1), "min_area"), (dict(min_aspect=3, max_aspect=2), "max_aspect"),
    (dict(blur=4), "blur"), (dict(learning_rate=2), "learning_rate"),
    (dict(background_ratio=1.5), "background_ratio"), (dict(close_size="big"), "close_size"),
    (dict(warmup="x"), "warmup")])
def test_mog2_bad_parameters(kwargs, needle):
    with pytest.raises(InputError, match=needle):
        MOG2Detector(**kwargs)


# --------------------------------------------------------------------------- factory


def test_make_detector(det_file, tmp_path):
    source = SimpleNamespace(det_path=det_file, name="toy")
    pub = make_detector("public", source)
    assert isinstance(pub, PublicDetections) and len(pub(1, None)) == 2
    pub50 = make_detector("public:50", source)
    assert pub50.min_score == 50 and len(pub50(1, None)) == 1
    assert isinstance(make_detector("mog2", source), MOG2Detector)
    assert isinstance(make_detector("MOG2", None), MOG2Detector)


@pytest.mark.parametrize("spec", ["yolo", "", "mog2:3", "public-0.5"])
def test_make_detector_unknown_spec_lists_choices(spec, det_file):
    with pytest.raises(InputError, match="choices: 'public'.*'mog2'"):
        make_detector(spec, SimpleNamespace(det_path=det_file))


def test_make_detector_errors(tmp_path, det_file):
    with pytest.raises(InputError, match="min_score"):
        make_detector("public:abc", SimpleNamespace(det_path=det_file))
    folder = tmp_path / "imgs"
    folder.mkdir()
    import cv2
    cv2.imwrite(str(folder / "0001.png"), np.zeros((8, 8, 3), np.uint8))
    src = open_source(folder)
    assert src.det_path is None
    with pytest.raises(InputError, match="no public detections"):
        make_detector("public", src)
    with pytest.raises(InputError, match="missing_det.txt"):
        make_detector("public", SimpleNamespace(det_path=tmp_path / "missing_det.txt"))


# --------------------------------------------------------------------------- evaluation


def test_match_detections_counts():
    gt = np.array([[0, 0, 20, 50], [100, 0, 20, 50]], float)
    ign = np.array([[300, 0, 20, 50]], float)
    d = Detections([[1, 1, 20, 50], [301, 0, 20, 50], [200, 200, 10, 10]], [1, 1, 1])
    c = match_detections(d, gt, ign)
    assert (c.tp, c.fp, c.fn, c.n_det, c.n_gt) == (1, 1, 1, 3, 2)
    f = match_detections(Detections([[6, 0, 20, 50]], [1]), gt, criterion="foot", foot_px=5)
    assert (f.tp, f.fn) == (0, 2)
    group = Detections([[-2, 0, 124, 52]], [1])  # one box over both people
    g = match_detections(group, gt)
    assert g.merged == 1 and g.people_in_merged == 2 and g.tp == 0
    total = c + g
    assert total == MatchCounts(tp=1, fp=2, fn=3, merged=1, people_in_merged=2, n_det=4,
                                n_gt=4)
    assert total.precision == pytest.approx(1 / 3) and total.recall == pytest.approx(0.25)
    assert match_detections(Detections.empty(), gt).fn == 2


def test_pair_boxes_counts_pairs_before_their_total():
    """Hand-worked: A overlaps X by 0.95 and Y by 0.5, B overlaps X by 0.5 and Y by 0.4
    (below the 0.5 test). The best total IoU (A-X, B-Y: 1.35) keeps one valid pair;
    counting first keeps two (A-Y, B-X)."""
    iou = np.array([[0.95, 0.5], [0.5, 0.4]])
    r, c = pair_boxes(iou >= 0.5, iou)
    assert sorted(zip(r.tolist(), c.tolist(), strict=True)) == [(0, 1), (1, 0)]
    # among equally many pairs, the larger total wins
    iou = np.array([[0.9, 0.6], [0.6, 0.8]])
    r, c = pair_boxes(iou >= 0.5, iou)
    assert sorted(zip(r.tolist(), c.tolist(), strict=True)) == [(0, 0), (1, 1)]
    r, c = pair_boxes(np.zeros((0, 3), bool), np.zeros((0, 3)))
    assert len(r) == len(c) == 0
    # seven boxes each way: six perfect pairs (i, i) leave box 6 alone, while a chain of
    # seven half-overlaps (6, 0), (0, 1), ..., (5, 6) pairs everyone. A gain of 2 + IoU
    # per pair would prefer the six (18 > 17.5); counting first takes the seven
    iou = np.eye(7)
    iou[6, 6] = 0.0
    iou[6, 0] = 0.5
    for i in range(6):
        iou[i, i + 1] = 0.5
    r, c = pair_boxes(iou >= 0.5, iou)
    assert len(r) == 7
    # the most pairs on random tables: as many as a maximum bipartite matching
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import maximum_bipartite_matching

    rng = np.random.default_rng(0)
    for _ in range(200):
        n, m = rng.integers(1, 9, size=2)
        s = rng.uniform(size=(n, m))
        ok = s >= 0.6
        most = int(np.count_nonzero(maximum_bipartite_matching(csr_matrix(ok),
                                                               perm_type="column") >= 0))
        r, c = pair_boxes(ok, s)
        assert len(r) == most and np.all(ok[r, c])
        assert len(set(r.tolist())) == len(r) and len(set(c.tolist())) == len(c)


# --------------------------------------------------------------------------- real data


@pytest.mark.data
def test_mog2_and_public_on_pets_first_60_frames(shared_data):
    """PETS09-S2L1 ``vtest.avi``, frames 1-60, flag-1 ground truth, IoU >= 0.3.

    Measured with the defaults: MOG2 precision 0.954, recall 0.728 (foot points within
    20 px: 0.894 / 0.682); public det.txt (all rows) precision 0.790, recall 0.915.
    The floors sit well below, to catch a broken detector rather than tuning drift.
    """
    seq = shared_data / "PETS09-S2L1-video"
    source = open_source(seq)
    gt = load_mot(source.gt_path, kind="gt")
    mog2 = make_detector("mog2", source)
    public = make_detector("public", source)
    counts = {"mog2": MatchCounts(), "public": MatchCounts()}
    for k, image in source.frames(1, 61):
        rows = gt.rows(k)
        boxes, ignore = gt.boxes[rows], gt.ignore[rows]
        for name, det in (("mog2", mog2), ("public", public)):
            counts[name] += match_detections(det(k, image), boxes[~ignore], boxes[ignore])
    assert counts["mog2"].n_gt == 283
    assert counts["mog2"].recall > 0.55 and counts["mog2"].precision > 0.8
    assert counts["public"].recall > 0.85 and counts["public"].precision > 0.7
