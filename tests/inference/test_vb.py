"""Mean-field VB on one Gaussian (pgm.inference.vb): the VB adaptive Kalman update is
coordinate ascent on its ELBO, and its fixed point is the batched one's."""

import numpy as np
import pytest

from pgm.core.expfam import Gaussian, InverseGamma
from pgm.inference.kalman import vb_akf_batch
from pgm.inference.vb import gaussian_elbo_terms, vb_akf_update


def _problem(seed=0):
    rng = np.random.default_rng(seed)
    prior = Gaussian(rng.normal(size=4), np.diag(rng.uniform(1.0, 3.0, size=4)))
    q_pred = InverseGamma(np.full(2, 2.5), np.array([0.4, 3.0]))
    H = np.eye(2, 4)
    z = prior.mean()[:2] + rng.normal(size=2) * 4.0
    return prior, q_pred, H, z


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_each_iteration_raises_the_elbo(seed):
    prior, q_pred, H, z = _problem(seed)
    g, q, info = vb_akf_update(prior, q_pred, H, z, tol=1e-14, max_iter=50)
    elbo = np.array(info["elbo"])
    assert len(elbo) == info["iterations"] + 1
    assert (np.diff(elbo) >= -1e-9).all(), elbo
    # the fixed point beats moving the noise belief away from it
    worse = InverseGamma(q.alpha, q.beta * 1.5)
    assert gaussian_elbo_terms(g, prior, q, q_pred, H, z) > \
        gaussian_elbo_terms(g, prior, worse, q_pred, H, z)
    np.testing.assert_allclose(info["r_hat"], q.beta / q.alpha)


def test_single_update_is_the_batched_fixed_point():
    prior, q_pred, H, z = _problem()
    g, q, info = vb_akf_update(prior, q_pred, H, z, tol=1e-10, max_iter=30)
    m, P, alpha, beta, it = vb_akf_batch(prior.m[None], prior.P[None],
                                         q_pred.alpha[None], q_pred.beta[None], H, z[None],
                                         1e-10, 30)
    np.testing.assert_array_equal(g.mean(), m[0])
    np.testing.assert_array_equal(g.cov(), P[0])
    np.testing.assert_array_equal(q.beta, beta[0])
    assert info["iterations"] == it
