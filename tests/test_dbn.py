"""The deep-belief-network person likelihood (SPEC §3c): features, training, files, use."""

import json

import numpy as np
import pytest

from pgm.appearance.dbn import DBN, DBNLikelihood, training_set
from pgm.appearance.features import PatchFeatures, gradient_integrals
from pgm.cli import main
from pgm.errors import InputError
from pgm.frame import FrameContext


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
