"""The one Kalman update and the one VB adaptive Kalman fixed point (pgm.inference.kalman)
against closed forms written out here."""

import numpy as np
import pytest

from pgm.inference.kalman import (
    kalman_filter,
    kalman_update,
    kalman_update_batch,
    selects,
    vb_akf_batch,
)


def _random_gaussians(rng, B, d):
    m = rng.normal(size=(B, d))
    A = rng.normal(size=(B, d, d))
    P = A @ np.swapaxes(A, 1, 2) + d * np.eye(d)
    return m, P


def _textbook(m, P, H, R, z):
    """The information form of the posterior: an independent closed form."""
    Pi = np.linalg.inv(np.linalg.inv(P) + H.T @ np.linalg.inv(R) @ H)
    mi = Pi @ (np.linalg.inv(P) @ m + H.T @ np.linalg.inv(R) @ z)
    return mi, Pi


@pytest.mark.parametrize("select", [True, False])
def test_batched_update_is_the_information_form_posterior(select):
    rng = np.random.default_rng(0)
    B, d, k = 5, 6, 3
    m, P = _random_gaussians(rng, B, d)
    H = np.eye(k, d) if select else rng.normal(size=(k, d))
    assert selects(H) is select
    R = np.diag(rng.uniform(0.5, 2.0, size=k))
    z = rng.normal(size=(B, k))
    mm, PP = kalman_update_batch(m, P, H, R, z)
    for b in range(B):
        mi, Pi = _textbook(m[b], P[b], H, R, z[b])
        np.testing.assert_allclose(mm[b], mi, rtol=1e-9, atol=1e-10)
        np.testing.assert_allclose(PP[b], Pi, rtol=1e-9, atol=1e-10)
        np.testing.assert_array_equal(PP[b], PP[b].T)
    # per-replica noise (B, k, k) and the select shortcut give the same numbers
    Rb = np.stack([R] * B)
    m2, P2 = kalman_update_batch(m, P, H, Rb, z, select=select)
    np.testing.assert_allclose(m2, mm, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(P2, PP, rtol=1e-12, atol=1e-12)


def test_single_update_is_the_batched_one_with_its_log_likelihood():
    rng = np.random.default_rng(1)
    m, P = _random_gaussians(rng, 1, 4)
    H = rng.normal(size=(2, 4))
    R = np.diag([0.3, 0.7])
    z = rng.normal(size=2)
    m1, P1, ll = kalman_update(m[0], P[0], H, R, z)
    mb, Pb = kalman_update_batch(m, P, H, R, z[None])
    np.testing.assert_array_equal(m1, mb[0])
    np.testing.assert_array_equal(P1, Pb[0])
    S = H @ P[0] @ H.T + R
    r = z - H @ m[0]
    expected = -0.5 * (np.log(np.linalg.det(2 * np.pi * S)) + r @ np.linalg.inv(S) @ r)
    assert ll == pytest.approx(expected, rel=1e-12)


def test_kalman_filter_skips_missing_measurements():
    F = np.array([[1.0, 1.0], [0.0, 1.0]])
    Q, H, R = 0.1 * np.eye(2), np.array([[1.0, 0.0]]), np.array([[0.5]])
    ys = np.array([[0.0], [np.nan], [2.0]])
    res = kalman_filter(np.zeros(2), np.eye(2), F, Q, H, R, ys)
    m, P = np.zeros(2), np.eye(2)
    m, P, _ = kalman_update(m, P, H, R, ys[0])
    m, P = F @ m, F @ P @ F.T + Q  # frame 2: predicted only
    np.testing.assert_allclose(res.filtered_means[1], m)
    m, P = F @ m, F @ P @ F.T + Q
    m, P, _ = kalman_update(m, P, H, R, ys[2])
    np.testing.assert_allclose(res.filtered_means[2], m)
    assert res.log_likelihood_increments[1] == 0.0


def _vb_akf_written_out(m0, P0, a0, b0, H, z, tol, max_iter, size2=1.0):
    """Särkkä and Nummenmaa (2009)'s fixed point for one Gaussian, written out."""
    alpha, beta = a0 + 0.5, b0.copy()
    r_hat = beta / alpha
    for it in range(1, max_iter + 1):  # noqa: B007 - the count is returned
        m, P, _ = kalman_update(m0, P0, H, np.diag(r_hat * size2), z)
        resid = z - H @ m
        beta = b0 + 0.5 * resid ** 2 / size2 + 0.5 * np.diag(H @ P @ H.T) / size2
        new = beta / alpha
        done = np.max(np.abs(new - r_hat) / r_hat) < tol
        r_hat = new
        if done:
            break
    return m, P, alpha, beta, it


@pytest.mark.parametrize("scaled", [False, True])
def test_vb_akf_batch_is_the_fixed_point_of_each_gaussian(scaled):
    """Batched, each Gaussian converges to its own fixed point; with one Gaussian the
    iteration count is its own (the batch stops when all have converged)."""
    rng = np.random.default_rng(2)
    B, d, k = 4, 4, 2
    m0, P0 = _random_gaussians(rng, B, d)
    H = np.eye(k, d)
    a0 = np.full((B, k), 3.0)
    b0 = rng.uniform(0.5, 2.0, size=(B, k))
    z = rng.normal(size=(B, k)) * 2
    size2 = rng.uniform(1.0, 4.0, size=(B, k)) if scaled else 1.0
    m, P, alpha, beta, it = vb_akf_batch(m0, P0, a0, b0, H, z, 1e-12, 200, size2)
    for b in range(B):
        s2 = size2[b] if scaled else 1.0
        mb, Pb, ab, bb, itb = _vb_akf_written_out(m0[b], P0[b], a0[b], b0[b], H, z[b],
                                                  1e-12, 200, s2)
        np.testing.assert_allclose(m[b], mb, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(P[b], Pb, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(beta[b], bb, rtol=1e-8)
        np.testing.assert_array_equal(alpha[b], ab)
        assert itb <= it < 200
    one = vb_akf_batch(m0[:1], P0[:1], a0[:1], b0[:1], H, z[:1], 1e-12, 200)
    assert one[4] == _vb_akf_written_out(m0[0], P0[0], a0[0], b0[0], H, z[0], 1e-12, 200)[4]
    seen = []
    vb_akf_batch(m0, P0, a0, b0, H, z, 1e-12, 3, on_iteration=lambda *a: seen.append(a))
    assert len(seen) == 3 and seen[0][2].shape == (B, k)
