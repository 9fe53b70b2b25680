"""The deep-belief-network person likelihood (Feng et al. 2015): features, training, files, use."""

import json

import numpy as np
import pytest

from pgm.app.cli import main
from pgm.core.errors import InputError
from pgm.core.frame import FrameContext
from pgm.observation.appearance.dbn import DBN, DBNLikelihood, training_set
from pgm.observation.appearance.features import PatchFeatures, gradient_integrals


def test_gradient_features_equal_a_plain_loop():
    """Vectorised cell histograms (integral images, all boxes at once) equal direct sums
    of the gradient magnitude over each cell's pixels, box by box."""
    import cv2

    rng = np.random.default_rng(0)
    img = rng.integers(0, 256, (50, 70, 3), dtype=np.uint8)
    pf = PatchFeatures(n_orient=6, cells=(2, 3))
    boxes = np.array([[30.0, 25.0, 20.0, 30.0], [10.0, 40.0, 16.0, 24.0]])
    got = pf.compute(img, boxes)[:, pf.colour.n_bins:]
    g = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float32)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=1)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=1)
    mag = np.hypot(gx, gy)
    ang = np.mod(np.degrees(np.arctan2(gy, gx)), 180.0)
    bins = np.minimum((ang * 6 / 180.0).astype(int), 5)
    for i, (cx, cy, w, h) in enumerate(boxes):
        xs = np.clip(np.round(cx - w / 2 + w * np.arange(3) / 2), 0, 70).astype(int)
        ys = np.clip(np.round(cy - h / 2 + h * np.arange(4) / 3), 0, 50).astype(int)
        ref = []
        for r in range(3):
            for c in range(2):
                m = mag[ys[r]:ys[r + 1], xs[c]:xs[c + 1]]
                b = bins[ys[r]:ys[r + 1], xs[c]:xs[c + 1]]
                ref += [m[b == k].sum() for k in range(6)]
        ref = np.array(ref)
        np.testing.assert_allclose(got[i], ref / max(np.linalg.norm(ref), 1e-9), atol=2e-3)
    assert gradient_integrals(img, 6).shape == (6, 51, 71)


@pytest.fixture(scope="module")
def synthetic_mot(tmp_path_factory):
    from pgm.synthetic import multi_target_scene

    d = tmp_path_factory.mktemp("dbn")
    multi_target_scene(seed=0, n_frames=60).write_mot(d / "train", rng=0)
    multi_target_scene(seed=1, n_frames=60).write_mot(d / "test", rng=1)
    return d


@pytest.mark.slow
def test_dbn_separates_people_from_background_on_held_out_frames(synthetic_mot, tmp_path):
    """Synthetic scenes: trained on one rendering, tested on another (different seed).

    Measured: held-out accuracy 1.00 against a base rate of about 0.7.
    """
    X, y = training_set([synthetic_mot / "train"], np.random.default_rng(0), every=4)
    Xt, yt = training_set([synthetic_mot / "test"], np.random.default_rng(1), every=6)
    net = DBN(hidden=(32, 16)).fit(X, y, np.random.default_rng(2), rbm_epochs=5,
                                   finetune_epochs=30)
    p = net.predict_proba(Xt)
    base = max(yt.mean(), 1 - yt.mean())
    assert np.mean((p > 0.5) == yt) > base + 0.15
    # the likelihood ratio is positive on people and negative on background on average
    lr = net.log_ratio(Xt)
    assert lr[yt == 1].mean() > 0 > lr[yt == 0].mean()
    # save / load round trip, no pickle
    net.save(tmp_path / "net.npz")
    net2 = DBN.load(tmp_path / "net.npz")
    np.testing.assert_allclose(net2.predict_proba(Xt), p, rtol=1e-12)
    with np.load(tmp_path / "net.npz", allow_pickle=False) as f:
        assert json.loads(str(f["header"]))["format"] == "pgm-dbn-v1"


