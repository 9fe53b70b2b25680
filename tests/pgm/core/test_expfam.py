"""The Gaussian's KL divergence where the reference is degenerate (a component known
exactly: a point prior, a state without process noise), as the VB adaptive Kalman
filter's ELBO reads it."""

import numpy as np
import pytest

import pgm
from pgm.core.expfam import Gaussian


def _random_spd(rng, d):
    a = rng.normal(size=(d, d))
    return a @ a.T + d * np.eye(d)


def test_kl_of_full_rank_gaussians_is_the_closed_form():
    rng = np.random.default_rng(0)
    p, q = Gaussian(rng.normal(size=3), _random_spd(rng, 3)), Gaussian(rng.normal(size=3),
                                                                     _random_spd(rng, 3))
    j = np.linalg.inv(q.P)
    diff = q.m - p.m
    closed = 0.5 * (np.trace(j @ p.P) + diff @ j @ diff - 3
                    + np.linalg.slogdet(q.P)[1] - np.linalg.slogdet(p.P)[1])
    assert p.kl(q) == pytest.approx(closed, rel=1e-12)
    assert p.kl(p) == pytest.approx(0.0, abs=1e-12)


def test_kl_against_a_degenerate_reference_is_that_of_its_support():
    """A reference holding one component exactly, and a distribution that agrees with it
    there: the divergence of the other components' marginals; disagreeing there (another
    value, or any spread): infinite. A point reference and the same point: zero."""
    rng = np.random.default_rng(1)
    cov_p, cov_q = _random_spd(rng, 2), _random_spd(rng, 2)
    m_p, m_q = rng.normal(size=2), rng.normal(size=2)
    point = np.zeros((3, 3))
    p = Gaussian(np.r_[m_p, 4.0], np.block([[cov_p, np.zeros((2, 1))], [np.zeros((1, 3))]]))
    q = Gaussian(np.r_[m_q, 4.0], np.block([[cov_q, np.zeros((2, 1))], [np.zeros((1, 3))]]))
    assert p.kl(q) == pytest.approx(Gaussian(m_p, cov_p).kl(Gaussian(m_q, cov_q)), rel=1e-9)
    moved = Gaussian(np.r_[m_p, 4.5], p.P)
    spread = Gaussian(p.m, p.P + np.diag([0.0, 0.0, 0.1]))
    assert moved.kl(q) == np.inf and spread.kl(q) == np.inf
    assert Gaussian(np.zeros(3), point).kl(Gaussian(np.zeros(3), point)) == 0.0


def test_the_vb_kalman_filter_runs_from_a_point_prior():
    """A point prior and no process noise (the Kalman filter runs it; so must its VB
    version, whose ELBO takes the KL against that prior): the state stays where it is
    known, the noise is learned from the measurements, the ELBO finite."""
    from pgm.factors.multitarget import InverseGammaPrior, VBNoise
    from pgm.inference import Engine

    graph = pgm.FactorGraph(
        [pgm.Variable("x", 2, role="state"), pgm.Variable("noise", 2, role="noise")],
        [pgm.GaussianPrior("x", mean=[5.0, 1.0], cov=np.diag([0.0, 4.0])),
         pgm.LinearGaussianTransition("x", F=np.eye(2), Q=np.diag([0.0, 0.1])),
         pgm.LinearGaussianLikelihood("x", H=np.eye(2), R=np.eye(2), name="lik"),
         InverseGammaPrior("noise", sigma=[1.0, 1.0], alpha=2.0),
         VBNoise("noise", "x", likelihood="lik", name="vb")])
    engine = Engine(graph, 0, belief_types={"x": Gaussian})
    z = np.random.default_rng(2).normal([5.5, 1.0], 0.5, size=(10, 2))
    for t, zt in enumerate(z):
        record = engine.step(pgm.FrameContext(t + 1, measurements=zt))
    x = engine.beliefs["x"]
    assert x.m[0] == 5.0 and x.P[0, 0] == 0.0 and x.P[1, 1] > 0
    elbo = np.asarray(record.info["vb"].elbo)
    assert np.all(np.isfinite(elbo)) and np.all(np.diff(elbo) >= -1e-9)  # a VB fixed point
