"""Perturbed sequences (pgm.evaluation.perturb): seeded, what each kind says it does, and
a folder the toolkit reads as it reads the original."""

import numpy as np
import pytest

from pgm.evaluation.perturb import (
    KINDS,
    SCORE_KINDS,
    keep_frames,
    perturb_detections,
    perturb_sequence,
    score_transform,
)


def detections(rng, frames=50, per_frame=6):
    rows = []
    for f in range(1, frames + 1):
        for _ in range(per_frame):
            w, h = rng.uniform(20, 60), rng.uniform(50, 150)
            rows.append([f, -1, rng.uniform(1, 500), rng.uniform(1, 300), w, h,
                         rng.uniform(-1, 100), -1, -1, -1])
    return np.array(rows)


@pytest.mark.parametrize("kind", SCORE_KINDS)
def test_score_maps_keep_the_order_and_ties(kind):
    s = np.array([3.0, -1.0, 2.0, 2.0, 100.0, 0.5])
    t = score_transform(s, kind)
    order = np.argsort(s, kind="stable")
    assert np.array_equal(np.argsort(t, kind="stable"), order)
    assert np.array_equal(np.diff(s[order]) > 0, np.diff(t[order]) > 0)
    if kind in ("probability", "rank"):
        assert np.all((t >= 0) & (t <= 1))


def test_each_kind_is_seeded_and_does_what_it_says():
    det = detections(np.random.default_rng(0))
    for kind in KINDS:
        if kind.startswith("fps"):
            continue
        a = perturb_detections(det, kind, np.random.default_rng(1), image_size=(640, 480))
        b = perturb_detections(det, kind, np.random.default_rng(1), image_size=(640, 480))
        np.testing.assert_array_equal(a, b)
    dropped = perturb_detections(det, "drop", np.random.default_rng(2))
    assert abs(len(dropped) / len(det) - 0.8) < 4 * np.sqrt(0.16 / len(det))
    fp = perturb_detections(det, "false-positives", np.random.default_rng(3),
                            image_size=(640, 480))
    extra = len(fp) - len(det)
    assert extra == round(0.2 * len(det))
    assert np.all(fp[:, 2] >= 1) and np.all(fp[:, 2] + fp[:, 4] <= 640 + 1e-9)
    assert np.all(fp[:, 3] >= 1) and np.all(fp[:, 3] + fp[:, 5] <= 480 + 1e-9)
    assert np.all(np.diff(fp[:, 0]) >= 0)  # still sorted by frame
    low = perturb_detections(det, "low-scores", np.random.default_rng(3), image_size=(640, 480))
    assert len(low) == 2 * len(det) and np.all(np.diff(low[:, 0]) >= 0)
    added = ~(low[:, None, :7] == det[None, :, :7]).all(axis=2).any(axis=1)
    assert added.sum() == len(det)  # as many more, every one new
    s = det[:, 6]
    assert np.all(low[added, 6] < s.min())  # below every score it gave ...
    assert np.all(low[added, 6] >= s.min() - 0.5 * np.ptp(s) - 1e-6)  # ... by at most half
    assert np.all(low[added, 2] >= 1) and np.all(low[added, 2] + low[added, 4] <= 640 + 1e-9)
    high = perturb_detections(det, "high-scores", np.random.default_rng(3))
    assert abs(len(high) / len(det) - 0.6) < 1.0 / len(det) + 1e-9
    removed = det[~np.isin(det[:, 6], high[:, 6])]
    assert high[:, 6].min() >= removed[:, 6].max()  # the lowest scores, and only they
    np.testing.assert_array_equal(high, det[det[:, 6] >= high[:, 6].min()])  # rows intact
    jit = perturb_detections(det, "jitter", np.random.default_rng(4))
    rel = (jit[:, 4] - det[:, 4]) / det[:, 4]
    assert abs(rel.std() - 0.05) < 0.01
    sh = perturb_detections(det, "shifted", np.random.default_rng(5))
    np.testing.assert_allclose(sh[:, 5], 1.1 * det[:, 5])
    np.testing.assert_allclose(sh[:, 2], det[:, 2] + 0.03 * det[:, 4])
    with pytest.raises(ValueError, match="unknown perturbation"):
        perturb_detections(det, "blur", np.random.default_rng(0))


def test_frame_rate_keeps_every_kth_frame_renumbered():
    """Every third frame from the first, or from the second or third (the phase): each
    row keeps its box, renumbered; the three phases share out every frame."""
    rows = np.array([[f, 1, f, 0, 1, 1, 1] for f in range(1, 11)], dtype=float)
    kept = keep_frames(rows, 3, 10)
    np.testing.assert_array_equal(kept[:, 0], [1, 2, 3, 4])
    np.testing.assert_array_equal(kept[:, 2], [1, 4, 7, 10])
    shares = [keep_frames(rows, 3, 10, phase)[:, 2] for phase in range(3)]
    np.testing.assert_array_equal(shares[1], [2, 5, 8])
    np.testing.assert_array_equal(keep_frames(rows, 3, 10, 2)[:, 0], [1, 2, 3])
    np.testing.assert_array_equal(np.sort(np.concatenate(shares)), np.arange(1, 11))
    with pytest.raises(ValueError, match="phase"):
        keep_frames(rows, 3, 10, 3)


@pytest.mark.data
def test_a_perturbed_sequence_reads_as_the_original(shared_data, tmp_path):
    from pgm.io.annotations import load_mot
    from pgm.io.video import open_source
    from pgm.observation.detections import PublicDetections

    src = shared_data / "TUD-Campus"
    orig = open_source(src)
    for kind in ("none", "fps/3", "false-positives"):
        out = perturb_sequence(src, tmp_path / kind.replace("/", "-"), kind, seed=0)
        seq = open_source(out)
        step = 3 if kind == "fps/3" else 1
        assert len(seq) == len(range(0, len(orig), step))
        assert seq.fps == pytest.approx(orig.fps / step)
        gt = load_mot(out / "gt" / "gt.txt", kind="gt")
        det = PublicDetections(out / "det" / "det.txt")
        assert gt.frames.max() <= len(seq) and det.table.frames.max() <= len(seq)
        first = next(iter(seq.frames()))[1]
        assert first.shape == next(iter(orig.frames()))[1].shape
    # the seed picks the phase of a frame rate: seed 1 starts at the original's frame 2
    out = perturb_sequence(src, tmp_path / "fps-3-seed1", "fps/3", seed=1)
    seq = open_source(out)
    assert len(seq) == len(range(1, len(orig), 3))
    second = [image for _, image in orig.frames(2, 3)][0]
    np.testing.assert_array_equal(next(iter(seq.frames()))[1], second)
    gt1 = load_mot(out / "gt" / "gt.txt", kind="gt")
    gt_orig = load_mot(src / "gt" / "gt.txt", kind="gt")
    np.testing.assert_array_equal(gt1.at(1)[1], gt_orig.at(2)[1])
    same = PublicDetections(tmp_path / "none" / "det" / "det.txt").table
    ref = PublicDetections(src / "det" / "det.txt").table
    np.testing.assert_allclose(same.boxes, ref.boxes)
    np.testing.assert_allclose(same.conf, ref.conf)
    with pytest.raises(ValueError, match="unknown perturbation"):
        perturb_sequence(src, tmp_path / "x", "blur")
