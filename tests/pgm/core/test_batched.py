"""Batched beliefs of a plate's replicas (pgm.core.batched): each row is the single-graph
belief, and the batch operations are those of the rows."""

import numpy as np
import pytest

from pgm.core.batched import (
    BatchedGaussian,
    BatchedInverseGamma,
    BatchedParticles,
    Replicated,
    batched_type,
    is_batched,
)
from pgm.core.beliefs import Intensity, Particles
from pgm.core.expfam import Gaussian, InverseGamma
from pgm.inference.resampling import get_resampler


def _rows(K=3, n=20, d=2, seed=0):
    rng = np.random.default_rng(seed)
    return [Particles(rng.normal(size=(n, d)), rng.normal(size=n)) for _ in range(K)]


def test_particle_batch_rows_are_the_particles():
    rows = _rows()
    b = BatchedParticles.stack(rows)
    assert b.K == 3 and b.num == 20 and b.dim == 2 and is_batched(b)
    for k, p in enumerate(rows):
        np.testing.assert_allclose(b.weights[k], p.weights, rtol=1e-12)
        np.testing.assert_allclose(b.mean()[k], p.mean(), rtol=1e-12)
        assert b.ess[k] == pytest.approx(p.ess)
        assert b.log_mass[k] == pytest.approx(p.log_mass)
        np.testing.assert_array_equal(b.row(k).x, p.x)
    sel = b.select([2, 0])
    np.testing.assert_array_equal(sel.x, np.stack([rows[2].x, rows[0].x]))
    both = sel.concat(b.select([1]))
    assert both.K == 3
    np.testing.assert_array_equal(both.row(2).x, rows[1].x)


def test_normalising_keeps_a_degenerate_replica_on_its_fallback():
    b = BatchedParticles.stack(_rows())
    dead = b.reweight(np.where(np.arange(3)[:, None] == 1, -np.inf, 0.0) * np.ones((3, 20)))
    out, bad = dead.normalized(fallback=b)
    assert bad.tolist() == [False, True, False]
    np.testing.assert_array_equal(out.log_weights[1], b.log_weights[1])
    np.testing.assert_allclose(np.exp(out.log_weights[0]).sum(), 1.0)


def test_resampling_rows_keeps_each_mass_and_leaves_the_others():
    b = BatchedParticles.stack(_rows())
    rngs = [np.random.default_rng(k) for k in range(3)]
    r = b.resample_rows(rngs, get_resampler("systematic"), 20, np.array([0, 2]))
    np.testing.assert_allclose(r.log_mass, b.log_mass)
    np.testing.assert_array_equal(r.x[1], b.x[1])
    assert np.allclose(r.log_weights[0], r.log_weights[0][0])  # equal weights after it
    with pytest.raises(ValueError, match="every replica"):
        b.resample_rows(rngs, get_resampler("systematic"), 10, np.array([0]))


def test_gaussian_and_noise_batches_and_the_type_table():
    g = [Gaussian(np.full(2, k), np.eye(2) * (k + 1)) for k in range(3)]
    bg = BatchedGaussian.stack(g)
    assert bg.K == 3 and bg.dim == 2
    np.testing.assert_array_equal(bg.row(2).cov(), g[2].cov())
    assert bg.select([1]).concat(bg.select([0])).K == 2
    q = BatchedInverseGamma(np.full((2, 3), 4.0), np.full((2, 3), 2.0))
    np.testing.assert_allclose(q.r_hat(), 0.5)
    f = q.forget(0.5, alpha_min=3.0)  # alpha 2 is raised to 3, the mean kept
    np.testing.assert_allclose(f.alpha, 3.0)
    np.testing.assert_allclose(f.r_hat(), 0.5)
    assert batched_type(Particles) is BatchedParticles
    assert batched_type(Gaussian) is BatchedGaussian
    assert batched_type(InverseGamma) is BatchedInverseGamma
    rep = batched_type(Intensity)
    assert issubclass(rep, Replicated) and rep.row_type is Intensity
    assert batched_type(Intensity) is rep
    items = rep.stack([Intensity.empty(2), Intensity.empty(2)])
    assert items.K == 2 and items.select([1]).K == 1


def test_every_belief_gives_its_point_estimate():
    """The belief protocol's ``estimate()``: particles their weighted mean, a Gaussian its
    mean, and their batches one row per replica."""
    rows = _rows()
    for p in rows:
        np.testing.assert_array_equal(p.estimate(), p.mean())
    np.testing.assert_array_equal(BatchedParticles.stack(rows).estimate(),
                                  np.stack([p.mean() for p in rows]))
    g = [Gaussian(np.full(2, k), np.eye(2)) for k in range(3)]
    assert g[1].estimate() is g[1].mean()
    np.testing.assert_array_equal(BatchedGaussian.stack(g).estimate(),
                                  np.stack([x.mean() for x in g]))
