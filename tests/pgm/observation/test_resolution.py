"""Appearance at the resolution it needs (issue 39, item 1): each box read from a bounded
number of pixels, every track scored against every detection in one pass per cue, and the
exact answers those passes must equal."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from pgm.core.frame import FrameContext
from pgm.core.resolution import (
    BOX_PIXELS,
    MAX_LEVEL,
    appearance_matrix,
    box_levels,
    learn_all,
    pyramid_level,
    working_frames,
)
from pgm.observation.appearance.colour import ColourHistogramScorer
from pgm.observation.appearance.likelihoods import (
    ColourHistogramLikelihood,
    GradientLikelihood,
    RotationInvariantLikelihood,
    TemplateLikelihood,
)


def _image(rng, h=300, w=400):
    """Smooth colour noise: neighbouring pixels alike, as in a photograph."""
    img = rng.integers(0, 256, (h // 4, w // 4, 3), dtype=np.uint8)
    img = cv2.resize(img, (w, h), interpolation=cv2.INTER_CUBIC)
    return cv2.GaussianBlur(img, (3, 3), 0)


def _boxes(rng, n, w=400, h=300):
    """Boxes of every size, some partly or wholly outside the image."""
    return np.column_stack([rng.uniform(-30, w + 30, n), rng.uniform(-30, h + 30, n),
                            np.exp(rng.uniform(0, np.log(w), n)),
                            np.exp(rng.uniform(0, np.log(h), n))])


def test_each_box_keeps_between_box_pixels_and_four_times_as_many():
    rng = np.random.default_rng(0)
    b = _boxes(rng, 500, 4000, 3000)
    level = box_levels(b, 1024)
    area = b[:, 2] * b[:, 3] / 4.0 ** level
    big = b[:, 2] * b[:, 3] >= 1024
    assert np.all(area[big] >= 1024 - 1e-6)
    assert np.all((area < 4 * 1024)[level < MAX_LEVEL])
    assert np.all(level[~big] == 0)                       # small boxes keep every pixel
    assert box_levels(b, 0).max() == 0                     # 0: full resolution
    assert box_levels(np.array([[0, 0, np.nan, 5.0]])).tolist() == [0]
    assert BOX_PIXELS > 0


def test_pyramid_level_halves_by_averaging_once_per_frame():
    rng = np.random.default_rng(1)
    img = _image(rng, 64, 96)
    ctx = FrameContext(3, img)
    one = pyramid_level(ctx, 1)
    assert pyramid_level(ctx, 0) is ctx and pyramid_level(ctx, 1) is one  # cached
    want = img.reshape(32, 2, 48, 2, 3).astype(float).mean(axis=(1, 3))
    assert np.abs(one.image.astype(float) - want).max() <= 1.0  # 2x2 means (rounded)
    assert pyramid_level(ctx, 2).image.shape == (16, 24, 3) and one.index == 3
    groups = working_frames(ctx, np.array([[10, 10, 40, 40], [50, 30, 4, 4.0]]),
                            np.array([1, 0]))
    assert [(g[0].image.shape[0], g[1].tolist()) for g in groups] == [(64, [1]), (32, [0])]
    np.testing.assert_allclose(groups[1][2], [[5, 5, 20, 20]])


@pytest.mark.parametrize("layout", ["perez", "hsv", "rgb"])
def test_gathered_histograms_equal_the_integral_histograms(layout):
    """Oracle: the boxes' own pixels gathered give the integral-histogram path's exact
    histograms, and on level k exactly those of the boxes / 2**k on image[::2**k, ::2**k]."""
    rng = np.random.default_rng(2)
    img = _image(rng)
    b = _boxes(rng, 40)
    s = ColourHistogramScorer(layout=layout)
    h1, f1 = s.histograms(img, b)
    h2, f2 = s.box_histograms(img, b)
    np.testing.assert_array_equal(h1, h2)
    np.testing.assert_array_equal(f1, f2)
    small = np.array([[50.0, 50.0, 3.0, 2.0], [80.0, 60.0, 9.0, 7.0]])  # a few pixels:
    for n in (1, 2):  # quantised in rows narrower than a frame's many boxes are
        np.testing.assert_array_equal(s.box_histograms(img, small[:n])[0],
                                      s.histograms(img, small[:n])[0])
    levels = rng.integers(0, 4, len(b))
    hl, fl = s.box_histograms(img, b, levels)
    for k in range(4):
        rows = levels == k
        step = 1 << k
        hk, fk = s.histograms(np.ascontiguousarray(img[::step, ::step]), b[rows] / step)
        np.testing.assert_array_equal(hl[rows], hk)
        np.testing.assert_array_equal(fl[rows], fk)
    grey = cv2.cvtColor(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), cv2.COLOR_GRAY2BGR)
    np.testing.assert_array_equal(s.box_histograms(grey, b)[0], s.histograms(grey, b)[0])
    view = img[::-1, 5:]  # a frame that is a strided view reads the same pixels
    np.testing.assert_array_equal(s.box_histograms(view, b, levels)[0],
                                  s.box_histograms(np.ascontiguousarray(view), b, levels)[0])


def _colour_models(rng, img, k):
    models = [ColourHistogramLikelihood("box", name=f"c{i}") for i in range(k)]
    for m, box in zip(models, _boxes(rng, k), strict=True):
        box[:2] = np.clip(box[:2], 10, 290)
        m.learn(FrameContext(1, img), box)
    return models


def test_colour_matrix_equals_scoring_model_by_model():
    """At full resolution the one-pass matrix is each model's log-likelihood, and
    learning many models at once is learning each."""
    rng = np.random.default_rng(3)
    img = _image(rng)
    models = _colour_models(rng, img, 6)
    b = _boxes(rng, 25)
    ctx = FrameContext(1, img)
    want = np.array([m.log_likelihood(b, FrameContext(1, img)) for m in models])
    got = ColourHistogramLikelihood.log_likelihood_matrix(models, b, ctx)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(appearance_matrix(models, b, ctx, box_pixels=0), want,
                               rtol=1e-12, atol=1e-12)
    inside = b[(b[:, 0] > 0) & (b[:, 0] < 400) & (b[:, 1] > 0) & (b[:, 1] < 300)][:6]
    learned = [ColourHistogramLikelihood("box", name=f"l{i}") for i in range(len(inside))]
    learn_all(learned, FrameContext(2, img), inside, box_pixels=0)
    for m, box in zip(learned, inside, strict=True):
        alone = ColourHistogramLikelihood("box")
        alone.learn(FrameContext(2, img), box)
        np.testing.assert_allclose(m.template, alone.template, rtol=1e-12)


def test_colour_reads_each_box_once_per_frame(monkeypatch):
    """Scoring K tracks against M detections, then learning from them, counts the
    detections' pixels once in the frame, not once per track or per pair."""
    rng = np.random.default_rng(4)
    img = _image(rng)
    models = _colour_models(rng, img, 8)
    b = _boxes(rng, 12)
    b[:, :2] = np.clip(b[:, :2], 20, 280)
    calls = []
    real = ColourHistogramScorer.box_histograms

    def counted(self, ctx, boxes, levels=None):
        calls.append(len(boxes))
        return real(self, ctx, boxes, levels)

    monkeypatch.setattr(ColourHistogramScorer, "box_histograms", counted)
    ctx = FrameContext(5, img)
    appearance_matrix(models, b, ctx)
    learn_all(models[:4], ctx, b[[0, 3, 5, 7]])
    assert calls == [len(b)]


