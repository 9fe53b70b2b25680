"""Particle beliefs and PHD intensities (pgm.core.beliefs): weights, moments, mass kept by
the transformations, validation."""

import numpy as np
import pytest

from pgm.core.beliefs import Intensity, Particles
from pgm.core.errors import DegenerateWeightsError
from pgm.inference.resampling import get_resampler


def _particles(seed=0, n=50, d=3, mass=2.0):
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(n, d))
    lw = rng.normal(size=n)
    lw += np.log(mass) - np.log(np.exp(lw).sum())
    return Particles(x, lw, (x - 1.0,))


def test_moments_weights_and_ess_by_definition():
    p = _particles()
    w = np.exp(p.log_weights) / np.exp(p.log_weights).sum()
    np.testing.assert_allclose(p.weights, w, rtol=1e-12)
    assert p.mass == pytest.approx(2.0)
    np.testing.assert_allclose(p.mean(), w @ p.x, rtol=1e-12)
    c = p.x - w @ p.x
    np.testing.assert_allclose(p.cov(), (c * w[:, None]).T @ c, rtol=1e-12)
    assert p.ess == pytest.approx(1.0 / np.sum(w ** 2))
    assert 1.0 <= p.ess <= p.num
    assert not p.weights.flags.writeable


def test_transformations_keep_or_set_the_mass():
    p = _particles()
    q = p.normalized()
    assert q.mass == pytest.approx(1.0) and q.ess == pytest.approx(p.ess)
    r = p.resample(np.random.default_rng(1), get_resampler("systematic"), 80)
    assert r.num == 80 and r.mass == pytest.approx(p.mass)
    assert len(r.history) == 1 and r.history[0].shape == (80, 3)
    np.testing.assert_allclose(r.history[0], r.x - 1.0)  # resampled with their history
    moved = p.moved(p.x + 1.0, history_len=2)
    assert len(moved.history) == 2
    np.testing.assert_array_equal(moved.history[0], p.x)
    np.testing.assert_array_equal(moved.log_weights, p.log_weights)
    delta = np.full(p.num, np.log(0.5))
    delta[0] = np.nan  # NaN evidence is no evidence
    half = p.reweight(delta)
    assert half.log_weights[0] == -np.inf
    u = Particles.uniform(np.zeros((4, 2)), mass=3.0, history_len=2)
    assert u.mass == pytest.approx(3.0) and len(u.history) == 2


def test_bad_shapes_and_degenerate_weights_are_errors():
    with pytest.raises(ValueError, match="shape"):
        Particles(np.zeros(5), np.zeros(5))
    with pytest.raises(ValueError, match="log_weights"):
        Particles(np.zeros((5, 2)), np.zeros(4))
    with pytest.raises(ValueError, match="history"):
        Particles(np.zeros((5, 2)), np.zeros(5), (np.zeros((4, 2)),))
    p = _particles()
    with pytest.raises(ValueError, match="reweight"):
        p.reweight(np.zeros(3))
    dead = p.reweight(np.full(p.num, -np.inf))
    with pytest.raises(DegenerateWeightsError):
        dead.normalized()


def test_intensity_counts_its_newborn_and_empty_has_no_mass():
    p = _particles(mass=2.5)
    born = Particles.uniform(np.zeros((3, 3)), mass=0.5)
    i = Intensity(p.x, p.log_weights, newborn=born)
    assert i.expected_count == pytest.approx(3.0)
    assert not Intensity.likelihood_reweights and Particles.likelihood_reweights
    e = Intensity.empty(4)
    assert e.num == 0 and e.dim == 4 and e.expected_count == 0.0 and e.log_mass == -np.inf
