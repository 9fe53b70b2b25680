"""GMM-KL (Wang et al. 2008, §3.2.6): the shared-component formulation against the literal
per-particle mixture fit, against a plain per-box loop, and as a model cue."""

import numpy as np
import pytest
from scipy.special import logsumexp
from scipy.stats import spearmanr

from pgm.core.frame import FrameContext
from pgm.observation.appearance.gmm import (
    MixtureTemplate,
    SharedComponentKL,
    box_pixels,
    fit_template,
    literal_kl,
)
from pgm.observation.appearance.likelihoods import GMMKLLikelihood


def two_colour_person(rng):
    """A 20x30 object (yellow top, blue bottom, noisy) on a dark textured background."""
    img = rng.integers(0, 60, (80, 120, 3)).astype(np.int64)
    img[25:40, 50:70] = (40, 180, 200)  # BGR
    img[40:55, 50:70] = (200, 40, 40)
    img[25:55, 50:70] += rng.integers(-20, 20, (30, 20, 3))
    return np.clip(img, 0, 255).astype(np.uint8), np.array([60.0, 40.0, 20.0, 30.0])


@pytest.mark.slow
def test_shared_components_rank_candidates_like_the_literal_per_box_fit():
    img, box = two_colour_person(np.random.default_rng(0))
    t = fit_template(img, box, n_components=3)
    for axis in (0, 1):
        shifts = np.arange(-24, 25, 4.0)
        boxes = np.repeat(box[None], len(shifts), axis=0)
        boxes[:, axis] += shifts
        shared = SharedComponentKL(t).divergence(img, boxes)
        literal = literal_kl(img, boxes, t)
        assert spearmanr(shared, literal).statistic >= 0.9
        assert shifts[np.argmin(shared)] == 0 and shifts[np.argmin(literal)] == 0
        assert shared[shifts == 0][0] < 0.1  # the template box scores D ≈ 0


def test_vectorised_divergence_equals_a_plain_loop():
    rng = np.random.default_rng(1)
    img, box = two_colour_person(rng)
    t = fit_template(img, box, n_components=3, n_samples=64)
    kl = SharedComponentKL(t, outlier_weight=0.05)
    boxes = np.column_stack([rng.uniform(-10, 130, 40), rng.uniform(-10, 90, 40),
                             rng.uniform(4, 40, 40), rng.uniform(4, 40, 40)])
    got = kl.divergence(FrameContext(1, img), boxes)
    log_pi1 = np.log(np.append(0.95 * t.weights, 0.05))
    lp_samples = np.column_stack([t.component_logpdf(t.samples), np.zeros(len(t.samples))])
    for b, d in zip(boxes, got, strict=True):
        pix = box_pixels(img, b)
        if len(pix) == 0:
            pi2 = np.eye(4)[3]
        else:
            crop_cells = kl.cell_index(np.round(pix[:, ::-1] * 255).astype(np.uint8)[None])
            pi2 = kl._lut[crop_cells[0]].astype(float).mean(axis=0)
        term1 = np.mean(logsumexp(lp_samples + log_pi1, axis=1)
                        - logsumexp(lp_samples + np.log(np.maximum(pi2, 1e-300)), axis=1))
        nz = pi2 > 0
        term2 = np.sum(pi2[nz] * (np.log(pi2[nz]) - log_pi1[nz]))
        assert d == pytest.approx(term1 + term2, abs=1e-5)


def test_lookup_table_responsibilities_match_the_exact_ones():
    img, box = two_colour_person(np.random.default_rng(2))
    kl = SharedComponentKL(fit_template(img, box, n_components=3))
    pix = img.reshape(-1, 3)
    exact = kl.exact_responsibilities(pix[:, ::-1] / 255.0)
    lut = kl.responsibilities(img).reshape(-1, exact.shape[1])
    # cells are 4 grey levels wide; over the object's whole box the difference is tiny
    assert np.abs(lut - exact).mean() < 0.01
    assert np.abs(lut.mean(axis=0) - exact.mean(axis=0)).max() < 0.01


def test_gmm_factor_peaks_at_the_template_and_one_sided_version_too():
    img, box = two_colour_person(np.random.default_rng(3))
    shifts = np.arange(-12, 13, 3.0)
    x = np.array([box + [dx, dy, 0, 0] for dx in shifts for dy in shifts])
    for symmetric in (True, False):
        f = GMMKLLikelihood("object", symmetric=symmetric)
        f.initialize(FrameContext(1, img), box)
        ll = f.log_likelihood(x, FrameContext(2, img))
        np.testing.assert_allclose(x[np.argmax(ll)], box)
    lit = GMMKLLikelihood("object", method="literal", n_components=2)
    lit.initialize(FrameContext(1, img), box)
    few = x[[0, 40, 80]]  # corner, centre, corner
    assert np.argmax(lit.log_likelihood(few, FrameContext(2, img))) == 1


def test_gmm_factor_round_trips_through_json(tmp_path):
    from pgm import FactorGraph
    from pgm.inference import Engine
    from pgm.models import part_graph

    img, box = two_colour_person(np.random.default_rng(4))
    g = part_graph.build_graph(part_graph.Params(init_box=tuple(box), n_parts=1,
                                                 appearance="colour+gmm+rings"))
    kinds = [type(f).__name__ for f in g.factors_of("object", "likelihood")]
    assert kinds == ["ColourHistogramLikelihood", "GMMKLLikelihood",
                     "RotationInvariantLikelihood"]
    eng = Engine(g, np.random.default_rng(0), num_particles=40)
    for k in range(3):
        eng.step(FrameContext(k + 1, img))
    eng.graph.save(tmp_path / "m.json")
    back = FactorGraph.load(tmp_path / "m.json")
    assert back == eng.graph
    x = box + np.random.default_rng(5).normal(0, 3, (30, 4))
    a = eng.graph.factors["gmm:object"].log_likelihood(x, FrameContext(9, img))
    b = back.factors["gmm:object"].log_likelihood(x, FrameContext(9, img))
    np.testing.assert_allclose(a, b, rtol=1e-6)


