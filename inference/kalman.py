"""The exact Kalman filter: an oracle for the particle engines (and a real filter).

The same :class:`~pgm.FactorGraph` feeds the approximate engine and this exact one:
:func:`linear_gaussian_matrices` reads ``(m0, P0, F, Q, H, R)`` off a graph made of a
:class:`~pgm.GaussianPrior`, a :class:`~pgm.LinearGaussianTransition` and a
:class:`~pgm.LinearGaussianLikelihood` (particles' ``MVLinearGauss`` duality).

Convention (as in the engine): the prior is the belief of the first frame's state
before its measurement, so the first step is an update without a prediction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgm.core.graph import FactorGraph
from pgm.factors import GaussianPrior, LinearGaussianLikelihood, LinearGaussianTransition

__all__ = ["KalmanResult", "kalman_filter", "kalman_update", "linear_gaussian_matrices"]


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
    """One measurement update: posterior mean, covariance and ``log N(y; H m, S)``.

    The one Kalman update of the package: :func:`kalman_filter` and the exact Gaussian
    rules of :mod:`pgm.inference.vb` (including the VB adaptive Kalman filter) use it.
    """
    S = H @ P @ H.T + R
    r = y - H @ m
    K = np.linalg.solve(S, H @ P).T
    m = m + K @ r
    P = P - K @ S @ K.T
    P = 0.5 * (P + P.T)
    _, logdet = np.linalg.slogdet(2 * np.pi * S)
    return m, P, float(-0.5 * (logdet + r @ np.linalg.solve(S, r)))


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
