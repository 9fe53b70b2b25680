"""Log-domain numerics shared by every engine.

References
----------
.. [#kong1992] A. Kong, "A note on importance sampling using standardized weights",
   Technical Report 348, Department of Statistics, University of Chicago, 1992 (no DOI).
"""

from __future__ import annotations

import math

import numpy as np

from pgm.core.errors import DegenerateWeightsError

__all__ = ["scratch", "logsumexp", "log_normalize", "normalized_weights", "ess_from_log_weights",
           "check_finite_param"]


def logsumexp(a: np.ndarray, axis: int | None = None) -> np.ndarray | float:
    """``log(sum(exp(a)))`` with the max-shift trick; ``-inf`` for all-``-inf`` input.

    A plain-numpy version: ``scipy.special.logsumexp`` costs ~0.2 ms per call in array-API
    dispatch, which dominates a filter step with few particles.
    """
    a = np.asarray(a, dtype=float)
    if axis is None:
        if a.size == 0:
            return -np.inf
        m = float(a.max())
        if math.isfinite(m):  # python scalars: ~2x faster than numpy's on small arrays
            return m + math.log(float(np.exp(a - m).sum()))
        return m  # NaN, all -inf, or a +inf entry
    if a.size == 0:
        return np.full(np.delete(a.shape, axis), -np.inf)
    m = np.max(a, axis=axis, keepdims=True)
    m = np.where(np.isfinite(m), m, 0.0)
    with np.errstate(divide="ignore"):
        out = np.log(np.sum(np.exp(a - m), axis=axis, keepdims=True)) + m
    return np.squeeze(out, axis=axis)


def log_normalize(log_weights: np.ndarray) -> np.ndarray:
    """Return ``log_weights - logsumexp(log_weights)``; NaN counts as -inf.

    Raises
    ------
    DegenerateWeightsError
        If every weight is zero (or one is +inf).
    """
    lw = np.asarray(log_weights, dtype=float)
    if lw.size == 0:
        raise DegenerateWeightsError("no particles")
    m = float(lw.max())
    if m != m:  # a NaN: treat it as -inf
        lw = np.where(np.isnan(lw), -np.inf, lw)
        m = float(lw.max())
    if not math.isfinite(m):
        if m == math.inf:
            raise DegenerateWeightsError("a log-weight is +inf")
        raise DegenerateWeightsError("every particle weight is zero")
    shifted = lw - m
    return shifted - math.log(float(np.exp(shifted).sum()))


def normalized_weights(log_weights: np.ndarray) -> np.ndarray:
    """Normalised weights (sum to one) from unnormalised log-weights."""
    return np.exp(log_normalize(log_weights))


def ess_from_log_weights(log_weights: np.ndarray) -> float:
    """Effective sample size ``1 / sum(w_i^2)`` of normalised weights (Kong [#kong1992])."""
    w = normalized_weights(log_weights)
    return float(1.0 / np.sum(w * w))


def scratch(owner: object, key: str, shape: tuple[int, ...]) -> np.ndarray:
    """A float64 C-contiguous work buffer of ``shape``, kept on ``owner`` under ``key``
    and reused (grown by a quarter when too small). Fresh temporaries of hundreds of
    kilobytes are mmap'd by glibc and page-faulted in on every call; hot loops that make
    one per step reuse this instead. The content is undefined."""
    size = math.prod(shape)  # np.prod of a tuple costs an array (a few µs a call)
    buf = owner.__dict__.get(key)
    if buf is None or buf.size < size:
        buf = np.empty(max(size, 1) * 5 // 4)
        owner.__dict__[key] = buf
    return buf[:size].reshape(shape)


def check_finite_param(name: str, value, *, positive: bool = False, nonneg: bool = False):
    """Raise ``ValueError`` naming ``name`` if ``value`` has a NaN/inf or the wrong sign."""
    arr = np.asarray(value, dtype=float)
    shown = value.item() if isinstance(value, np.generic) else value  # -1.0, not np.float64(-1.0)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"parameter {name!r} must be finite, got {shown!r}")
    if positive and np.any(arr <= 0):
        raise ValueError(f"parameter {name!r} must be positive, got {shown!r}")
    if nonneg and np.any(arr < 0):
        raise ValueError(f"parameter {name!r} must be non-negative, got {shown!r}")
    return value
