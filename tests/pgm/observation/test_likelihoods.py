"""The fragments likelihood: vectorised scores, peak at the template, robust to occlusion."""

import numpy as np
import pytest

from pgm.core.frame import FrameContext
from pgm.observation.appearance.colour import ColourHistogramScorer
from pgm.observation.appearance.likelihoods import ColourHistogramLikelihood, FragmentsLikelihood


def textured_scene(rng):
    """A 40x60 object made of differently coloured blocks on a noisy background."""
    img = rng.integers(60, 120, (160, 200, 3), dtype=np.uint8)
    colours = rng.integers(0, 256, (3, 3, 3))
    for r in range(3):
        for c in range(3):
            img[50 + 20 * r:70 + 20 * r, 80 + 13 * c:93 + 13 * c] = colours[r, c]
    return img, np.array([100.0, 80.0, 40.0, 60.0])


def test_fragment_scores_equal_scoring_each_fragment_alone():
    rng = np.random.default_rng(0)
    img, box = textured_scene(rng)
    f = FragmentsLikelihood("object", grid=(3, 3))
    f.initialize(FrameContext(1, img), box)
    x = box + np.column_stack([rng.normal(0, 6, (25, 2)), np.zeros((25, 2))])
    got = f.fragment_rho(x, FrameContext(2, img))
    sc = ColourHistogramScorer()
    frags = f.fragments(x).reshape(25, 9, 4)
    for k in range(9):
        want = sc.rho(FrameContext(3, img), frags[:, k], f.templates[k])
        np.testing.assert_allclose(got[:, k], want, rtol=0, atol=1e-12)


def scan(factor, img, box, shifts):
    x = np.array([box + [dx, dy, 0, 0] for dx in shifts for dy in shifts])
    ll = factor.log_likelihood(x, FrameContext(2, img))
    return x[np.argmax(ll)]


def test_fragments_peak_at_the_template_and_survive_a_third_covered():
    rng = np.random.default_rng(1)
    img, box = textured_scene(rng)
    for q in (0.25, 0.5):
        f = FragmentsLikelihood("object", grid=(3, 3), quantile=q)
        f.initialize(FrameContext(1, img), box)
        shifts = np.arange(-12, 13, 3)
        np.testing.assert_allclose(scan(f, img, box, shifts), box)
    # cover the right third of the object with a flat grey occluder
    occluded = img.copy()
    occluded[45:115, 107:125] = 128
    best = scan(f, occluded, box, shifts)
    assert np.abs(best[:2] - box[:2]).max() <= 3, best
    # a whole-box histogram is pulled off the object by the same occluder
    whole = ColourHistogramLikelihood("object")
    whole.initialize(FrameContext(1, img), box)
    f_ll = f.log_likelihood(np.array([box]), FrameContext(3, occluded))[0]
    w_ll = whole.log_likelihood(np.array([box]), FrameContext(3, occluded))[0]
    assert f_ll > w_ll  # the visible fragments still match their templates


def test_fragments_learn_a_box_at_the_border_and_refuse_one_outside():
    """A detection half out of the image (an association learns from it): the fragments
    with no pixel inside take the visible ones' mean histogram; the visible ones are
    their own. A box wholly outside is a ValueError naming it."""
    rng = np.random.default_rng(2)
    img, _ = textured_scene(rng)
    box = np.array([5.0, 80.0, 40.0, 60.0])  # the left column of fragments is outside
    f = FragmentsLikelihood("object", grid=(3, 3))
    f.learn(FrameContext(1, img), box)
    hist, in_frac = f.scorer.histograms(FrameContext(1, img), f.fragments(box[None]))
    seen = in_frac > 0
    assert 0 < seen.sum() < 9 and np.all(np.isfinite(f.templates))
    np.testing.assert_allclose(f.templates[seen], hist[seen] / hist[seen].sum(1, keepdims=True))
    np.testing.assert_allclose(f.templates[~seen],
                               np.broadcast_to(f.templates[seen].mean(0), f.templates[~seen].shape))
    assert np.isfinite(f.log_likelihood(box[None], FrameContext(2, img))).all()
    with pytest.raises(ValueError, match="outside the image"):
        f.learn(FrameContext(1, img), np.array([-100.0, 80.0, 40.0, 60.0]))


def test_fragments_bad_parameters():
    with pytest.raises(ValueError, match="grid"):
        FragmentsLikelihood("object", grid=(0, 3))
    with pytest.raises(ValueError, match="quantile"):
        FragmentsLikelihood("object", quantile=1.5)