@pytest.mark.slow
def test_training_set_takes_a_person_taller_than_the_frame(synthetic_mot, tmp_path):
    """MOT16's ground truth has people close to the camera whose boxes run past the frame:
    their negatives are still drawn (this raised "high - low < 0" inside numpy)."""
    import shutil

    d = tmp_path / "tall"
    shutil.copytree(synthetic_mot / "train", d)
    gt = d / "gt" / "gt.txt"
    lines = gt.read_text().splitlines()
    f, i, x, y, w, h, *rest = lines[0].split(",")
    lines.insert(0, ",".join([f, "999", "5", "-20", "60", "5000", *rest]))
    gt.write_text("\n".join(lines) + "\n")
    X, y = training_set([d], np.random.default_rng(0), every=4)
    assert np.all(np.isfinite(X)) and y.sum() > 0 and (y == 0).sum() > 0


def test_dbn_file_errors(tmp_path):
    with pytest.raises(InputError, match="not found"):
        DBN.load(tmp_path / "missing.npz")
    np.savez(tmp_path / "other.npz", a=np.zeros(3))
    with pytest.raises(InputError, match="not a pgm DBN file"):
        DBN.load(tmp_path / "other.npz")
    np.save(tmp_path / "obj.npy", np.array([{"x": 1}], dtype=object), allow_pickle=True)
    (tmp_path / "obj.npz").write_bytes((tmp_path / "obj.npy").read_bytes())
    with pytest.raises(InputError, match="not a pgm DBN file"):
        DBN.load(tmp_path / "obj.npz")
    with pytest.raises(InputError, match="both classes"):
        DBN().fit(np.zeros((20, 4)), np.zeros(20), np.random.default_rng(0))


@pytest.mark.slow
def test_learn_and_track_with_dbn_from_the_cli(synthetic_mot, tmp_path, capsys):
    code = main(["learn", "dbn", "--train", str(synthetic_mot / "train"), "--out",
                 str(tmp_path / "dbn.npz"), "--every", "6", "--epochs", "10"])
    assert code == 0, capsys.readouterr().err
    assert "training accuracy" in capsys.readouterr().out
    code = main(["track", str(synthetic_mot / "test"), "--model", "phd", "--dbn",
                 str(tmp_path / "dbn.npz"), "--out", str(tmp_path / "o"), "--quiet",
                 "--no-video", "--max-frames", "20"])
    assert code == 0, capsys.readouterr().err
    model = json.loads((tmp_path / "o" / "model.json").read_text())
    assert any(f["type"] == "DBNLikelihood" for f in model["factors"])
    fac = DBNLikelihood("targets", model=str(tmp_path / "dbn.npz"))
    x = np.array([[100.0, 0.0, 200.0, 0.0], [300.0, 0.0, 250.0, 0.0]])
    img = np.zeros((480, 640, 3), np.uint8)
    assert fac.log_likelihood(x, FrameContext(1, img)).shape == (2,)


@pytest.mark.slow
@pytest.mark.data
def test_dbn_trained_on_tud_recognises_people_in_pets(shared_data):
    """Leave-one-sequence-out: trained on TUD-Campus + TUD-Stadtmitte, tested on
    PETS09-S2L1 patches. Measured (seeds 0/1/2): ROC AUC 0.993, accuracy 0.942 against a
    base rate of 0.742."""
    from sklearn.metrics import roc_auc_score

    X, y = training_set([shared_data / "TUD-Campus", shared_data / "TUD-Stadtmitte"],
                        np.random.default_rng(0), every=3)
    Xt, yt = training_set([shared_data / "PETS09-S2L1"], np.random.default_rng(1), every=10)
    net = DBN().fit(X, y, np.random.default_rng(2))
    p = net.predict_proba(Xt)
    assert roc_auc_score(yt, p) > 0.95
    assert np.mean((p > 0.5) == yt) > max(yt.mean(), 1 - yt.mean()) + 0.1


@pytest.fixture(scope="module")
def tiny_dbn(tmp_path_factory):
    rng = np.random.default_rng(0)
    dim = PatchFeatures().dim
    X = rng.random((120, dim)).astype(np.float32)
    y = (X[:, 0] > 0.5).astype(np.float32)
    path = tmp_path_factory.mktemp("tiny") / "dbn.npz"
    net = DBN(hidden=(8, 4)).fit(X, y, rng, rbm_epochs=1, finetune_epochs=30)
    net.save(path)
    return str(path)


