"""The correlation-filter likelihood: peak on the moved object, scale, illumination,
the confidence gate, and a saved model that loads."""

import cv2
import numpy as np
import pytest

from pgm.core.frame import FrameContext
from pgm.observation.appearance.correlation import CorrelationFilterLikelihood, peak_to_sidelobe


def texture(rng, shape, blur=2.0):
    t = cv2.GaussianBlur(rng.normal(0, 1, shape).astype(np.float32), (0, 0), blur)
    return (t - t.min()) / (t.max() - t.min())


def scene(rng, centre, size=(40, 56), scale=1.0, shape=(200, 260)):
    """A textured object (fixed texture, drawn at ``scale``) on a textured background."""
    bg = texture(np.random.default_rng(100), shape, 3.0) * 120 + 40
    obj = texture(np.random.default_rng(101), (size[1], size[0]), 1.5) * 200 + 30
    w, h = int(round(size[0] * scale)), int(round(size[1] * scale))
    obj = cv2.resize(obj, (w, h), interpolation=cv2.INTER_LINEAR)
    img = bg.copy()
    x0, y0 = int(round(centre[0] - w / 2)), int(round(centre[1] - h / 2))
    img[y0:y0 + h, x0:x0 + w] = obj
    img = img + rng.normal(0, 2, shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def grid(centre, size, shifts, scales=(1.0,)):
    return np.array([[centre[0] + dx, centre[1] + dy, size[0] * s, size[1] * s]
                     for dx in shifts for dy in shifts for s in scales])


def test_response_peaks_on_the_moved_object_and_ignores_illumination():
    rng = np.random.default_rng(0)
    f = CorrelationFilterLikelihood("object")
    f.initialize(FrameContext(1, scene(rng, (120, 100))), np.array([120.0, 100, 40, 56]))
    moved = scene(rng, (132, 93))
    x = grid((120, 100), (40, 56), np.arange(-20, 21, 1.0))
    ctx = FrameContext(2, moved)
    ll = f.log_likelihood(x, ctx)
    best = x[np.argmax(ll)]
    assert abs(best[0] - 132) <= 1 and abs(best[1] - 93) <= 1
    assert ll.max() > 0.5 * f.lam  # a typical peak scores about lam
    # away from the object the response is near zero
    far = np.abs(x[:, 0] - 132) + np.abs(x[:, 1] - 93) > 15
    assert np.median(ll[far]) < 0.15 * f.lam
    # a darker, lower-contrast frame: the same peak, about the same score
    dim = np.clip(0.5 * moved.astype(float) + 20, 0, 255).astype(np.uint8)
    ll_dim = f.log_likelihood(x, FrameContext(3, dim))
    np.testing.assert_allclose(x[np.argmax(ll_dim)], best)
    assert ll_dim.max() == pytest.approx(ll.max(), rel=0.1)


def test_response_prefers_the_true_scale():
    rng = np.random.default_rng(1)
    f = CorrelationFilterLikelihood("object", scales=5, scale_step=1.08)
    f.initialize(FrameContext(1, scene(rng, (130, 100))), np.array([130.0, 100, 40, 56]))
    grown = scene(rng, (130, 100), scale=1.25)
    scales = np.array([0.8, 1.0, 1.25, 1.5])
    x = grid((130, 100), (40, 56), [0.0], scales)
    ll = f.log_likelihood(x, FrameContext(2, grown))
    assert scales[np.argmax(ll)] == 1.25


def test_the_gate_keeps_an_occluder_out_of_the_filter():
    rng = np.random.default_rng(2)
    box = np.array([120.0, 100, 40, 56])
    f = CorrelationFilterLikelihood("object", adapt_rate=0.2, gate=0.5)
    f.initialize(FrameContext(1, scene(rng, (120, 100))), box)
    num = f.num.copy()
    # the object itself, slightly moved: confident, learned
    f.update({"object": box}, {}, FrameContext(2, scene(rng, (120, 100))))
    assert f.last_response > 0.5 and not np.allclose(f.num, num)
    psr_object = f.last_psr
    # a flat occluder over the object: not confident, not learned
    occluded = scene(rng, (120, 100))
    occluded[60:140, 90:150] = 128
    num = f.num.copy()
    f.update({"object": box}, {}, FrameContext(3, occluded))
    assert f.last_response < 0.5
    np.testing.assert_array_equal(f.num, num)
    # the map's peak-to-sidelobe ratio (the confidence's feature) falls with it
    assert f.last_psr < 0.5 * psr_object
    assert f.confidence_feature == pytest.approx(np.log(f.last_psr))


def test_peak_to_sidelobe_ratio_by_hand():
    r = np.zeros((9, 9))
    r[4, 4] = 10.0
    r[0, :] = 1.0  # side lobe outside the 5 x 5 square around the peak: 9 ones, 47 zeros
    side = np.r_[np.ones(9), np.zeros(81 - 25 - 9)]
    assert peak_to_sidelobe(r, 2) == pytest.approx((10 - side.mean()) / side.std())
    # the peak is found wherever it is (a square clipped at the border)
    r2 = np.roll(np.roll(r, -4, 0), -4, 1)
    assert np.isfinite(peak_to_sidelobe(r2, 2))
    with pytest.raises(ValueError, match="no side lobe"):
        peak_to_sidelobe(np.ones((3, 3)), 2)


def test_settings_are_checked_and_saved_with_the_model(tmp_path):
    for bad in ({"lam": float("nan")}, {"scales": 2}, {"padding": -1}, {"n_orient": 1},
                {"scale_step": 0.9}):
        with pytest.raises(ValueError):
            CorrelationFilterLikelihood("object", **bad)
    check_unlearned_refuses_and_saved_settings_load(
        CorrelationFilterLikelihood("object", lam=7.0, padding=2.0, gate=0.3), tmp_path)


def check_unlearned_refuses_and_saved_settings_load(f, tmp_path):
    """A box factor with no model yet refuses to score (a ``ValueError`` naming the
    model), and a graph holding it saves and loads with the same settings."""
    from pgm import FactorGraph, GaussianPrior, Variable

    with pytest.raises(ValueError, match="no num"):
        f.log_likelihood(np.zeros((1, 4)), FrameContext(1, np.zeros((10, 10), np.uint8)))
    g = FactorGraph([Variable("object", 4)],
                    [GaussianPrior("object", mean=[50.0, 40, 20, 20], cov=1.0), f], name="t")
    g.save(tmp_path / "g.json")
    loaded = FactorGraph.load(tmp_path / "g.json").factors[f.name]
    assert loaded.params() == f.params()


def _moving_scene(t, collar):
    """Frame ``t``: a textured object (40 x 56) moving 3 px a frame to the right over a
    static textured background; with ``collar`` a textured band twice the object's size
    around it moves with it (context that belongs to the object)."""
    bg = texture(np.random.default_rng(100), (200, 300), 2.0) * 160 + 40
    cx, cy = 100 + 3 * t, 100
    img = bg.copy()
    if collar:
        band = texture(np.random.default_rng(102), (112, 80), 1.5) * 160 + 40
        img[cy - 56:cy + 56, cx - 40:cx + 40] = band
    img[cy - 28:cy + 28, cx - 20:cx + 20] = texture(np.random.default_rng(101), (56, 40),
                                                    1.5) * 200 + 30
    img = img + np.random.default_rng(t).normal(0, 2, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8), np.array([cx, cy, 40.0, 56.0])


@pytest.mark.parametrize("collar", [False, True])
def test_context_learns_which_cells_move_with_the_object(collar):
    """``context_rate``: after 25 frames of steady motion the cells around the box read
    as static background (a static desk) or as moving with the object (a collar that
    moves with it); the box's own cells stay the object's."""
    f = CorrelationFilterLikelihood("object", context_rate=0.2)
    img, box = _moving_scene(0, collar)
    f.initialize(FrameContext(1, img), box)
    assert f.context is not None and np.all(np.isin(f.context, (0.5, 1.0)))
    for t in range(1, 26):
        img, box = _moving_scene(t, collar)
        f.update({"object": box}, None, FrameContext(t + 1, img))
    ring = _ring(f)
    assert np.all(f.context[f.box_cells] == 1.0)
    if collar:
        assert f.context[ring].mean() > 0.7
    else:
        assert f.context[ring].mean() < 0.3
    # without context_rate there is no map and the response is the whole window's
    plain = CorrelationFilterLikelihood("object")
    plain.initialize(FrameContext(1, img), box)
    assert plain.context is None


def _ring(f):
    """The cells between the box and twice its size (inside the window's Hann taper)."""
    th, tw = f.context.shape
    yy, xx = np.mgrid[0:th, 0:tw]
    u = np.abs(xx - (tw - 1) / 2) / (tw / 3 / 2)
    v = np.abs(yy - (th - 1) / 2) / (th / 3 / 2)
    return (np.maximum(u, v) > 1.2) & (np.maximum(u, v) < 1.8)


def test_context_is_learned_while_the_estimate_rests_on_the_desk():
    """A tracker held by the static desk does not move, so the estimate's own motion
    cannot tell the desk from the object. The box's own cells then place the object
    (their response's peak), and the window there is compared: the desk reads as static
    (below the even odds it started at). Once the object has left the box, its cells
    fail the gate and nothing more is learned: neither the context nor the filter."""
    f = CorrelationFilterLikelihood("object", context_rate=0.2)
    img, box0 = _moving_scene(0, False)
    f.initialize(FrameContext(1, img), box0)
    history = []
    for t in range(1, 12):  # the object moves 3 px a frame; the estimate stays
        img, _ = _moving_scene(t, False)
        f.update({"object": box0}, None, FrameContext(t + 1, img))
        history.append((f.context[_ring(f)].mean(), f.num.copy()))
    # the first frame's move (3 px, two cells) is seen: the desk reads as static, where
    # the estimate's own (null) motion would have left it at even odds
    assert history[0][0] < 0.45
    assert all(ring <= history[0][0] for ring, _ in history)
    # the object 15 px out of its 40 px box and further: no more learning
    for ring, num in history[5:]:
        assert ring == history[4][0] and np.array_equal(num, history[4][1])


def test_context_is_dropped_when_the_camera_moves():
    """Learning which cells stay where they were needs a still camera. A camera that
    follows the object moves the whole background: from the start, the first frame's
    check finds it (each of the first 20 frames is checked on its own); later, the
    still-camera check's verdict (16 of 20 frames moving:
    :class:`~pgm.observation.camera_motion.CameraMotionEstimator`, ``auto``). The
    context is then dropped (every cell counts, as without ``context_rate``); on the
    still camera of the same scene it is kept."""
    desk = texture(np.random.default_rng(100), (200, 500), 2.0) * 160 + 40
    obj = texture(np.random.default_rng(101), (56, 40), 1.5) * 200 + 30

    def frame(t, pan_from):
        p = max(0, t - pan_from)  # frames the camera has followed the object
        img = desk[:, 3 * p:3 * p + 300].copy()
        cx = 120 + 2 * (t - p)
        img[72:128, cx - 20:cx + 20] = obj
        img = img + np.random.default_rng(t).normal(0, 2, img.shape)
        return np.clip(img, 0, 255).astype(np.uint8), np.array([cx, 100, 40.0, 56.0])

    for pan_from, moved_at in ((0, (2, 2)), (30, (47, 52)), (None, None)):
        f = CorrelationFilterLikelihood("object", context_rate=0.2)
        img, box = frame(0, pan_from or 99)
        f.initialize(FrameContext(1, img), box)
        for t in range(1, 60):
            img, box = frame(t, 99 if pan_from is None else pan_from)
            f.update({"object": box}, None, FrameContext(t + 1, img))
        if moved_at:
            assert f.context is None and moved_at[0] <= f.camera_moved_at <= moved_at[1]
        else:
            assert f.context is not None and f.camera_moved_at is None
            assert f.context[_ring(f)].mean() < 0.3


def _soft_binned_reference(patch, n_orient):
    """patch_features written as the formula reads (np.mod, the circle's distance for
    every bin): what the in-place version must equal bit for bit."""
    gx = cv2.Sobel(patch, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(patch, cv2.CV_32F, 0, 1, ksize=3)
    mag = np.sqrt(gx * gx + gy * gy)
    theta = np.mod(np.arctan2(gy, gx), np.pi) * (n_orient / np.pi)
    energy = np.sqrt(np.maximum(cv2.boxFilter(mag * mag, -1, (5, 5)), 0)) + 1e-3 * 255
    out = [(patch - float(patch.mean())) / (float(patch.std()) + 1e-3 * 255) * 0.5]
    for c in range(n_orient):
        d = np.abs(theta - c)
        d = np.minimum(d, n_orient - d)
        out.append(cv2.boxFilter(mag * np.maximum(1 - d, 0), -1, (3, 3)) / energy)
    return np.stack(out).astype(np.float32)


@pytest.mark.parametrize("n_orient", [1, 3, 6, 9])
def test_patch_features_are_the_soft_binning_formula_bit_for_bit(n_orient):
    from pgm.observation.appearance.cf_features import patch_features

    rng = np.random.default_rng(n_orient)
    for k in range(12):
        p = (rng.random((int(rng.integers(5, 90)), int(rng.integers(5, 90)))) * 255)
        p = p.astype(np.float32)
        if k % 3 == 0:  # flat areas: zero gradients, angles of exactly 0 and pi
            p = np.round(p / 64) * 64
        elif k % 3 == 1:
            p = cv2.GaussianBlur(p, (5, 5), 2)
        assert np.array_equal(patch_features(p, n_orient), _soft_binned_reference(p, n_orient))


def _smooth(n: int) -> bool:
    """Whether ``n`` has no prime factor above 5."""
    for p in (2, 3, 5):
        while n % p == 0:
            n //= p
    return n == 1


def test_the_window_has_fast_fourier_sides_and_keeps_its_extent():
    """Each side of the window, in cells, is the even number nearest the exact size whose
    half has no prime factor above 5 (the FFTs run on it every frame); the window still
    covers ``(1 + padding)`` boxes of the image."""
    from pgm.observation.appearance.cf_features import _fast_even

    for cells in np.arange(8.0, 400.0, 0.5):
        side = _fast_even(cells)
        assert side % 2 == 0 and side >= 8 and _smooth(side // 2)
        half = max(4, int(round(cells / 2)))
        smooth = [k for k in range(4, 2 * half + 8) if _smooth(k)]
        best = min(abs(k - half) for k in smooth)
        assert abs(side // 2 - half) == best, cells
        limit = 1 / 17 if half >= 32 else 1 / 11 if half >= 16 else 1 / 7
        assert abs(side / (2 * half) - 1) <= limit + 1e-12, cells
    assert [_smooth(n) for n in (1, 30, 79, 158 // 2, 81, 14)] == [True, True, False, False,
                                                                   True, False]
    # a drone video's person, 13 x 35.4 px: 158 x 58 cells at the exact size, 79 and 29 prime
    f = CorrelationFilterLikelihood("object")
    f.initialize(FrameContext(1, scene(np.random.default_rng(0), (120, 100))),
                 np.array([120.0, 100, 13, 35.4]))
    assert f.hann.shape == (160, 60) and f.shape == (60, 160)
    np.testing.assert_allclose(f.ref_size, np.array([13.0, 35.4]) * (1 + f.padding))
