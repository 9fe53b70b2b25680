"""Log-domain numerics shared by every engine."""

from __future__ import annotations

import numpy as np
from scipy.special import logsumexp

from .errors import DegenerateWeightsError

__all__ = ["logsumexp", "log_normalize", "normalized_weights", "ess_from_log_weights",
           "check_finite_param"]


def log_normalize(log_weights: np.ndarray) -> np.ndarray:
    """Return ``log_weights - logsumexp(log_weights)``; NaN counts as -inf.

    Raises
    ------
    DegenerateWeightsError
        If every weight is zero.
    """
    lw = np.asarray(log_weights, dtype=float)
    lw = np.where(np.isnan(lw), -np.inf, lw)
    m = np.max(lw) if lw.size else -np.inf
    if not np.isfinite(m):
        if m == np.inf:
            raise DegenerateWeightsError("a log-weight is +inf")
        raise DegenerateWeightsError("every particle weight is zero")
    shifted = lw - m
    return shifted - np.log(np.sum(np.exp(shifted)))


def normalized_weights(log_weights: np.ndarray) -> np.ndarray:
    """Normalised weights (sum to one) from unnormalised log-weights."""
    return np.exp(log_normalize(log_weights))


def ess_from_log_weights(log_weights: np.ndarray) -> float:
    """Effective sample size ``1 / sum(w_i^2)`` of normalised weights (Kong 1992)."""
    w = normalized_weights(log_weights)
    return float(1.0 / np.sum(w * w))


def check_finite_param(name: str, value, *, positive: bool = False, nonneg: bool = False):
    """Raise ``ValueError`` naming ``name`` if ``value`` has a NaN/inf or the wrong sign."""
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"parameter {name!r} must be finite, got {value!r}")
    if positive and np.any(arr <= 0):
        raise ValueError(f"parameter {name!r} must be positive, got {value!r}")
    if nonneg and np.any(arr < 0):
        raise ValueError(f"parameter {name!r} must be non-negative, got {value!r}")
    return value