def test_dbn_contamination_bounds_the_ratio_and_zero_is_literal(tiny_dbn):
    rng = np.random.default_rng(1)
    img = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    x = np.column_stack([rng.uniform(0, 160, 50), np.zeros(50), rng.uniform(40, 120, 50),
                         np.zeros(50)])
    literal = DBNLikelihood("t", model=tiny_dbn, epsilon=0.0, stride=0.0)
    boxes = np.column_stack([x[:, 0], x[:, 2] - 50, np.full(50, 40.0), np.full(50, 100.0)])
    want = literal.net.log_ratio(literal.features.compute(img, boxes))
    np.testing.assert_allclose(literal.log_likelihood(x, FrameContext(1, img)), want)
    eps = 0.2
    robust = DBNLikelihood("t", model=tiny_dbn, epsilon=eps, stride=0.0)
    got = robust.log_likelihood(x, FrameContext(1, img))
    pi = robust.calibration()[1]
    lo, hi = np.log(eps * (1 - pi) / (1 - eps * pi)), np.log((1 - eps * (1 - pi)) / (eps * pi))
    assert np.all(got >= lo - 1e-9) and np.all(got <= hi + 1e-9)
    assert np.all(np.sign(got) == np.sign(want)) or np.allclose(want, 0)  # order kept
    assert np.all(np.diff(got[np.argsort(want)]) >= -1e-12)
    with pytest.raises(InputError, match="epsilon"):
        DBNLikelihood("t", model=tiny_dbn, epsilon=1.0)


def test_dbn_lattice_scores_each_cell_once(tiny_dbn, monkeypatch):
    rng = np.random.default_rng(2)
    img = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    stride = 4.0
    cells = rng.integers(5, 30, (12, 2))
    pick = rng.integers(0, 12, 200)  # 200 particles on at most 12 cell centres
    x = np.zeros((200, 4))
    x[:, 0], x[:, 2] = (cells[pick, 0] + 0.5) * stride, (cells[pick, 1] + 0.5) * stride
    exact = DBNLikelihood("t", model=tiny_dbn, stride=0.0)
    lattice = DBNLikelihood("t", model=tiny_dbn, stride=stride)
    rows = []
    orig = lattice.features.compute
    monkeypatch.setattr(lattice.features, "compute",
                        lambda ctx, b: rows.append(len(b)) or orig(ctx, b))
    got = lattice.log_likelihood(x, FrameContext(1, img))
    np.testing.assert_allclose(got, exact.log_likelihood(x, FrameContext(1, img)), rtol=1e-6)
    assert rows == [len(np.unique(pick))]


def test_dbn_recalibrates_on_detections_without_labels(tiny_dbn, tmp_path):
    from pgm import FactorGraph, Variable
    from pgm.factors.multitarget import IntensityPrior
    from pgm.observation.detections import Detections

    rng = np.random.default_rng(3)
    img = rng.integers(0, 256, (240, 320, 3), dtype=np.uint8)
    f = DBNLikelihood("t", model=tiny_dbn, calibrate_with=12, stride=0.0)
    before = f.calibration()
    x = np.column_stack([rng.uniform(0, 320, 20), np.zeros(20), rng.uniform(100, 240, 20),
                         np.zeros(20)])
    boxes = np.array([[30.0, 40, 40, 100], [150, 60, 40, 100], [250, 120, 40, 100]])
    for k in range(3):  # 9 detections: not yet
        f.log_likelihood(x, FrameContext(k + 1, img, detections=Detections(boxes, np.ones(3))))
    assert not f.calibrated and f.calibration() == before
    f.log_likelihood(x, FrameContext(4, img, detections=Detections(boxes, np.ones(3))))
    assert f.calibrated and f.calibration() != before
    assert 0 < f.prior < 1 and f.calibration() == (f.platt, f.prior)
    assert (f.net.platt_, f.net.prior_) == before  # the network itself is not changed
    # the fitted calibration is part of the declaration and comes back on loading
    g = FactorGraph([Variable("t", 4, role="set")],
                    [IntensityPrior("t", mean=np.zeros(4), mass=0.0), f], name="g")
    g.save(tmp_path / "g.json")
    back = FactorGraph.load(tmp_path / "g.json").factors[f.name]
    assert back.calibrated and back.platt == pytest.approx(f.platt)
    np.testing.assert_allclose(back.log_likelihood(x, FrameContext(5, img)),
                               f.log_likelihood(x, FrameContext(5, img)))
    with pytest.raises(InputError, match="together"):
        DBNLikelihood("t", model=tiny_dbn, platt=[1.0, 0.0])