def test_reduced_resolution_scores_stay_close_to_full_resolution():
    """Each box read from at least ``BOX_PIXELS`` pixels: the Bhattacharyya coefficients of
    a photograph-like frame move little from those at full resolution."""
    rng = np.random.default_rng(5)
    img = _image(rng, 1080, 1920)
    models = _colour_models(rng, cv2.resize(img, (400, 300)), 5)
    b = _boxes(rng, 40, 1920, 1080)
    b[:, 2:] = np.clip(b[:, 2:], 60, 500)
    ctx = FrameContext(1, img)
    full = appearance_matrix(models, b, ctx, box_pixels=0)
    reduced = appearance_matrix(models, b, ctx)
    assert box_levels(b).max() >= 2                        # the test does shrink boxes
    lam = models[0].lam
    assert np.abs(full - reduced).max() / lam < 0.02       # rho within 0.02


def _per_model_on_shrunk_frames(models, b, ctx):
    """The oracle: each model asked alone, each box on the frame halved by averaging to its
    level, in that frame's pixels."""
    want = np.zeros((len(models), len(b)))
    for frame, idx, xb in working_frames(ctx, b, box_levels(b)):
        for i, m in enumerate(models):
            want[i, idx] = m.log_likelihood(xb, frame)
    return want


@pytest.mark.parametrize("cue", ["gradient", "template"])
def test_feature_cues_score_and_learn_in_one_pass(cue):
    """Gradient descriptors and grey templates: one feature pass per level equals asking
    each model alone on the shrunk frames, and learning many at once equals learning each."""
    rng = np.random.default_rng(6)
    img = _image(rng, 600, 800)
    make = (lambda i: GradientLikelihood("box", name=f"g{i}")) if cue == "gradient" else \
        (lambda i: TemplateLikelihood("box", name=f"t{i}"))
    models = [make(i) for i in range(3)]
    for i, m in enumerate(models):
        m.learn(FrameContext(1, img), np.array([200.0 + 100 * i, 300, 120, 240]))
    b = np.array([[210.0, 300, 120, 240], [500, 300, 20, 30], [400, 250, 64, 128]])
    ctx = FrameContext(1, img)
    assert box_levels(b).tolist() == [2, 0, 1]
    got = appearance_matrix(models, b, ctx)
    np.testing.assert_allclose(got, _per_model_on_shrunk_frames(models, b, ctx),
                               rtol=1e-10, atol=1e-10)
    learned = [make(10 + i) for i in range(3)]
    learn_all(learned, FrameContext(2, img), b, box_pixels=0)
    for m, box in zip(learned, b, strict=True):
        alone = make(99)
        alone.learn(FrameContext(2, img), box)
        np.testing.assert_allclose(m.template, alone.template, rtol=1e-12)


