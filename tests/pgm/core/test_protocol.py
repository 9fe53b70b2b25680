"""The belief protocol (pgm.core.protocol): every built-in belief and its batched form give
dim, mean, cov, estimate and log_mass, checked against closed forms; a batch's values are
its rows' values."""

import numpy as np
import pytest
from scipy import stats

from pgm.core.batched import BatchedInverseGamma, Replicated, batched_type, register_batched
from pgm.core.beliefs import Intensity, Particles
from pgm.core.expfam import Gaussian, InverseGamma
from pgm.core.protocol import BatchedBelief, Belief


def _beliefs(k: int) -> list:
    rng = np.random.default_rng(k)
    x = rng.normal(size=(30, 3))
    lw = rng.normal(size=30)
    a = rng.uniform(0.5, 6.0, size=3)
    return [Particles(x, lw), Intensity(x, lw + np.log(2.0)),
            Gaussian(rng.normal(size=2), np.diag(rng.uniform(1, 2, size=2))),
            InverseGamma(a, rng.uniform(0.5, 2.0, size=3))]


def test_every_belief_gives_the_protocol_with_its_closed_forms():
    p, intensity, g, q = _beliefs(0)
    for b in (p, intensity, g, q):
        assert isinstance(b, Belief), type(b).__name__
        assert b.mean().shape == (b.dim,) and b.cov().shape == (b.dim, b.dim)
        assert b.estimate().shape == (b.dim,)
    w = np.exp(p.log_weights - p.log_weights.max())
    w /= w.sum()
    np.testing.assert_allclose(p.mean(), w @ p.x, rtol=1e-12)
    np.testing.assert_allclose(p.cov(), np.cov(p.x.T, aweights=w, bias=True), rtol=1e-10)
    assert intensity.log_mass == pytest.approx(p.log_mass + np.log(2.0))  # expected count
    np.testing.assert_allclose(intensity.mean(), p.mean(), rtol=1e-12)  # where targets are
    assert g.log_mass == 0.0 and g.estimate() is g.mean()
    assert q.log_mass == 0.0
    np.testing.assert_allclose(q.estimate(), q.beta / q.alpha)  # the VB plug-in variance
    frozen = stats.invgamma(q.alpha, scale=q.beta)
    with np.errstate(invalid="ignore"):
        np.testing.assert_allclose(q.mean(), np.where(q.alpha > 1, frozen.mean(), np.nan))
        np.testing.assert_allclose(np.diag(q.cov()), np.where(q.alpha > 2, frozen.var(), np.nan))


@pytest.mark.parametrize("which", range(4))
def test_a_batch_gives_its_rows_values(which):
    rows = [_beliefs(k)[which] for k in range(3)]
    cls = batched_type(type(rows[0]))
    if type(rows[0]) is Intensity:
        assert issubclass(cls, Replicated)
    b = cls.stack(rows)
    assert isinstance(b, BatchedBelief) and isinstance(b, Belief) and b.K == 3
    assert b.row_type is type(rows[0]) and b.dim == rows[0].dim
    for name in ("mean", "cov", "estimate"):
        got = getattr(b, name)()
        assert got.shape[0] == 3
        for k, r in enumerate(rows):
            np.testing.assert_allclose(got[k], getattr(r, name)(), rtol=1e-12, equal_nan=True)
    np.testing.assert_allclose(b.log_mass, [r.log_mass for r in rows], rtol=1e-12)
    births = b.select([2, 0]).concat(b.select([1]))  # deaths and births on the replica axis
    assert births.K == 3
    np.testing.assert_allclose(births.mean()[0], rows[2].mean(), rtol=1e-12, equal_nan=True)
    np.testing.assert_allclose(births.row(2).mean(), rows[1].mean(), rtol=1e-12, equal_nan=True)


def test_a_new_belief_type_registers_its_batched_form():
    class Point:  # a belief known exactly (a user's own)
        log_mass = 0.0

        def __init__(self, v):
            self.v = np.asarray(v, dtype=float)

        @property
        def dim(self):
            return self.v.size

        def mean(self):
            return self.v

        def cov(self):
            return np.zeros((self.dim, self.dim))

        estimate = mean

    assert isinstance(Point([1.0]), Belief)
    assert issubclass(batched_type(Point), Replicated)  # kept one object per replica

    @register_batched
    class BatchedPoint(Replicated):
        row_type = Point

    assert batched_type(Point) is BatchedPoint
    b = BatchedPoint.stack([Point([1.0, 2.0]), Point([3.0, 4.0])])
    np.testing.assert_array_equal(b.estimate(), [[1, 2], [3, 4]])
    with pytest.raises(ValueError, match="row_type"):
        register_batched(type("NoRow", (), {}))
    assert batched_type(InverseGamma) is BatchedInverseGamma
