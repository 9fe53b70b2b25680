"""Resampling schemes.

Every scheme is a pure function ``scheme(rng, weights, num_samples) -> indices`` with
``weights`` normalised, shape ``(N,)``, returning ancestor indices, shape
``(num_samples,)``, in ``[0, N)``; all are unbiased (each particle's expected number of
offspring is ``num_samples * w_i``) and vectorised (``cumsum`` + ``searchsorted``).
Douc, Cappé & Moulines [#douc2005] compare them: residual, stratified and systematic have
lower variance than multinomial; systematic is the usual default.

References
----------
.. [#douc2005] R. Douc, O. Cappé and E. Moulines, "Comparison of resampling schemes for
   particle filtering", Proc. 4th Int. Symp. Image and Signal Processing and Analysis
   (ISPA), 64–69, 2005. doi:10.1109/ISPA.2005.195385
.. [#kitagawa1996] G. Kitagawa, "Monte Carlo filter and smoother for non-Gaussian nonlinear
   state space models", J. Computational and Graphical Statistics 5(1), 1–25, 1996.
   doi:10.1080/10618600.1996.10474692
.. [#carpenter1999] J. Carpenter, P. Clifford and P. Fearnhead, "Improved particle filter for
   nonlinear problems", IEE Proc. Radar, Sonar and Navigation 146(1), 2–7, 1999.
   doi:10.1049/ip-rsn:19990255
.. [#liu1998] J. S. Liu and R. Chen, "Sequential Monte Carlo methods for dynamic systems",
   J. American Statistical Association 93(443), 1032–1044, 1998.
   doi:10.1080/01621459.1998.10473765
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["multinomial", "systematic", "stratified", "residual", "RESAMPLERS",
           "get_resampler", "ess_triggered"]

Resampler = Callable[[np.random.Generator, np.ndarray, int], np.ndarray]


def _check(weights: np.ndarray, num_samples: int) -> np.ndarray:
    w = np.asarray(weights, dtype=float)
    if w.ndim != 1 or w.size == 0:
        raise ValueError(f"weights must be a non-empty 1-D array, got shape {w.shape}")
    if not (w.min() >= 0.0 and np.isfinite(w.sum())):  # NaN fails the first test
        raise ValueError("weights must be finite and non-negative")
    if int(num_samples) < 1:
        raise ValueError(f"num_samples must be positive, got {num_samples}")
    return w


def _inverse_cdf(weights: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Indices ``i`` with ``cdf[i-1] <= u < cdf[i]`` for sorted uniforms ``u`` in [0, 1)."""
    cdf = np.cumsum(weights)
    idx = np.searchsorted(cdf, u * cdf[-1], side="right")
    return np.minimum(idx, weights.size - 1)


def multinomial(rng: np.random.Generator, weights: np.ndarray, num_samples: int) -> np.ndarray:
    """Independent draws from the categorical distribution of ``weights``."""
    w = _check(weights, num_samples)
    return _inverse_cdf(w, np.sort(rng.random(num_samples)))


def stratified(rng: np.random.Generator, weights: np.ndarray, num_samples: int) -> np.ndarray:
    """One uniform per stratum ``[k/M, (k+1)/M)`` (Kitagawa [#kitagawa1996])."""
    w = _check(weights, num_samples)
    u = (np.arange(num_samples) + rng.random(num_samples)) / num_samples
    return _inverse_cdf(w, u)


def systematic(rng: np.random.Generator, weights: np.ndarray, num_samples: int) -> np.ndarray:
    """One shared uniform offset for all strata (Carpenter, Clifford & Fearnhead [#carpenter1999]).

    The points ``(j + u)/M`` are evenly spaced, so particle ``i`` receives
    ``ceil(M cdf_i − u) − ceil(M cdf_{i−1} − u)`` of them: offspring counts in O(N) and one
    ``np.repeat`` instead of a binary search per point (the same indices as
    :func:`_inverse_cdf` of those points; a test checks it).
    """
    w = _check(weights, num_samples)
    u = rng.random()
    cdf = np.cumsum(w)
    m = int(num_samples)
    below = np.ceil(cdf * (m / cdf[-1]) - u)  # points strictly below each cdf value
    np.clip(below, 0, m, out=below)
    below[-1] = m
    counts = np.empty(w.size, dtype=np.int64)  # np.diff(below, prepend=0), without its copy
    counts[0] = below[0]
    np.subtract(below[1:], below[:-1], out=counts[1:], casting="unsafe")
    return np.repeat(np.arange(w.size), counts)


def residual(rng: np.random.Generator, weights: np.ndarray, num_samples: int) -> np.ndarray:
    """Deterministic ``floor(M w_i)`` copies, the remainder drawn multinomially (Liu & Chen
    [#liu1998])."""
    w = _check(weights, num_samples)
    w = w / w.sum()
    scaled = num_samples * w
    counts = np.floor(scaled).astype(np.int64)
    n_rest = num_samples - int(counts.sum())
    det = np.repeat(np.arange(w.size), counts)
    if n_rest == 0:
        return det
    rest = scaled - counts
    extra = multinomial(rng, rest / rest.sum(), n_rest)
    return np.sort(np.concatenate([det, extra]))


RESAMPLERS: dict[str, Resampler] = {
    "multinomial": multinomial,
    "systematic": systematic,
    "stratified": stratified,
    "residual": residual,
}


def get_resampler(name: str | Resampler) -> Resampler:
    """A scheme by name (or a user's callable, returned as is)."""
    if callable(name):
        return name
    try:
        return RESAMPLERS[name]
    except KeyError:
        raise ValueError(f"unknown resampling scheme {name!r} "
                         f"(choose from {sorted(RESAMPLERS)})") from None


def ess_triggered(ess: float, num: int, threshold: float) -> bool:
    """Resample when ``ESS < threshold * N`` (``threshold=1`` always, ``0`` never)."""
    return threshold >= 1.0 or ess < threshold * num
