"""Resampling schemes: unbiasedness over many seeded streams, and invariants (Hypothesis)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from pgm.core.beliefs import Particles
from pgm.core.errors import DegenerateWeightsError
from pgm.core.numerics import log_normalize
from pgm.inference.resampling import RESAMPLERS, ess_triggered, get_resampler, systematic

SCHEMES = sorted(RESAMPLERS)


@pytest.mark.parametrize("scheme", SCHEMES)
@pytest.mark.parametrize("num", [100, 1000])
def test_weighted_moments_preserved(scheme, num):
    """Mean over 200 streams of the resampled average of f(x) equals the weighted average.

    Each stream's resampled mean has a variance at most that of multinomial resampling,
    Var_w[f] / num; over 200 independent streams the grand mean's standard error is
    sqrt(Var_w[f] / (num * 200)); we allow 5 standard errors.
    """
    rng = np.random.default_rng(2024)
    x = rng.standard_normal(num)
    w = rng.gamma(0.5, size=num)
    w /= w.sum()
    f = np.cos(x)
    target = w @ f
    var_w = w @ (f - target) ** 2
    fn = RESAMPLERS[scheme]
    streams = np.random.default_rng(7).spawn(200)
    means = np.array([f[fn(s, w, num)].mean() for s in streams])
    se = np.sqrt(var_w / (num * len(streams)))
    assert abs(means.mean() - target) < 5 * se


@pytest.mark.parametrize("scheme", SCHEMES)
def test_expected_offspring_counts(scheme):
    """E[count_i] = M w_i, checked per particle over 4000 streams (6 binomial SEs)."""
    w = np.array([0.5, 0.25, 0.125, 0.0625, 0.0625])
    m = 8
    fn = RESAMPLERS[scheme]
    counts = np.zeros(w.size)
    n_streams = 4000
    for s in np.random.default_rng(11).spawn(n_streams):
        counts += np.bincount(fn(s, w, m), minlength=w.size)
    mean = counts / n_streams
    se = np.sqrt(m * w * (1 - w) / n_streams)  # multinomial bound
    assert np.all(np.abs(mean - m * w) < 6 * se + 1e-12)


@pytest.mark.parametrize("scheme", SCHEMES)
def test_zero_weight_never_selected(scheme):
    w = np.array([0.0, 0.3, 0.0, 0.7, 0.0])
    rng = np.random.default_rng(3)
    for _ in range(200):
        idx = RESAMPLERS[scheme](rng, w, 50)
        assert not np.isin(idx, [0, 2, 4]).any()


weights_strategy = arrays(np.float64, st.integers(1, 60),
                          elements=st.floats(0.0, 1e3, allow_nan=False, allow_infinity=False)
                          ).filter(lambda a: a.sum() > 1e-9)


@settings(max_examples=60, deadline=None)
@given(w=weights_strategy, num=st.integers(1, 200), seed=st.integers(0, 2**32 - 1),
       scheme=st.sampled_from(SCHEMES))
def test_indices_in_range_and_supported(w, num, seed, scheme):
    p = w / w.sum()
    idx = RESAMPLERS[scheme](np.random.default_rng(seed), p, num)
    assert idx.shape == (num,)
    assert idx.min() >= 0 and idx.max() < w.size
    assert np.all(p[idx] > 0)


@settings(max_examples=60, deadline=None)
@given(w=weights_strategy, seed=st.integers(0, 2**32 - 1))
def test_systematic_counts_are_floor_or_ceil(w, seed):
    p = w / w.sum()
    n = 97
    counts = np.bincount(RESAMPLERS["systematic"](np.random.default_rng(seed), p, n),
                         minlength=p.size)
    assert np.all(counts >= np.floor(n * p - 1e-9)) and np.all(counts <= np.ceil(n * p + 1e-9))


@settings(max_examples=60, deadline=None)
@given(w=weights_strategy, seed=st.integers(0, 2**32 - 1))
def test_residual_keeps_deterministic_copies(w, seed):
    p = w / w.sum()
    n = 50
    counts = np.bincount(RESAMPLERS["residual"](np.random.default_rng(seed), p, n),
                         minlength=p.size)
    assert np.all(counts >= np.floor(n * p * (1 - 1e-12))) and counts.sum() == n


@settings(max_examples=100, deadline=None)
@given(lw=arrays(np.float64, st.integers(1, 50),
                 elements=st.floats(-700, 700, allow_nan=False)),
       shift=st.floats(-300, 300, allow_nan=False))
def test_log_normalize_sums_to_one_and_is_shift_invariant(lw, shift):
    a = log_normalize(lw)
    assert np.isclose(np.exp(a).sum(), 1.0, rtol=1e-12)
    assert np.allclose(a, log_normalize(lw + shift), atol=1e-9)


def test_log_normalize_degenerate():
    with pytest.raises(DegenerateWeightsError):
        log_normalize(np.array([-np.inf, np.nan]))
    out = log_normalize(np.array([np.nan, 0.0]))
    assert out[0] == -np.inf and out[1] == 0.0


@settings(max_examples=40, deadline=None)
@given(lw=arrays(np.float64, st.integers(2, 40), elements=st.floats(-50, 50)),
       seed=st.integers(0, 2**32 - 1), scheme=st.sampled_from(SCHEMES))
def test_particle_resampling_keeps_mass_and_history(lw, seed, scheme):
    n = lw.size
    x = np.arange(n, dtype=float)[:, None] * np.ones((1, 2))
    b = Particles(x, lw + 3.0, history=(x - 1.0,))
    r = b.resample(np.random.default_rng(seed), get_resampler(scheme))
    assert np.isclose(r.log_mass, b.log_mass)
    assert np.allclose(r.history[0], r.x - 1.0)  # histories travel with their particles
    assert np.allclose(r.weights, 1.0 / n)


def test_ess_and_trigger():
    b = Particles(np.zeros((4, 1)), np.log([0.25, 0.25, 0.25, 0.25]))
    assert np.isclose(b.ess, 4.0)
    b2 = Particles(np.zeros((4, 1)), np.log([1.0, 1e-300, 1e-300, 1e-300]))
    assert np.isclose(b2.ess, 1.0)
    assert ess_triggered(1.0, 4, 0.5) and not ess_triggered(4.0, 4, 0.5)
    assert ess_triggered(4.0, 4, 1.0) and not ess_triggered(0.5, 4, 0.0)


def test_unknown_scheme():
    with pytest.raises(ValueError, match="unknown resampling scheme"):
        get_resampler("bogus")


def test_systematic_counts_equal_the_inverse_cdf_of_the_same_points():
    from pgm.inference.resampling import _inverse_cdf

    gen = np.random.default_rng(11)
    for trial in range(300):
        n = int(gen.integers(1, 60))
        w = gen.random(n) ** int(gen.integers(1, 6))
        w[gen.random(n) < 0.2] = 0.0
        if w.sum() == 0:
            w[0] = 1.0
        m = int(gen.integers(1, 120))
        got = systematic(np.random.default_rng(trial), w, m)
        u = np.random.default_rng(trial).random()
        want = _inverse_cdf(w, (np.arange(m) + u) / m)
        np.testing.assert_array_equal(got, want)


def test_a_likelihood_that_explains_no_particle_is_named():
    """Every particle weight zero after the weight stage (a likelihood that reads NaN or
    -inf everywhere, a NaN parameter): the error names the variable, the frame and the
    likelihoods that weighted it."""
    import pgm
    from pgm.inference import Engine

    class Nowhere(pgm.LikelihoodFactor):
        def log_likelihood(self, x, ctx):
            return np.full(len(x), np.nan)

    graph = pgm.FactorGraph([pgm.Variable("box", 4, role="part")],
                            [pgm.GaussianPrior("box", mean=[10.0, 10.0, 5.0, 5.0]),
                             pgm.AR2Transition("box", noise_std=[2, 2, 0, 0]),
                             Nowhere("box", name="nowhere")])
    engine = Engine(graph, 0, num_particles=20)
    with pytest.raises(DegenerateWeightsError,
                       match=r"zero: variable 'box' at frame 3 after the likelihoods \['nowhere'\]"):
        engine.step(pgm.FrameContext(3, image=np.zeros((40, 40, 3), np.uint8)))