def test_fragments_model_config_round_trips_and_runs(tmp_path):
    from pgm import FactorGraph
    from pgm.inference import Engine
    from pgm.models import part_graph

    rng = np.random.default_rng(2)
    img, box = textured_scene(rng)
    g = part_graph.build_graph(part_graph.Params(init_box=tuple(box), n_parts=1,
                                                 appearance="fragments"))
    eng = Engine(g, np.random.default_rng(0), num_particles=50)
    for k in range(3):
        eng.step(FrameContext(k + 1, img))
    learned = eng.graph
    learned.save(tmp_path / "m.json")
    back = FactorGraph.load(tmp_path / "m.json")
    assert back == learned
    np.testing.assert_allclose(back.factors["likelihood:object"].templates,
                               learned.factors["likelihood:object"].templates)
    with pytest.raises(ValueError, match="appearance must be"):
        part_graph.build_graph(part_graph.Params(init_box=tuple(box), appearance="sift"))


def test_gradient_likelihood_peaks_at_the_template_position_and_scale():
    from pgm.observation.appearance.likelihoods import GradientLikelihood

    rng = np.random.default_rng(3)
    img, box = textured_scene(rng)
    g = GradientLikelihood("object", cells=(3, 3))
    g.initialize(FrameContext(1, img), box)
    shifts = np.arange(-12, 13, 3)
    np.testing.assert_allclose(scan(g, img, box, shifts), box)
    # scale is observable: of boxes 0.7x .. 1.4x the size, the true size scores best
    scales = np.array([0.7, 0.8, 0.9, 1.0, 1.15, 1.3, 1.4])
    x = np.array([[box[0], box[1], box[2] * s, box[3] * s] for s in scales])
    ll = g.log_likelihood(x, FrameContext(2, img))
    assert scales[np.argmax(ll)] == 1.0, ll
    # the same scan with a whole-box colour histogram cannot tell 0.9x from 1.0x
    whole = ColourHistogramLikelihood("object")
    whole.initialize(FrameContext(1, img), box)
    lw = whole.log_likelihood(x, FrameContext(2, img))
    assert np.ptp(ll[2:5]) > np.ptp(lw[2:5])


def test_adaptive_template_follows_a_slow_appearance_change():
    """Nummiaro's update: the template moves towards the estimate's histogram when the
    match is good enough, and stays put otherwise."""
    rng = np.random.default_rng(4)
    img, box = textured_scene(rng)
    changed = img.copy()
    changed[50:110, 80:120] = np.clip(changed[50:110, 80:120].astype(int) + 25, 0, 255)
    x = np.array([box])
    f = ColourHistogramLikelihood("object", adapt_rate=0.5, adapt_threshold=0.0)
    f.initialize(FrameContext(1, img), box)
    assert f.learns
    before = f.rho(x, FrameContext(2, changed))[0]
    f.update({"object": box}, {}, FrameContext(2, changed))
    after = f.rho(x, FrameContext(3, changed))[0]
    assert after > before
    strict = ColourHistogramLikelihood("object", adapt_rate=0.5, adapt_threshold=0.999)
    strict.initialize(FrameContext(1, img), box)
    q0 = strict.template.copy()
    strict.update({"object": box}, {}, FrameContext(2, changed))
    np.testing.assert_array_equal(strict.template, q0)
    assert not ColourHistogramLikelihood("object").learns


def test_rotation_invariant_model_peaks_and_ignores_rotation():
    import cv2

    from pgm.observation.appearance.likelihoods import RotationInvariantLikelihood

    rng = np.random.default_rng(5)
    img = rng.integers(60, 120, (160, 160, 3), dtype=np.uint8)
    yy, xx = np.mgrid[0:160, 0:160]
    rad = np.hypot(xx - 80, yy - 80)
    for r0, colour in ((8, (200, 30, 30)), (16, (30, 200, 30)), (24, (30, 30, 200))):
        img[(rad >= r0 - 8) & (rad < r0)] = colour
    img[70:90, 95:102] = (250, 250, 0)  # an asymmetric mark: rotation moves it
    box = np.array([80.0, 80.0, 56.0, 56.0])
    f = RotationInvariantLikelihood("object", rings=4, angles=24)
    f.initialize(FrameContext(1, img), box)
    assert f.gamma(box[None], FrameContext(1, img))[0] == pytest.approx(1.0)
    shifts = np.arange(-12, 13, 3)
    np.testing.assert_allclose(scan(f, img, box, shifts), box)
    rotated = cv2.rotate(img, cv2.ROTATE_90_CLOCKWISE)  # about (79.5, 79.5)
    g_rot = f.gamma(np.array([[79.5 + 0.5, 79.5 + 0.5, 56, 56]]), FrameContext(2, rotated))[0]
    g_shift = f.gamma(np.array([box + [8, 0, 0, 0]]), FrameContext(2, img))[0]
    assert g_rot < 1.05 < g_shift  # invariant to the quarter turn, not to a shift


