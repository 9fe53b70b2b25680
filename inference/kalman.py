"""The exact Kalman filter: an oracle for the particle engines (and a real filter).

The same :class:`~pgm.FactorGraph` feeds the approximate engine and this exact one:
:func:`linear_gaussian_matrices` reads ``(m0, P0, F, Q, H, R)`` off a graph made of a
:class:`~pgm.GaussianPrior`, a :class:`~pgm.LinearGaussianTransition` and a
:class:`~pgm.LinearGaussianLikelihood` (particles' ``MVLinearGauss`` duality).

Convention (as in the engine): the prior is the belief of the first frame's state
before its measurement, so the first step is an update without a prediction.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pgm.core.graph import FactorGraph
from pgm.factors import GaussianPrior, LinearGaussianLikelihood, LinearGaussianTransition

__all__ = ["KalmanResult", "kalman_filter", "kalman_update", "kalman_update_batch",
           "linear_gaussian_matrices", "selects", "vb_akf_batch"]


@dataclass(frozen=True)
class KalmanResult:
    """Filtered means ``(T, d)``, covariances ``(T, d, d)`` and ``log p(y_t | y_{1:t-1})`` ``(T,)``."""

    filtered_means: np.ndarray
    filtered_covs: np.ndarray
    log_likelihood_increments: np.ndarray

    @property
    def marginal_log_likelihood(self) -> float:
        """``log p(y_{1:T})``."""
        return float(np.sum(self.log_likelihood_increments))


def linear_gaussian_matrices(graph: FactorGraph, variable: str) -> dict[str, np.ndarray]:
    """``m0, P0, F, Q, H, R`` of a linear-Gaussian graph for ``variable``."""
    def one(kind, cls):
        fs = graph.factors_of(variable, kind)
        if len(fs) != 1 or not isinstance(fs[0], cls):
            raise ValueError(f"variable {variable!r} needs exactly one {cls.__name__} "
                             f"({kind}) for the Kalman filter")
        return fs[0]

    prior = one("prior", GaussianPrior)
    trans = one("transition", LinearGaussianTransition)
    lik = one("likelihood", LinearGaussianLikelihood)
    return {"m0": prior.mean(), "P0": prior.cov, "F": trans.F, "Q": trans.Q, "H": lik.H,
            "R": lik.R}


def kalman_update(m: np.ndarray, P: np.ndarray, H: np.ndarray, R: np.ndarray,
                  y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """One measurement update: posterior mean, covariance and ``log N(y; H m, S)``
    (:func:`kalman_update_batch` on one Gaussian)."""
    m = np.asarray(m, dtype=float)
    P = np.asarray(P, dtype=float)
    S = H @ P @ H.T + R
    r = y - H @ m
    mm, PP = kalman_update_batch(m[None], P[None], H, R, np.asarray(y, dtype=float)[None])
    _, logdet = np.linalg.slogdet(2 * np.pi * S)
    return mm[0], PP[0], float(-0.5 * (logdet + r @ np.linalg.solve(S, r)))


def selects(H: np.ndarray) -> bool:
    """Whether ``H`` reads the first ``k`` components of the state (``[I 0]``)."""
    k = H.shape[0]
    return H.shape[1] >= k and bool(np.array_equal(H, np.eye(k, H.shape[1])))


def kalman_update_batch(m: np.ndarray, P: np.ndarray, H: np.ndarray, R: np.ndarray,
                        z: np.ndarray, select: bool | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """The one Kalman update of the package, of ``B`` Gaussians at once: means ``(B, d)``,
    covariances ``(B, d, d)``, measurements ``z`` ``(B, k)``, noise ``R`` ``(k, k)`` or
    ``(B, k, k)``; ``P ← P − K S Kᵀ``, symmetrised. ``select``: whether ``H = [I 0]``
    (:func:`selects`; found out when not given).

    >>> m, P = kalman_update_batch(np.zeros((2, 2)), np.stack([np.eye(2)] * 2), np.eye(2),
    ...                            np.eye(2), np.ones((2, 2)))
    >>> m.round(2).tolist()
    [[0.5, 0.5], [0.5, 0.5]]
    """
    k = H.shape[0]
    if select if select is not None else selects(H):  # H reads the box: slices, no products
        PHt = P[:, :, :k]
        S = P[:, :k, :k] + R
    else:
        PHt = P @ H.T  # (B, d, k)
        S = H @ PHt + R  # (B, k, k)
    K = np.linalg.solve(S, np.swapaxes(PHt, 1, 2)).swapaxes(1, 2)  # P Hᵀ S⁻¹ (S symmetric)
    r = z - m @ H.T
    m = m + np.einsum("bdk,bk->bd", K, r)
    P = P - K @ np.swapaxes(PHt, 1, 2)
    P = 0.5 * (P + np.swapaxes(P, 1, 2))
    return m, P


def vb_akf_batch(m0: np.ndarray, P0: np.ndarray, alpha0: np.ndarray, beta0: np.ndarray,
                 H: np.ndarray, z: np.ndarray, tol: float, max_iter: int,
                 size2: np.ndarray | float = 1.0, select: bool | None = None,
                 on_iteration: Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], None]
                 | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """The VB adaptive Kalman filter's fixed point of ``q(x) q(R)``, of ``B`` Gaussians at
    once: eqs. (16)–(17) of [#feng2015], garbled in its text, in the form of
    [#sarkka2009] — ``α = α̂ + ½``; ``β = β̂ + ½ (z − H m)² + ½ diag(H P Hᵀ)``, with
    ``R = diag(β / α)`` — iterated until the largest relative change of ``β / α`` is
    below ``tol`` (or ``max_iter``).

    ``m0, P0``: the predicted means ``(B, d)`` and covariances; ``alpha0, beta0``
    ``(B, k)``: the predicted inverse-Gamma noise beliefs; ``z`` ``(B, k)``. ``size2``:
    the noise is of the variance in units of a size (scale-aware, ``R = diag(r · size²)``,
    residuals measured so too), ``(B, k)`` or 1. ``on_iteration(m, P, alpha, beta)`` is
    called at each iteration with the update it made (the ELBO of
    :func:`pgm.inference.vb.vb_akf_update`). Returns ``(m, P, alpha, beta, iterations)``.
    """
    alpha = alpha0 + 0.5
    beta = beta0.copy()
    r_hat = beta / alpha
    eye = np.eye(H.shape[0])
    m, P, it = m0, P0, 0
    for it in range(1, max_iter + 1):  # noqa: B007 - the count is reported
        R = np.einsum("bk,kl->bkl", r_hat * size2, eye)
        m, P = kalman_update_batch(m0, P0, H, R, z, select)
        if on_iteration is not None:
            on_iteration(m, P, alpha, beta)
        resid = z - m @ H.T
        hph = np.einsum("kd,bde,ke->bk", H, P, H)
        beta = beta0 + 0.5 * resid ** 2 / size2 + 0.5 * hph / size2
        new_r = beta / alpha
        change = np.max(np.abs(new_r - r_hat) / r_hat)
        r_hat = new_r
        if change < tol:
            break
    return m, P, alpha, beta, it


def kalman_filter(m0, P0, F, Q, H, R, ys) -> KalmanResult:
    """Filter ``ys`` (shape ``(T, k)``; a row of NaN is a missing measurement)."""
    m = np.asarray(m0, dtype=float)
    P = np.asarray(P0, dtype=float)
    F, Q, H, R = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (F, Q, H, R))
    ys = np.asarray(ys, dtype=float).reshape(len(ys), -1)
    T, d = len(ys), m.size
    means, covs, lls = np.zeros((T, d)), np.zeros((T, d, d)), np.zeros(T)
    for t in range(T):
        if t > 0:
            m = F @ m
            P = F @ P @ F.T + Q
        y = ys[t]
        if np.all(np.isfinite(y)):
            m, P, lls[t] = kalman_update(m, P, H, R, y)
        means[t], covs[t] = m, P
    return KalmanResult(means, covs, lls)
