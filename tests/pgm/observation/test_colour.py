"""Colour-histogram likelihood: quantisation, vectorised box histograms, rho, cache."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from reference import reference_box_histograms

from pgm.core.frame import FrameContext
from pgm.observation.appearance.colour import (
    ColourHistogramScorer,
    bhattacharyya,
    box_histograms,
    colour_bin_count,
    quantize_colour,
)
from pgm.observation.appearance.colour import cache as colour_cache
from pgm.observation.appearance.colour import integral as colour_integral

DATA = Path(__file__).resolve().parents[4] / "shared" / "data"


def _random_boxes(rng, n, width, height):
    """Boxes anywhere from well outside to inside, tiny to larger than the image."""
    cx = rng.uniform(-0.4 * width, 1.4 * width, n)
    cy = rng.uniform(-0.4 * height, 1.4 * height, n)
    w = np.exp(rng.uniform(np.log(0.3), np.log(1.2 * width), n))
    h = np.exp(rng.uniform(np.log(0.3), np.log(1.2 * height), n))
    return np.column_stack([cx, cy, w, h])


def _numpy_quantize(img, layout, a, b, c):
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV).astype(int)
    H, S, V = hsv[..., 0], hsv[..., 1], hsv[..., 2]
    if layout == "perez":
        return np.where((S >= 26) & (V >= 52), (H * a // 180) * b + S * b // 256,
                        a * b + V * c // 256)
    return ((H * a // 180) * b + S * b // 256) * c + V * c // 256


# --- quantisation ------------------------------------------------------------------------

@pytest.mark.parametrize("layout,a,b,c", [
    ("perez", 16, 4, 16), ("perez", 10, 3, 7), ("perez", 30, 8, 16),
    ("hsv", 16, 4, 4), ("hsv", 10, 5, 5), ("hsv", 16, 8, 8)])
def test_quantize_matches_numpy_formula(layout, a, b, c):
    img = np.random.default_rng(11).integers(0, 256, (150, 170, 3), dtype=np.uint8)
    bins, n_bins = quantize_colour(img, layout, a, b, c)
    assert n_bins == colour_bin_count(layout, a, b, c)
    assert bins.shape == img.shape[:2]
    assert bins.dtype == (np.uint8 if n_bins <= 256 else np.uint16)
    np.testing.assert_array_equal(bins, _numpy_quantize(img, layout, a, b, c))


@pytest.mark.parametrize("layout,a,b,c", [
    ("perez", 16, 4, 16), ("perez", 10, 3, 7), ("hsv", 16, 4, 4), ("hsv", 10, 5, 5)])
def test_quantize_greyscale_shortcut_matches_cvtcolor(layout, a, b, c):
    # equal channels skip cvtColor (H = S = 0, V = level): every grey level, and
    # frames that are grey except for one pixel (first row grey, then not)
    levels = np.arange(256, dtype=np.uint8).reshape(16, 16)
    grey = cv2.cvtColor(levels, cv2.COLOR_GRAY2BGR)
    np.testing.assert_array_equal(quantize_colour(grey, layout, a, b, c)[0],
                                  _numpy_quantize(grey, layout, a, b, c))
    for y, x, ch in [(5, 7, 0), (15, 15, 2), (0, 3, 1)]:
        img = grey.copy()
        img[y, x, ch] ^= 0x55
        np.testing.assert_array_equal(quantize_colour(img, layout, a, b, c)[0],
                                      _numpy_quantize(img, layout, a, b, c))


@pytest.mark.parametrize("n", [4, 5, 8])
def test_quantize_rgb(n):
    img = np.random.default_rng(12).integers(0, 256, (40, 50, 3), dtype=np.uint8)
    bins, n_bins = quantize_colour(img, "rgb", n_rgb=n)
    bl, g, r = (img[..., i].astype(int) * n // 256 for i in range(3))
    assert n_bins == n ** 3
    np.testing.assert_array_equal(bins, (r * n + g) * n + bl)


def test_default_bin_counts():
    assert colour_bin_count() == 80                       # perez 16x4 + 16
    assert colour_bin_count("hsv") == 256                 # 16x4x4
    assert colour_bin_count("rgb") == 512                 # 8x8x8


def _grey_frame():
    path = DATA / "FaceOcc1" / "imgs" / "img00000.png"
    if path.exists():
        return cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    ramp = np.tile(np.arange(256, dtype=np.uint8), (64, 1))   # every grey level
    return ramp


def test_greyscale_keeps_intensity_bins_under_perez_only():
    # FaceOcc1 frame 0 (or a 0..255 ramp): "perez" keeps its 16 value bins (the
    # frame occupies 16 of them; >= 10 required), "hsv" collapses onto the 4 value
    # bins of hue 0 / saturation 0 (at most 4 occupied bins).
    grey = _grey_frame()
    perez, _ = quantize_colour(grey, "perez")
    hsv, _ = quantize_colour(grey, "hsv")
    assert len(np.unique(perez)) >= 10
    assert len(np.unique(hsv)) <= 4
    # three equal channels (how FrameContext delivers greyscale) quantise the same
    np.testing.assert_array_equal(quantize_colour(cv2.cvtColor(grey, cv2.COLOR_GRAY2BGR),
                                                  "perez")[0], perez)


# --- vectorised histograms against the loop reference -----------------------------------

@pytest.mark.parametrize("layout", ["perez", "hsv", "rgb"])
def test_box_histograms_equal_loop_reference(layout):
    rng = np.random.default_rng(21)
    img = rng.integers(0, 256, (97, 131, 3), dtype=np.uint8)
    bins, n_bins = quantize_colour(img, layout)
    boxes = _random_boxes(rng, 400, 131, 97)
    boxes[:5] = [[-30, 40, 20, 20], [200, 40, 20, 20], [60, -70, 10, 10],  # outside
                 [0, 0, 40, 40], [130.5, 96.5, 3, 3]]                     # corners
    hist, in_frac = box_histograms(bins, n_bins, boxes)
    counts, ref_frac = reference_box_histograms(bins, n_bins, boxes)
    assert hist.shape == (400, n_bins) and hist.dtype == np.float64
    np.testing.assert_array_equal(in_frac, ref_frac)
    inside = counts.sum(axis=1)
    # integer counts exactly (counts = hist * in-image pixel count)
    np.testing.assert_array_equal(np.rint(hist * inside[:, None]).astype(np.int64), counts)
    ref = counts / np.maximum(inside, 1)[:, None]
    np.testing.assert_allclose(hist, ref, rtol=0, atol=1e-12)
    assert np.all(hist[:3] == 0) and np.all(in_frac[:3] == 0)
    assert np.all(in_frac[inside > 0] > 0)


@pytest.mark.parametrize("layout", ["hsv", "perez"])
@pytest.mark.parametrize("n_boxes", [3, 40, 150])
def test_all_integral_paths_equal_reference(monkeypatch, n_boxes, layout):
    # dense: several bin blocks, block-by-block one-hot (large-union path);
    # compressed: the grid of distinct corner coordinates (few boxes), by
    # cv2.calcHist (perez: 80 slots) or np.bincount (hsv: 256 slots > 255)
    rng = np.random.default_rng(22)
    img = rng.integers(0, 256, (80, 90, 3), dtype=np.uint8)
    bins, n_bins = quantize_colour(img, layout)
    boxes = _random_boxes(rng, n_boxes, 90, 80)
    counts, _ = reference_box_histograms(bins, n_bins, boxes)
    ref = counts / np.maximum(counts.sum(axis=1), 1)[:, None]
    for bias, block, onehot in [(0.0, 1, 1 << 40), (0.0, 50_000, 1 << 40),
                                (0.0, 50_000, 1), (0.0, 1, 1), (1e9, 1 << 20, 1 << 40)]:
        monkeypatch.setattr(colour_integral, "_COMPRESS_BIAS", bias)
        monkeypatch.setattr(colour_integral, "_BLOCK_BYTES", block)
        monkeypatch.setattr(colour_integral, "_ONEHOT_BYTES", onehot)
        hist, _ = box_histograms(bins, n_bins, boxes)
        np.testing.assert_allclose(hist, ref, rtol=0, atol=1e-12)


@pytest.mark.parametrize("method", ["dense", "compressed"])
def test_counts_paths_on_clustered_boxes(method):
    # tracker-like boxes: 40x80 around a point, some beyond the top-left corner
    rng = np.random.default_rng(23)
    img = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    bins, n_bins = quantize_colour(img, "perez")
    for centre in ([80.0, 60.0], [10.0, 15.0]):
        for n in (5, 30, 200):
            boxes = np.column_stack([centre + 12 * rng.standard_normal((n, 2)),
                                     np.full(n, 40.0), np.full(n, 80.0)])
            xa, xb, ya, yb, _, _ = colour_integral._pixel_bounds(boxes, *bins.shape)
            counts = colour_integral._corner_counts(bins, xa, xb, ya, yb, np.arange(n_bins),
                                           n_bins, method)
            ref, _ = reference_box_histograms(bins, n_bins, boxes)
            np.testing.assert_array_equal(counts.T, ref)


def test_rounding_convention():
    bins = np.arange(20, dtype=np.uint8).reshape(1, 20).repeat(3, axis=0)
    # columns [round(cx - w/2), round(cx + w/2)) = [3, 7), rounding half up
    hist, _ = box_histograms(bins, 20, np.array([[5.0, 1.5, 4.0, 3.0]]))
    np.testing.assert_allclose(hist[0, 3:7], 0.25)
    hist, _ = box_histograms(bins, 20, np.array([[5.5, 1.5, 3.0, 3.0]]))   # [4, 7)
    assert np.count_nonzero(hist[0]) == 3 and hist[0, 4] > 0
    # a valid box always covers at least one pixel
    hist, frac = box_histograms(bins, 20, np.array([[10.0, 1.0, 0.2, 0.2]]))
    assert frac[0] == 1.0 and hist[0].sum() == pytest.approx(1.0)


def test_empty_box_list():
    bins = np.zeros((5, 5), np.uint8)
    hist, frac = box_histograms(bins, 80, np.zeros((0, 4)))
    assert hist.shape == (0, 80) and frac.shape == (0,)
    img = np.random.default_rng(13).integers(0, 256, (20, 20, 3), dtype=np.uint8)
    for kernel in ("uniform", "epanechnikov", "grid-uniform"):
        scorer = ColourHistogramScorer(kernel=kernel)
        scorer.template(img, (10, 10, 8, 8))
        assert scorer.rho(img, np.zeros((0, 4))).shape == (0,)


# --- rho -------------------------------------------------------------------------------

@pytest.mark.parametrize("layout", ["perez", "hsv"])
def test_rho_equals_reference(layout):
    rng = np.random.default_rng(31)
    img = rng.integers(0, 256, (90, 120, 3), dtype=np.uint8)
    img[20:60, 30:70] = rng.integers(0, 120, (40, 40, 3), dtype=np.uint8)
    scorer = ColourHistogramScorer(layout)
    ctx = FrameContext(1, img)
    q = scorer.template(ctx, (50, 40, 40, 40))
    assert q.shape == (scorer.n_bins,) and q.sum() == pytest.approx(1.0)
    boxes = _random_boxes(rng, 300, 120, 90)
    counts, frac = reference_box_histograms(scorer.bins(ctx), scorer.n_bins, boxes)
    p = counts / np.maximum(counts.sum(axis=1), 1)[:, None]
    expected = np.sqrt(p) @ np.sqrt(q) * frac
    np.testing.assert_allclose(scorer.rho(ctx, boxes), expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(bhattacharyya(p, q) * frac, expected, atol=1e-12)


def _patch_scene(seed):
    """Noise background with a colourful textured 30x50 patch centred at (70, 60)."""
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    patch = np.zeros((50, 30, 3), np.uint8)
    patch[..., 0] = rng.integers(150, 256, (50, 30))
    patch[..., 1] = rng.integers(0, 60, (50, 30))
    patch[..., 2] = (np.arange(30)[None, :] * 8).astype(np.uint8)   # texture: a ramp
    img[35:85, 55:85] = patch
    return img, np.array([70.0, 60.0, 30.0, 50.0])


@pytest.mark.parametrize("layout", ["perez", "hsv"])
@pytest.mark.parametrize("kernel", ["uniform", "epanechnikov", "grid-uniform"])
def test_rho_peaks_at_true_box(layout, kernel):
    img, box = _patch_scene(41)
    scorer = ColourHistogramScorer(layout, kernel=kernel)
    ctx = FrameContext(1, img)
    scorer.template(ctx, box)
    d = np.arange(-15, 16)
    dx, dy = np.meshgrid(d, d)
    boxes = np.column_stack([box[0] + dx.ravel(), box[1] + dy.ravel(),
                             np.full(dx.size, box[2]), np.full(dx.size, box[3])])
    rho = scorer.rho(ctx, boxes)
    best = np.argmax(rho)
    assert (dx.ravel()[best], dy.ravel()[best]) == (0, 0)
    assert rho[best] == pytest.approx(1.0)
    assert np.all(rho <= 1.0 + 1e-12) and np.all(rho >= 0)


def test_in_frac_half_outside_and_wholly_outside():
    img, box = _patch_scene(42)
    bins, n_bins = quantize_colour(img)
    boxes = np.array([[0.0, 60.0, 40.0, 20.0],        # half outside on the left
                      [160.0, 60.0, 40.0, 20.0],      # half outside on the right
                      [80.0, 120.0, 20.0, 30.0],      # half outside at the bottom
                      [-50.0, 60.0, 40.0, 20.0],      # wholly outside
                      [80.0, 200.0, 40.0, 20.0]])     # wholly outside
    hist, frac = box_histograms(bins, n_bins, boxes)
    np.testing.assert_array_equal(frac, [0.5, 0.5, 0.5, 0.0, 0.0])
    np.testing.assert_allclose(hist[:3].sum(axis=1), 1.0)
    assert np.all(hist[3:] == 0)
    for kernel in ("uniform", "epanechnikov", "grid-uniform"):
        scorer = ColourHistogramScorer(kernel=kernel)
        scorer.template(img, box)
        rho = scorer.rho(img, boxes)
        assert rho[3] == 0 and rho[4] == 0
        _, kfrac = scorer.histograms(img, boxes)
        np.testing.assert_allclose(kfrac, [0.5, 0.5, 0.5, 0.0, 0.0], atol=1e-12)
    # uniform rho of a half-outside box = Bhattacharyya of its in-image half x 0.5
    scorer = ColourHistogramScorer()
    q = scorer.template(img, box)
    assert scorer.rho(img, boxes[:1])[0] == pytest.approx(0.5 * bhattacharyya(hist[0], q))


def test_grid_kernels_approximate_and_normalise():
    rng = np.random.default_rng(51)
    img = rng.integers(0, 256, (100, 100, 3), dtype=np.uint8)
    bins, n_bins = quantize_colour(img, "perez", 4, 2, 4)     # 12 coarse bins
    boxes = np.column_stack([rng.uniform(30, 70, 50), rng.uniform(30, 70, 50),
                             np.full(50, 48.0), np.full(50, 48.0)])
    exact, _ = box_histograms(bins, n_bins, boxes)
    for kernel in ("epanechnikov", "grid-uniform"):
        scorer = ColourHistogramScorer("perez", 4, 2, 4, kernel=kernel, grid=24)
        hist, frac = scorer.histograms(img, boxes)
        np.testing.assert_allclose(hist.sum(axis=1), 1.0)
        np.testing.assert_allclose(frac, 1.0)
        assert np.abs(hist - exact).sum(axis=1).max() < 0.2
    flat = np.full((40, 40, 3), (200, 30, 30), np.uint8)
    hist, _ = ColourHistogramScorer(kernel="epanechnikov").histograms(
        flat, np.array([[20.0, 20.0, 16.0, 16.0]]))
    assert np.count_nonzero(hist[0]) == 1 and hist[0].max() == pytest.approx(1.0)


# --- cache -----------------------------------------------------------------------------

def _count_quantisation(monkeypatch):
    """Record ``(layout, (h, w))`` of every region quantisation."""
    calls = []
    real = colour_cache._quantize_bgr

    def counting(img, canon):
        calls.append((canon[0], img.shape[:2]))
        return real(img, canon)

    monkeypatch.setattr(colour_cache, "_quantize_bgr", counting)
    return calls


def test_quantisation_happens_once_per_frame(monkeypatch):
    calls = _count_quantisation(monkeypatch)
    img, box = _patch_scene(61)
    ctx = FrameContext(3, img)
    a = ColourHistogramScorer("perez")
    b = ColourHistogramScorer("perez", kernel="epanechnikov")    # same layout: shares
    c = ColourHistogramScorer("hsv")
    a.template(ctx, box)
    boxes = np.tile(box, (10, 1))
    r1 = a.rho(ctx, boxes)
    r2 = a.rho(ctx, boxes)
    b.rho(ctx, boxes, q=a.q)
    assert len(calls) == 1
    np.testing.assert_array_equal(r1, r2)
    assert ("colour-bins", "perez", 16, 4, 16) in ctx._cache
    c.template(ctx, box)
    c.rho(ctx, boxes)
    assert [layout for layout, _ in calls] == ["perez", "hsv"]
    # a raw image is wrapped (and quantised) on every call
    a.rho(img, boxes)
    assert len(calls) == 3


# --- lazy region quantisation ------------------------------------------------------------

def test_only_the_boxes_union_is_quantised(monkeypatch):
    calls = _count_quantisation(monkeypatch)
    img, box = _patch_scene(62)                        # 160x120
    ctx = FrameContext(1, img)
    scorer = ColourHistogramScorer()
    scorer.template(ctx, box)                          # 30x50 box at (70, 60)
    m = colour_integral._ROI_MARGIN
    assert calls == [("perez", (50 + 2 * m, 30 + 2 * m))]
    frame = ctx._cache[scorer.cache_key]
    assert frame.rect == (55 - m, 85 + m, 35 - m, 85 + m)
    assert frame.pixels == (30 + 2 * m) * (50 + 2 * m) < img.shape[0] * img.shape[1] // 4
    # boxes inside the quantised rectangle (the margin) cost nothing
    scorer.rho(ctx, np.array([box + [1, -1, 2, 2], box - [2, 0, 0, 0]]))
    assert len(calls) == 1


def test_lazy_bins_equal_full_frame_quantisation():
    rng = np.random.default_rng(63)
    img = rng.integers(0, 256, (90, 130, 3), dtype=np.uint8)
    for layout in ("perez", "hsv", "rgb"):
        full, _ = quantize_colour(img, layout)
        scorer = ColourHistogramScorer(layout)
        frame = scorer._frame(FrameContext(1, img))
        for rect in [(10, 40, 20, 50), (30, 70, 5, 30), (0, 5, 80, 90), (120, 200, -9, 3)]:
            bins = frame.ensure(*rect)
            x0, x1, y0, y1 = rect
            np.testing.assert_array_equal(bins[max(y0, 0):y1, max(x0, 0):x1],
                                          full[max(y0, 0):y1, max(x0, 0):x1])
            rx0, rx1, ry0, ry1 = frame.rect              # the whole rectangle is valid
            np.testing.assert_array_equal(bins[ry0:ry1, rx0:rx1], full[ry0:ry1, rx0:rx1])
        np.testing.assert_array_equal(scorer.bins(FrameContext(2, img)), full)
    # greyscale (H, W) images are quantised region by region too
    grey = rng.integers(0, 256, (40, 50), dtype=np.uint8)
    frame = ColourHistogramScorer()._frame(FrameContext(1, grey))
    np.testing.assert_array_equal(frame.ensure(5, 20, 10, 30)[10:30, 5:20],
                                  quantize_colour(grey)[0][10:30, 5:20])


@pytest.mark.parametrize("call_pixels", [0, 10 ** 9])
def test_scorers_sharing_a_layout_quantise_overlaps_once(monkeypatch, call_pixels):
    # three band scorers of one face (a part graph) on one frame: the first
    # quantises its band's boxes, the others only the strips they add (or, when a
    # call costs more than re-quantising the old rectangle, the new bounding box)
    monkeypatch.setattr(colour_cache, "_CALL_PIXELS", call_pixels)
    rng = np.random.default_rng(64)
    img = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    full_bins = quantize_colour(img)[0]
    calls = _count_quantisation(monkeypatch)
    bands = [np.array([80.0, 30.0 + 20.0 * (j + 0.5), 40.0, 20.0]) for j in range(3)]
    scorers = [ColourHistogramScorer() for _ in bands]
    for s, band in zip(scorers, bands, strict=True):
        s.template(img, band)
    calls.clear()
    ctx = FrameContext(2, img)
    rhos = []
    for s, band in zip(scorers, bands, strict=True):
        boxes = band + np.column_stack([rng.normal(0, 1.5, (10, 2)), np.zeros((10, 2))])
        rhos.append(s.rho(ctx, boxes))
        counts, frac = reference_box_histograms(full_bins, s.n_bins, boxes)
        p = counts / np.maximum(counts.sum(axis=1), 1)[:, None]
        np.testing.assert_allclose(rhos[-1], np.sqrt(p) @ np.sqrt(s.q) * frac, atol=1e-12)
    frame = ctx._cache[scorers[0].cache_key]
    x0, x1, y0, y1 = frame.rect
    slack = colour_integral._ROI_MARGIN + 8                     # margin + jitter
    assert (x0 >= 60 - slack and x1 <= 100 + slack and y0 >= 30 - slack
            and y1 <= 90 + slack)                      # the face (60..100, 30..90)
    assert frame.pixels == sum(h * w for _, (h, w) in calls)
    np.testing.assert_array_equal(frame.bins[y0:y1, x0:x1], full_bins[y0:y1, x0:x1])
    if call_pixels == 0:
        # every pixel quantised once: the calls tile the final rectangle
        assert frame.pixels == (x1 - x0) * (y1 - y0) and 3 <= len(calls) <= 1 + 2 * 4
    else:
        assert len(calls) == 3
    # a full-frame request quantises only what is left, and then nothing more
    n_before, px_before = len(calls), frame.pixels
    full = scorers[0].bins(ctx)
    np.testing.assert_array_equal(full, full_bins)
    assert len(calls) <= n_before + 4
    frame_px = img.shape[0] * img.shape[1]
    assert frame.pixels - px_before == (frame_px - (x1 - x0) * (y1 - y0) if call_pixels == 0
                                        else frame_px)
    n_before = len(calls)
    scorers[1].rho(ctx, np.array([[10.0, 10.0, 30.0, 30.0], [150.0, 110.0, 30.0, 30.0]]))
    scorers[1].histograms(ctx, np.array([[100.0, 50.0, 20.0, 20.0]]))
    assert len(calls) == n_before


def test_request_after_full_frame_bins_costs_nothing(monkeypatch):
    calls = _count_quantisation(monkeypatch)
    img, box = _patch_scene(65)
    ctx = FrameContext(1, img)
    for kernel in ("uniform", "epanechnikov"):
        scorer = ColourHistogramScorer(kernel=kernel)
        scorer.bins(ctx)
        scorer.template(ctx, box)
        scorer.rho(ctx, np.array([[5.0, 5.0, 40.0, 40.0], [150.0, 100.0, 60.0, 60.0]]))
    assert calls == [("perez", img.shape[:2])]


@pytest.mark.parametrize("kernel,bias", [("uniform", 0.0), ("uniform", 1e9),
                                         ("epanechnikov", 1.0), ("grid-uniform", 1.0)])
def test_lazy_scoring_of_boxes_partly_outside_matches_reference(monkeypatch, kernel, bias):
    monkeypatch.setattr(colour_integral, "_COMPRESS_BIAS", bias)   # dense / compressed counts
    rng = np.random.default_rng(66)
    img = rng.integers(0, 256, (70, 100, 3), dtype=np.uint8)
    boxes = _random_boxes(rng, 60, 100, 70)
    boxes[:4] = [[-5, 30, 20, 20], [98, 68, 10, 12], [50, -3, 30, 10], [-50, 30, 10, 10]]
    lazy = ColourHistogramScorer(kernel=kernel)
    full = ColourHistogramScorer(kernel=kernel)
    q = full.template(img, (50, 35, 30, 30))
    ctx_full = FrameContext(1, img)
    full.bins(ctx_full)                                  # whole frame first
    for n in (4, 10, 60):
        ctx = FrameContext(1, img)
        rho = lazy.rho(ctx, boxes[:n], q)
        np.testing.assert_array_equal(rho, full.rho(ctx_full, boxes[:n], q))
        hist, frac = lazy.histograms(FrameContext(1, img), boxes[:n])
        ref_hist, ref_frac = full.histograms(ctx_full, boxes[:n])
        np.testing.assert_array_equal(hist, ref_hist)
        np.testing.assert_array_equal(frac, ref_frac)
        if kernel == "uniform":
            counts, ref = reference_box_histograms(quantize_colour(img)[0], lazy.n_bins,
                                                    boxes[:n])
            np.testing.assert_array_equal(frac, ref)
            inside = counts.sum(axis=1)
            np.testing.assert_array_equal(np.rint(hist * inside[:, None]), counts)
            p = counts / np.maximum(inside, 1)[:, None]
            np.testing.assert_allclose(rho, np.sqrt(p) @ np.sqrt(q) * ref, atol=1e-12)
            assert rho[3] == 0


def test_template_cache_follows_the_values_of_q():
    img, box = _patch_scene(67)
    scorer = ColourHistogramScorer()
    q = scorer.template(img, box)
    ctx = FrameContext(1, img)
    boxes = np.tile(box, (5, 1)) + [[3, 0, 0, 0]]
    r1 = scorer.rho(ctx, boxes, q)
    q2 = q.copy()
    q2[np.argmax(q)] = 0.0                               # same array object mutated
    r2 = scorer.rho(ctx, boxes, q2)
    assert not np.allclose(r1, r2)
    q[:] = q2
    np.testing.assert_array_equal(scorer.rho(ctx, boxes, q), r2)
    scorer.q = q2 * 3.0                                  # stored q used as it is
    np.testing.assert_allclose(scorer.rho(ctx, boxes), r2 * np.sqrt(3.0 * q2.sum()),
                               rtol=1e-12)


# --- validation ------------------------------------------------------------------------

@pytest.mark.parametrize("boxes,word", [
    (np.array([[1.0, 2.0, 3.0]]), "shape"),
    (np.array([1.0, 2.0, 3.0, 4.0]), "shape"),
    (np.array([[1.0, np.nan, 3.0, 4.0]]), "finite"),
    (np.array([[1.0, 2.0, np.inf, 4.0]]), "finite"),
    (np.array([[1.0, 2.0, 0.0, 4.0]]), "w > 0"),
    (np.array([[1.0, 2.0, 3.0, -4.0]]), "h > 0"),
    (np.array([[1.0, 2.0, 3.0, 4.0], [5.0, 6.0, -0.5, 4.0]]),
     r"1 of 2 boxes \(cx, cy, w, h\) do not, e.g. \[5.0, 6.0, -0.5, 4.0\]"),
])
def test_bad_boxes_raise(boxes, word):
    img = np.zeros((20, 20, 3), np.uint8)
    scorer = ColourHistogramScorer()
    scorer.template(img, (10, 10, 5, 5))
    with pytest.raises(ValueError, match=word):
        scorer.rho(img, boxes)
    with pytest.raises(ValueError, match=word):
        box_histograms(quantize_colour(img)[0], 80, boxes)


@pytest.mark.parametrize("image", [
    np.zeros((10, 10, 3), np.float32), np.zeros((10, 10, 4), np.uint8),
    np.zeros((10,), np.uint8), np.zeros((0, 10, 3), np.uint8)])
def test_bad_image_raises(image):
    with pytest.raises(ValueError, match="image"):
        quantize_colour(image)


def test_bad_parameters_raise():
    with pytest.raises(ValueError, match="layout"):
        ColourHistogramScorer("lab")
    with pytest.raises(ValueError, match="kernel"):
        ColourHistogramScorer(kernel="gauss")
    with pytest.raises(ValueError, match="n_h"):
        quantize_colour(np.zeros((4, 4, 3), np.uint8), "perez", n_h=0)
    scorer = ColourHistogramScorer()
    img = np.zeros((20, 20, 3), np.uint8)
    with pytest.raises(ValueError, match="template"):
        scorer.rho(img, np.array([[5.0, 5.0, 2.0, 2.0]]))
    with pytest.raises(ValueError, match="outside"):
        scorer.template(img, (-50, -50, 10, 10))
    with pytest.raises(ValueError, match="shape"):
        scorer.rho(img, np.array([[5.0, 5.0, 2.0, 2.0]]), q=np.ones(7))


@pytest.mark.parametrize("kernel", ["uniform", "epanechnikov"])
def test_rho_many_equals_rho_per_template(kernel):
    rng = np.random.default_rng(21)
    img = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    sc = ColourHistogramScorer(kernel=kernel)
    T = np.array([sc.template(img, b) for b in ((50, 40, 30, 20), (50, 60, 30, 20),
                                                 (90, 80, 20, 30))])
    boxes = np.column_stack([rng.normal(70, 25, 40), rng.normal(60, 25, 40),
                             rng.uniform(10, 40, 40), rng.uniform(10, 40, 40)])
    owner = rng.integers(0, 3, 40)
    got = sc.rho_many(FrameContext(1, img), boxes, T, owner)
    want = np.array([sc.rho(FrameContext(1, img), boxes[i:i + 1], T[owner[i]])[0]
                     for i in range(40)])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