def test_gmm_bad_parameters():
    with pytest.raises(ValueError, match="method"):
        GMMKLLikelihood("object", method="exact")
    with pytest.raises(ValueError, match="outlier_weight"):
        GMMKLLikelihood("object", outlier_weight=1.0)
    with pytest.raises(ValueError, match="all of weights"):
        GMMKLLikelihood("object", weights=[1.0])
    with pytest.raises(ValueError, match="positive definite"):
        GMMKLLikelihood("object", weights=[1.0], means=[[0.5, 0.5, 0.5]],
                        covariances=[np.zeros((3, 3))], samples=[[0.5, 0.5, 0.5]])
    with pytest.raises(ValueError, match="finite"):
        MixtureTemplate([np.nan], [[0.5]], [[[1.0]]], [[0.5]])
    with pytest.raises(ValueError, match="fewer than 2 pixels"):
        fit_template(np.zeros((10, 10, 3), np.uint8), np.array([-20.0, -20, 4, 4]))


# -- the colour-contrast (foreground/background log-odds) cue ---------------------------
def test_contrast_cue_peaks_at_the_object_position_and_size():
    from pgm.observation.appearance.likelihoods import (
        ColourContrastLikelihood,
        ColourHistogramLikelihood,
    )

    img, box = two_colour_person(np.random.default_rng(6))
    f = ColourContrastLikelihood("object")
    f.initialize(FrameContext(1, img), box)
    shifts, scales = np.arange(-6, 7, 2.0), np.array([0.6, 0.8, 0.9, 1.0, 1.1, 1.25, 1.5])
    x = np.array([[box[0] + dx, box[1] + dy, box[2] * s, box[3] * s]
                  for dx in shifts for dy in shifts for s in scales])
    ll = f.log_likelihood(x, FrameContext(2, img))
    np.testing.assert_allclose(x[np.argmax(ll)], box)
    # a normalised whole-box histogram cannot tell a box inside the object from it
    c = ColourHistogramLikelihood("object")
    c.initialize(FrameContext(1, img), box)
    half = np.array([[box[0], box[1] - box[3] / 4, box[2] * 0.5, box[3] * 0.5], box])
    ll_c = c.log_likelihood(half, FrameContext(2, img))
    ll_f = f.log_likelihood(half, FrameContext(2, img))
    assert ll_f[1] - ll_f[0] > 5.0 and abs(ll_c[1] - ll_c[0]) < ll_f[1] - ll_f[0]


def test_contrast_box_sums_equal_a_plain_loop_and_round_trip(tmp_path):
    from pgm import FactorGraph, GaussianPrior, Variable
    from pgm.observation.appearance.likelihoods import ColourContrastLikelihood

    rng = np.random.default_rng(7)
    img, box = two_colour_person(rng)
    f = ColourContrastLikelihood("object", adapt_rate=0.2)
    ctx = FrameContext(1, img)
    f.initialize(ctx, box)
    x = np.column_stack([rng.uniform(-10, 130, 30), rng.uniform(-10, 90, 30),
                         rng.uniform(2, 50, 30), rng.uniform(2, 50, 30)])
    got = f.box_sums(x, FrameContext(2, img))
    bins = f.scorer.bins(FrameContext(3, img))
    from pgm.observation.appearance.colour import pixel_bounds

    for b, s in zip(x, got, strict=True):
        x0, x1, y0, y1 = (int(v[0]) for v in pixel_bounds(b, *img.shape[:2]))
        assert s == pytest.approx(f.log_odds[bins[y0:y1, x0:x1]].sum(), abs=1e-9)
    g = FactorGraph([Variable("object", 4)], [GaussianPrior("object", mean=box, cov=1.0), f],
                    name="t")
    g.save(tmp_path / "g.json")
    back = FactorGraph.load(tmp_path / "g.json").factors[f.name]
    np.testing.assert_allclose(back.log_odds, f.log_odds)
    # adapting towards a frame where the background turned the object's colour
    before = f.log_odds.copy()
    shifted = img.copy()
    shifted[:20] = (40, 180, 200)
    f.update({"object": box}, {}, FrameContext(4, shifted))
    assert not np.allclose(before, f.log_odds)
    with pytest.raises(ValueError, match="together"):
        ColourContrastLikelihood("object", ref_area=10.0)
    with pytest.raises(ValueError, match="adapt_rate"):
        ColourContrastLikelihood("object", adapt_rate=2.0)


def test_mixture_template_keeps_normalised_weights_bit_for_bit():
    # 0.1 + 0.2 + 0.7 is not exactly 1 in floating point; dividing by the sum would move
    # the weights by an ulp, and a saved model would not reload exactly
    rng = np.random.default_rng(0)
    w = rng.dirichlet(np.ones(7), size=50)
    for row in w:
        t = MixtureTemplate(row, np.zeros((7, 1)), np.ones((7, 1, 1)), [[0.5]])
        assert t.weights.tobytes() == row.tobytes()
    t = MixtureTemplate([1.0, 3.0], [[0.0], [1.0]], np.ones((2, 1, 1)), [[0.5]])
    np.testing.assert_array_equal(t.weights, [0.25, 0.75])