def test_a_cue_without_a_matrix_is_asked_per_model_on_the_shrunk_frame():
    """A cue with no ``log_likelihood_matrix`` gets, per level, the frame halved by
    averaging and its boxes in that frame's pixels."""
    rng = np.random.default_rng(7)
    img = _image(rng, 600, 800)
    models = [RotationInvariantLikelihood("box", name=f"r{i}") for i in range(3)]
    assert not hasattr(RotationInvariantLikelihood, "log_likelihood_matrix")
    for i, m in enumerate(models):
        m.learn(FrameContext(1, img), np.array([200.0 + 100 * i, 300, 120, 240]))
    b = np.array([[210.0, 300, 120, 240], [500, 300, 20, 30]])
    ctx = FrameContext(1, img)
    np.testing.assert_allclose(appearance_matrix(models, b, ctx),
                               _per_model_on_shrunk_frames(models, b, ctx))
    small = pyramid_level(ctx, 2)
    np.testing.assert_allclose(appearance_matrix(models, b, ctx)[:, 0],
                               [m.log_likelihood(b[:1] / 4.0, small)[0] for m in models])


def test_part_colour_factors_are_scored_in_one_histogram_pass(monkeypatch):
    """Several colour factors of one frame (a part graph's) are scored by one
    ``rho_many`` call, equal to scoring them one by one."""
    rng = np.random.default_rng(8)
    img = _image(rng)
    fs = _colour_models(rng, img, 3)
    xs = [_boxes(rng, 20) for _ in fs]
    calls = []
    real = ColourHistogramScorer.rho_many
    monkeypatch.setattr(ColourHistogramScorer, "rho_many",
                        lambda self, *a, **k: calls.append(1) or real(self, *a, **k))
    joint = ColourHistogramLikelihood.log_likelihood_batch(fs, xs, FrameContext(3, img))
    assert len(calls) == 1
    for f, x, ll in zip(fs, xs, joint, strict=True):
        np.testing.assert_allclose(ll, f.log_likelihood(x, FrameContext(3, img)), atol=1e-12)


def test_models_read_alike_unless_their_reading_differs():
    """Copies of one cue read boxes alike whatever their templates and sharpness; another
    bin layout or grid reads them otherwise (and is scored model by model)."""
    a, b = ColourHistogramLikelihood("box", lam=5.0), ColourHistogramLikelihood("box")
    b.template = np.ones(80)
    assert ColourHistogramLikelihood.read_alike([a, b])
    assert not ColourHistogramLikelihood.read_alike([a, ColourHistogramLikelihood("box", n_h=8)])
    assert not TemplateLikelihood.read_alike([TemplateLikelihood("box"),
                                              TemplateLikelihood("box", grid=(6, 12))])
    c = ColourHistogramLikelihood("box")
    assert ColourHistogramLikelihood.read_alike([a, c])  # its key is kept from now on
    c.template, c.lam = np.ones(80), 3.0  # what it learns, how sharply it scores: alike
    assert ColourHistogramLikelihood.read_alike([a, c])
    c.box_indices = (4, 5, 6, 7)  # a parameter set later: the kept key is dropped
    assert not ColourHistogramLikelihood.read_alike([a, c])
