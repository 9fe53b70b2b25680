"""Belief representations.

* :class:`Particles` — weighted particles ``(x, log_weights)`` with a leading particle
  axis. Log-weights are *unnormalised*: ``log_mass = logsumexp(log_weights)`` is the
  total mass (1 for a normalised posterior, the expected target count for a PHD
  intensity). Beliefs are immutable: methods return new objects.
* :class:`Intensity` — particles whose total weight is an expected number of targets
  (the belief of a ``set`` variable); its resampling keeps the mass.

Exponential-family beliefs for variational Bayes (Gaussian, inverse-Gamma) join this
module with the VB engine.

References
----------
.. [#ristic2012] B. Ristic, D. Clark, B.-N. Vo and B.-T. Vo, "Adaptive target birth intensity
   for PHD and CPHD filters", IEEE Trans. Aerospace and Electronic Systems 48(2),
   1656–1668, 2012. doi:10.1109/TAES.2012.6178085
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property
from typing import ClassVar

import numpy as np

from pgm.core.numerics import log_normalize, logsumexp

__all__ = ["Particles", "Intensity", "ParticleArrays"]


class ParticleArrays:
    """Operations shared by :class:`Particles` ``(N, d)`` and the batched particles of a
    plate's replicas ``(K, N, d)`` (:class:`pgm.core.batched.BatchedParticles`): the
    particle axis is the second last, the state axis the last; log-weights have the
    shape of ``x`` without its last axis."""

    x: np.ndarray
    log_weights: np.ndarray
    history: tuple[np.ndarray, ...]

    @property
    def num(self) -> int:
        """Number of particles ``N`` (per replica, for a batch)."""
        return self.x.shape[-2]

    @property
    def dim(self) -> int:
        """Dimension ``d`` of one particle."""
        return self.x.shape[-1]

    def reweight(self, delta_log_weights: np.ndarray):
        """Add ``delta_log_weights`` (the shape of the log-weights) to the log-weights
        (NaN counts as ``-inf``)."""
        delta = np.asarray(delta_log_weights, dtype=float)
        if delta.shape != self.log_weights.shape:
            raise ValueError(f"reweight: shape {delta.shape} != {self.log_weights.shape}")
        lw = self.log_weights + delta
        if np.isnan(lw).any():
            lw = np.where(np.isnan(lw), -np.inf, lw)
        return self._trusted(self.x, lw, self.history)

    def moved(self, x_new: np.ndarray, history_len: int | None = None):
        """Particles moved to ``x_new``; the current ``x`` is pushed onto the history."""
        n_hist = len(self.history) if history_len is None else history_len
        hist = ((self.x,) + self.history)[:n_hist]
        x_new = np.asarray(x_new, dtype=float)
        if x_new.shape != self.x.shape:
            raise ValueError(f"moved: shape {x_new.shape} != {self.x.shape}")
        return self._trusted(x_new, self.log_weights, hist)


@dataclass(frozen=True)
class Particles(ParticleArrays):
    r"""Weighted particle approximation :math:`\sum_i e^{\ell_i} \delta_{x_i}`.

    Parameters
    ----------
    x : ndarray, shape (N, d)
        Current values.
    log_weights : ndarray, shape (N,)
        Unnormalised log-weights (NaN is treated as -inf).
    history : tuple of ndarray, each (N, d)
        Past values, most recent first (``history[0]`` is ``x_{t-1}``), kept for
        higher-order transition factors and resampled together with ``x``.
    """

    x: np.ndarray
    log_weights: np.ndarray
    history: tuple[np.ndarray, ...] = field(default=())
    #: likelihood factors act on this belief by reweighting its particles (the engine's
    #: weight-stage contract: a likelihood rule returns the increment, never moves them)
    likelihood_reweights: ClassVar[bool] = True

    def __post_init__(self) -> None:
        x = np.asarray(self.x, dtype=float)
        if x.ndim != 2:
            raise ValueError(f"particles must have shape (N, d), got {x.shape}")
        lw = np.asarray(self.log_weights, dtype=float)
        if lw.shape != (x.shape[0],):
            raise ValueError(f"log_weights shape {lw.shape} does not match {x.shape[0]} particles")
        lw = np.where(np.isnan(lw), -np.inf, lw)
        for h in self.history:
            if np.shape(h) != x.shape:
                raise ValueError(f"history entry shape {np.shape(h)} != particles {x.shape}")
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "log_weights", lw)
        object.__setattr__(self, "history", tuple(np.asarray(h, dtype=float)
                                                  for h in self.history))

    # -- construction -------------------------------------------------------------------
    @classmethod
    def _trusted(cls, x: np.ndarray, log_weights: np.ndarray,
                 history: tuple[np.ndarray, ...] = (), log_mass: float | None = None
                 ) -> Particles:
        """Build without validation, for arrays the toolkit already checked (hot path).

        ``log_mass``, when the caller knows it, is stored so it is not recomputed.
        """
        obj = object.__new__(cls)
        obj.__dict__.update(x=x, log_weights=log_weights, history=tuple(history))
        if log_mass is not None:
            obj.__dict__["log_mass"] = float(log_mass)
        return obj

    @classmethod
    def uniform(cls, x: np.ndarray, mass: float = 1.0, history_len: int = 0) -> Particles:
        """Equally weighted particles of total ``mass``; history filled with ``x``."""
        x = np.asarray(x, dtype=float)
        n = x.shape[0]
        lw = np.full(n, np.log(mass) - np.log(n)) if mass > 0 else np.full(n, -np.inf)
        return cls(x, lw, tuple(x.copy() for _ in range(history_len)))

    # -- properties ---------------------------------------------------------------------
    @cached_property
    def log_mass(self) -> float:
        """``logsumexp(log_weights)`` (``-inf`` with no particles)."""
        if self.log_weights.size == 0:
            return -np.inf
        return float(logsumexp(self.log_weights))

    @property
    def mass(self) -> float:
        """Total weight."""
        return float(np.exp(self.log_mass))

    @cached_property
    def weights(self) -> np.ndarray:
        """Normalised weights, shape ``(N,)`` (computed once; do not modify in place)."""
        lm = self.log_mass
        if not math.isfinite(lm):
            log_normalize(self.log_weights)  # raises DegenerateWeightsError with the reason
        w = np.exp(self.log_weights - lm)
        w /= float(w.sum())  # exact normalisation despite rounding in log_mass
        w.flags.writeable = False
        return w

    @cached_property
    def ess(self) -> float:
        """Effective sample size ``1 / sum(w^2)`` of the normalised weights."""
        w = self.weights
        return 1.0 / float(np.dot(w, w))

    def mean(self) -> np.ndarray:
        """Weighted mean, shape ``(d,)``."""
        return self.weights @ self.x

    def estimate(self) -> np.ndarray:
        """The point estimate of the belief protocol: the weighted mean."""
        return self.mean()

    def cov(self) -> np.ndarray:
        """Weighted covariance, shape ``(d, d)``."""
        w = self.weights
        c = self.x - w @ self.x
        return (c * w[:, None]).T @ c

    # -- transformations ----------------------------------------------------------------
    def normalized(self) -> Particles:
        """The same particles with total mass 1."""
        lm = self.log_mass
        if not math.isfinite(lm):
            log_normalize(self.log_weights)  # raises DegenerateWeightsError with the reason
        out = self._trusted(self.x, self.log_weights - lm, self.history, log_mass=0.0)
        for key in ("weights", "ess"):  # identical for the normalised copy
            if key in self.__dict__:
                out.__dict__[key] = self.__dict__[key]
        return out

    def take(self, indices: np.ndarray, log_weights: np.ndarray) -> Particles:
        """Select particles (and their histories) by index with new log-weights."""
        idx = np.asarray(indices)
        lw = np.asarray(log_weights, dtype=float)
        if lw.shape != idx.shape:
            raise ValueError(f"take: {idx.shape[0]} indices but {lw.shape} log-weights")
        return self._trusted(self.x[idx], lw, tuple(h[idx] for h in self.history))

    def resample(self, rng: np.random.Generator, scheme, num: int | None = None) -> Particles:
        """Resample ``num`` particles (default ``N``) keeping the total mass.

        ``scheme`` is a function ``(rng, weights, num) -> indices`` (see
        :mod:`pgm.inference.resampling`). Every new particle gets weight ``mass / num``.
        """
        num = self.num if num is None else int(num)
        idx = scheme(rng, self.weights, num)
        lm = self.log_mass
        return self._trusted(self.x[idx], np.full(num, lm - np.log(num)),
                             tuple(h[idx] for h in self.history), log_mass=lm)


@dataclass(frozen=True)
class Intensity(Particles):
    """A PHD intensity: particles whose total weight is the expected number of targets.

    ``x, log_weights`` are the *persistent* particles; ``newborn`` holds the particles
    born from this frame's measurements (the persistent/newborn split of [#ristic2012]):
    they are not re-weighted, not resampled and not extracted this frame, and join the
    persistent set at the next prediction. ``expected_count`` includes them. ``labels``
    (optional, ``(N,)`` int) are lineage labels carried through prediction and resampling
    (one label per birth), used for per-track noise beliefs; ``newborn`` then carries
    labels too.
    """

    newborn: Particles | None = None
    labels: np.ndarray | None = None
    #: the PHD corrector is not a reweighting: its rule updates the intensity itself
    likelihood_reweights: ClassVar[bool] = False

    @property
    def expected_count(self) -> float:
        """Persistent plus newborn mass."""
        extra = self.newborn.mass if self.newborn is not None and self.newborn.num else 0.0
        return (self.mass if self.num else 0.0) + extra

    @classmethod
    def _trusted_set(cls, x: np.ndarray, log_weights: np.ndarray, *,
                     newborn: Particles | None = None, labels: np.ndarray | None = None,
                     log_mass: float | None = None) -> Intensity:
        """:meth:`Particles._trusted` for intensities (the PHD rules' hot path)."""
        obj = cls._trusted(x, log_weights, (), log_mass=log_mass)
        obj.__dict__.update(newborn=newborn, labels=labels)
        return obj

    @classmethod
    def empty(cls, dim: int) -> Intensity:
        """No particles, mass 0."""
        return cls(np.zeros((0, dim)), np.zeros(0))