def test_rotation_invariant_ring_stats_equal_a_plain_loop():
    from pgm.observation.appearance.likelihoods import RotationInvariantLikelihood

    rng = np.random.default_rng(6)
    img = rng.integers(0, 256, (90, 120, 3), dtype=np.uint8)
    f = RotationInvariantLikelihood("object", rings=3, angles=8, radial_samples=2)
    x = np.column_stack([rng.uniform(-5, 125, 12), rng.uniform(-5, 95, 12),
                         rng.uniform(4, 50, 12), rng.uniform(4, 50, 12)])
    got = f.ring_stats(x, FrameContext(1, img))
    for n, (cx, cy, w, h) in enumerate(x):
        R = 0.5 * np.sqrt(w * h)
        for k in range(3):
            vals = []
            for s in range(2):
                r = R * (2 * k + s + 0.5) / 6
                for a in range(8):
                    t = 2 * np.pi * a / 8
                    px = min(max(int(np.floor(cx + r * np.cos(t))), 0), 119)
                    py = min(max(int(np.floor(cy + r * np.sin(t))), 0), 89)
                    vals.append(img[py, px].astype(float))
            vals = np.array(vals)
            np.testing.assert_allclose(got[n, k, :, 0], vals.mean(axis=0), rtol=1e-9)
            np.testing.assert_allclose(got[n, k, :, 1], np.maximum(vals.var(axis=0), 4.0),
                                       rtol=1e-6)


def test_template_ncc_peaks_at_position_and_scale_and_ignores_gain():
    from pgm.observation.appearance.likelihoods import TemplateLikelihood

    rng = np.random.default_rng(8)
    img, box = textured_scene(rng)
    f = TemplateLikelihood("object")
    f.initialize(FrameContext(1, img), box)
    shifts, scales = np.arange(-6, 7, 3.0), np.array([0.7, 0.85, 1.0, 1.15, 1.3])
    x = np.array([[box[0] + dx, box[1] + dy, box[2] * s, box[3] * s]
                  for dx in shifts for dy in shifts for s in scales])
    ll = f.log_likelihood(x, FrameContext(2, img))
    np.testing.assert_allclose(x[np.argmax(ll)], box)
    brighter = np.clip(0.5 * img.astype(float) + 60, 0, 255).astype(np.uint8)
    assert f.log_likelihood(box[None], FrameContext(3, brighter))[0] > -0.05 * f.lam


def test_template_samples_equal_a_plain_loop_and_round_trip(tmp_path):
    import cv2

    from pgm import FactorGraph, GaussianPrior, Variable
    from pgm.observation.appearance.likelihoods import TemplateLikelihood

    rng = np.random.default_rng(9)
    img = rng.integers(0, 256, (70, 90, 3), dtype=np.uint8)
    f = TemplateLikelihood("object", grid=(3, 5), adapt_rate=0.5)
    x = np.column_stack([rng.uniform(-5, 95, 10), rng.uniform(-5, 75, 10),
                         rng.uniform(3, 40, 10), rng.uniform(3, 40, 10)])
    got = f.samples(x, FrameContext(1, img))
    grey = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(float)
    for n, (cx, cy, w, h) in enumerate(x):
        v = []
        for r in range(5):
            for c in range(3):
                px = min(max(int(np.floor(cx + w * ((c + 0.5) / 3 - 0.5))), 0), 89)
                py = min(max(int(np.floor(cy + h * ((r + 0.5) / 5 - 0.5))), 0), 69)
                v.append(grey[py, px])
        v = np.array(v) - np.mean(v)
        np.testing.assert_allclose(got[n], v / max(np.linalg.norm(v), 1e-6), atol=1e-9)
    f.initialize(FrameContext(1, img), x[0])
    before = f.template.copy()
    f.update({"object": x[1]}, {}, FrameContext(2, img))
    assert not np.allclose(before, f.template)
    g = FactorGraph([Variable("object", 4)],
                    [GaussianPrior("object", mean=x[0], cov=1.0), f], name="t")
    g.save(tmp_path / "g.json")
    np.testing.assert_allclose(FactorGraph.load(tmp_path / "g.json").factors[f.name].template,
                               f.template)
    with pytest.raises(ValueError, match="grid"):
        TemplateLikelihood("object", grid=(1, 1))
    with pytest.raises(ValueError, match="samples"):
        TemplateLikelihood("object", grid=(2, 2), template=[1.0, 2.0])
