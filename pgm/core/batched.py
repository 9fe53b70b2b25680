"""Batched beliefs: the beliefs of a plate's ``K`` replicas along a leading target axis.

A plate (:mod:`pgm.core.plate`) is a batch axis of beliefs, not a second engine. Each
belief type of a single graph has a batched form that the engine keeps for a plate
variable:

* :class:`BatchedParticles` — particles ``(K, N, d)`` with log-weights ``(K, N)`` and
  histories ``(K, N, d)``: the same operations as :class:`~pgm.Particles` (reweight,
  normalise, ESS, per-row resampling, estimate), row by row with the *same arithmetic*,
  so that replica ``k`` of a batch holds to the last bit what a single-graph run of the
  same factors would hold;
* :class:`Replicated` — a batch of any other belief (a :class:`~pgm.core.expfam.Gaussian`
  of an exact Kalman filter, an :class:`~pgm.core.expfam.InverseGamma` noise belief for
  mean-field VB per target), kept as one object per replica. :func:`batched_type`
  names the class: ``batched_type(Gaussian)`` is ``Replicated[Gaussian]``.

Every batched type names the single-graph type of one replica as ``row_type``; the
engine's rule table falls back to running a ``row_type`` rule once per replica where no
batched rule is registered (:mod:`pgm.inference.plates`), so everything a single graph
can hold, a plate can hold.

>>> import numpy as np
>>> b = BatchedParticles.uniform(np.zeros((3, 5, 2)))
>>> b.K, b.num, b.dim, b.row(0).num
(3, 5, 2, 5)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar

import numpy as np

from pgm.core.beliefs import ParticleArrays, Particles
from pgm.core.expfam import Gaussian, InverseGamma

__all__ = ["BatchedParticles", "BatchedGaussian", "BatchedInverseGamma", "Replicated",
           "batched_type", "is_batched", "register_batched"]


def is_batched(belief: Any) -> bool:
    """Whether ``belief`` is the belief of a plate's replicas (a batched type)."""
    return getattr(type(belief), "row_type", None) is not None


@dataclass(frozen=True)
class BatchedParticles(ParticleArrays):
    """``K`` particle beliefs of ``N`` particles each (the replicas of a plate variable).

    Parameters
    ----------
    x : ndarray (K, N, d)
    log_weights : ndarray (K, N)
        Unnormalised log-weights per replica.
    history : tuple of ndarray (K, N, d)
        Past values, most recent first (as :class:`~pgm.Particles`).
    """

    x: np.ndarray
    log_weights: np.ndarray
    history: tuple[np.ndarray, ...] = field(default=())
    likelihood_reweights: ClassVar[bool] = True
    row_type: ClassVar[type] = Particles

    def __post_init__(self) -> None:
        x = np.asarray(self.x, dtype=float)
        if x.ndim != 3:
            raise ValueError(f"batched particles must have shape (K, N, d), got {x.shape}")
        lw = np.asarray(self.log_weights, dtype=float)
        if lw.shape != x.shape[:2]:
            raise ValueError(f"log_weights shape {lw.shape} does not match particles {x.shape}")
        for h in self.history:
            if np.shape(h) != x.shape:
                raise ValueError(f"history entry shape {np.shape(h)} != particles {x.shape}")
        object.__setattr__(self, "x", x)
        object.__setattr__(self, "log_weights", np.where(np.isnan(lw), -np.inf, lw))
        object.__setattr__(self, "history", tuple(np.asarray(h, float) for h in self.history))

    # -- construction -------------------------------------------------------------------
    @classmethod
    def _trusted(cls, x: np.ndarray, log_weights: np.ndarray,
                 history: tuple[np.ndarray, ...] = (),
                 log_mass: np.ndarray | None = None) -> BatchedParticles:
        obj = object.__new__(cls)
        obj.__dict__.update(x=x, log_weights=log_weights, history=tuple(history))
        if log_mass is not None:
            obj.__dict__["log_mass"] = log_mass
        return obj

    @classmethod
    def uniform(cls, x: np.ndarray, history_len: int = 0) -> BatchedParticles:
        """Equally weighted particles ``(K, N, d)`` of mass 1 per replica."""
        x = np.asarray(x, dtype=float)
        n = x.shape[1]
        return cls(x, np.full(x.shape[:2], np.log(1.0) - np.log(n)),
                   tuple(x.copy() for _ in range(history_len)))

    @classmethod
    def empty(cls, num: int, dim: int, history_len: int = 0) -> BatchedParticles:
        """No replica (``K = 0``)."""
        x = np.zeros((0, num, dim))
        return cls._trusted(x, np.zeros((0, num)), tuple(x for _ in range(history_len)),
                            log_mass=np.zeros(0))

    @classmethod
    def stack(cls, rows: Sequence[Particles]) -> BatchedParticles:
        """The batch of single-replica beliefs ``rows`` (equal ``N``, ``d`` and history)."""
        lm = [r.__dict__.get("log_mass") for r in rows]
        return cls._trusted(np.stack([r.x for r in rows]),
                            np.stack([r.log_weights for r in rows]),
                            tuple(np.stack(h) for h in zip(*(r.history for r in rows),
                                                           strict=True)),
                            log_mass=None if any(m is None for m in lm) else np.array(lm))

    def row(self, k: int) -> Particles:
        """Replica ``k`` as a :class:`~pgm.Particles` (views, not copies)."""
        lm = self.__dict__.get("log_mass")
        return Particles._trusted(self.x[k], self.log_weights[k],
                                  tuple(h[k] for h in self.history),
                                  log_mass=None if lm is None else float(lm[k]))

    def rows(self) -> list[Particles]:
        """Every replica as a :class:`~pgm.Particles`."""
        return [self.row(k) for k in range(self.K)]

    # -- properties ---------------------------------------------------------------------
    @property
    def K(self) -> int:  # noqa: N802 - the plate's size is called K
        """Number of replicas."""
        return self.x.shape[0]

    @cached_property
    def log_mass(self) -> np.ndarray:
        """``(K,)`` per-replica ``logsumexp`` of the log-weights, computed as
        :func:`pgm.core.numerics.logsumexp` computes one row."""
        lw = self.log_weights
        if lw.shape[1] == 0:
            return np.full(lw.shape[0], -np.inf)
        m = lw.max(axis=1)
        finite = np.isfinite(m)
        e = np.exp(lw - np.where(finite, m, 0.0)[:, None])
        # row by row: numpy's axis-1 reduction may round differently from a 1-D sum
        return np.array([mk + math.log(float(row.sum())) if ok else mk
                         for mk, row, ok in zip(m.tolist(), e, finite.tolist(), strict=True)])

    @cached_property
    def weights(self) -> np.ndarray:
        """``(K, N)`` normalised weights per replica (rows of degenerate replicas: NaN)."""
        lm = self.log_mass
        ok = np.isfinite(lm)
        w = np.exp(self.log_weights - np.where(ok, lm, 0.0)[:, None])
        # each row divided by its own 1-D sum, as Particles.weights divides (exactly)
        sums = np.array([float(row.sum()) for row in w]) if self.K else np.zeros(0)
        w = w / np.where(ok, sums, np.nan)[:, None]
        w.flags.writeable = False
        return w

    @cached_property
    def ess(self) -> np.ndarray:
        """``(K,)`` effective sample size per replica."""
        w = self.weights
        return np.array([1.0 / float(np.dot(wk, wk)) for wk in w])

    def estimate(self) -> np.ndarray:
        """The point estimates of the belief protocol: ``(K, d)`` weighted means."""
        return self.mean()

    def mean(self) -> np.ndarray:
        """``(K, d)`` weighted means (each row as :meth:`Particles.mean`)."""
        w = self.weights
        if not self.K:
            return np.zeros((0, self.dim))
        return np.stack([w[k] @ self.x[k] for k in range(self.K)])

    def cov(self) -> np.ndarray:
        """``(K, d, d)`` weighted covariances (each row as :meth:`Particles.cov`)."""
        if not self.K:
            return np.zeros((0, self.dim, self.dim))
        return np.stack([r.cov() for r in self.rows()])

    # -- transformations ----------------------------------------------------------------
    def normalized(self, fallback: BatchedParticles | None = None
                   ) -> tuple[BatchedParticles, np.ndarray]:
        """Each replica with mass 1, and the ``(K,)`` mask of degenerate replicas (no
        finite weight). A degenerate replica keeps ``fallback``'s log-weights (the
        prediction) when given, else its own."""
        lm = self.log_mass
        bad = ~np.isfinite(lm)
        any_bad = bool(bad.any())
        lw = self.log_weights - (np.where(bad, 0.0, lm) if any_bad else lm)[:, None]
        out_lm = np.zeros(self.K)
        if any_bad:
            src = fallback if fallback is not None else self
            lw[bad] = src.log_weights[bad]
            out_lm[bad] = np.asarray(src.log_mass)[bad]
        out = self._trusted(self.x, lw, self.history, log_mass=out_lm)
        if not any_bad:
            for key in ("weights", "ess"):  # identical for the normalised copy
                if key in self.__dict__:
                    out.__dict__[key] = self.__dict__[key]
        return out, bad

    def resample_rows(self, rngs: Sequence[np.random.Generator], scheme, num: int,
                      rows: np.ndarray) -> BatchedParticles:
        """Resample the replicas ``rows`` to ``num`` particles each, each with its own
        generator (``rngs[k]``); the others are kept (they must then have ``num``
        particles). Every new particle gets weight ``mass / num`` of its replica."""
        rows = np.asarray(rows, dtype=int)
        if not len(rows):
            return self
        w, lm = self.weights, self.log_mass
        idx = np.stack([scheme(rngs[k], w[k], num) for k in rows])
        r = rows[:, None]
        new_lw = np.repeat((lm[rows] - np.log(num))[:, None], num, axis=1)
        if num != self.num:  # a fused mixture: every replica back to ``num`` particles
            if len(rows) != self.K:
                raise ValueError("resampling to another particle count takes every replica")
            return self._trusted(self.x[r, idx], new_lw, tuple(h[r, idx] for h in self.history),
                                 log_mass=lm.copy())
        x, lw = self.x.copy(), self.log_weights.copy()
        x[rows], lw[rows] = self.x[r, idx], new_lw
        hist = tuple(_assign_rows(h, rows, h[r, idx]) for h in self.history)
        return self._trusted(x, lw, hist, log_mass=lm.copy())

    def select(self, indices: Sequence[int] | np.ndarray) -> BatchedParticles:
        """The replicas at ``indices``, in that order."""
        i = np.asarray(indices, dtype=int)
        lm = self.__dict__.get("log_mass")
        return self._trusted(self.x[i], self.log_weights[i], tuple(h[i] for h in self.history),
                             log_mass=None if lm is None else lm[i])

    def concat(self, other: BatchedParticles) -> BatchedParticles:
        """This batch followed by ``other``'s replicas."""
        if not self.K:
            return other
        if not other.K:
            return self
        a, b = self.__dict__.get("log_mass"), other.__dict__.get("log_mass")
        cat = np.concatenate
        return self._trusted(cat([self.x, other.x]), cat([self.log_weights, other.log_weights]),
                             tuple(cat([h, g]) for h, g in zip(self.history, other.history,
                                                               strict=True)),
                             log_mass=None if a is None or b is None else cat([a, b]))


def _assign_rows(a: np.ndarray, rows: np.ndarray, values: np.ndarray) -> np.ndarray:
    out = a.copy()
    out[rows] = values
    return out


class Replicated:
    """A batch of ``K`` beliefs of one single-graph type (``row_type``), one object per
    replica: the batched form of beliefs without an array layout of their own (a
    Gaussian of an exact Kalman filter, an inverse-Gamma noise belief). Make the class
    with :func:`batched_type`."""

    row_type: ClassVar[type | None] = None
    likelihood_reweights: ClassVar[bool] = False

    def __init__(self, items: Sequence[Any] = ()):
        self.items = list(items)

    @classmethod
    def stack(cls, rows: Sequence[Any]) -> Replicated:
        """The batch of ``rows``."""
        return cls(rows)

    def row(self, k: int) -> Any:
        """Replica ``k``'s belief."""
        return self.items[k]

    def rows(self) -> list[Any]:
        """Every replica's belief."""
        return list(self.items)

    @property
    def K(self) -> int:  # noqa: N802
        """Number of replicas."""
        return len(self.items)

    @property
    def dim(self) -> int:
        """Dimension of each replica's belief (0 with no replica)."""
        return self.items[0].dim if self.items else 0

    @property
    def log_mass(self) -> np.ndarray:
        """``(K,)``: each replica's ``log_mass``."""
        return np.array([r.log_mass for r in self.items], dtype=float)

    def _stacked(self, method: str, shape: tuple[int, ...]) -> np.ndarray:
        if not self.items:
            return np.zeros((0,) + shape)
        return np.stack([getattr(r, method)() for r in self.items])

    def mean(self) -> np.ndarray:
        """``(K, d)``: each replica's mean."""
        return self._stacked("mean", (self.dim,))

    def cov(self) -> np.ndarray:
        """``(K, d, d)``: each replica's covariance."""
        return self._stacked("cov", (self.dim, self.dim))

    def estimate(self) -> np.ndarray:
        """``(K, d)``: each replica's point estimate."""
        return self._stacked("estimate", (self.dim,))

    def select(self, indices: Sequence[int] | np.ndarray) -> Replicated:
        """The replicas at ``indices``."""
        return type(self)([self.items[int(i)] for i in indices])

    def concat(self, other: Replicated) -> Replicated:
        """This batch followed by ``other``'s replicas."""
        return type(self)(self.items + other.items)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(K={self.K})"


class _ArrayBatch:
    """A batch of ``K`` beliefs held as arrays with a leading replica axis, one per field
    of the replica's belief (``_fields``, in the order its constructor takes them):
    rows, stacking, selection and concatenation for all such batches."""

    row_type: ClassVar[type | None] = None
    likelihood_reweights: ClassVar[bool] = False
    _fields: ClassVar[tuple[str, ...]] = ()
    __slots__ = ()

    def _arrays(self) -> tuple[np.ndarray, ...]:
        return tuple(getattr(self, f) for f in self._fields)

    @classmethod
    def stack(cls, rows: Sequence[Any]):
        """The batch of the beliefs ``rows``."""
        if not rows:
            return cls(np.zeros((0, 0)), *(np.zeros((0, 0)) for _ in cls._fields[1:]))
        return cls(*(np.stack([getattr(r, f) for r in rows]) for f in cls._fields))

    def row(self, k: int) -> Any:
        """Replica ``k``'s belief."""
        return self.row_type(*(a[k].copy() for a in self._arrays()))

    def rows(self) -> list[Any]:
        """Every replica's belief."""
        return [self.row(k) for k in range(self.K)]

    @property
    def K(self) -> int:  # noqa: N802
        """Number of replicas."""
        return self._arrays()[0].shape[0]

    def select(self, indices: Sequence[int] | np.ndarray):
        """The replicas at ``indices``."""
        idx = np.asarray(indices, dtype=int)
        return type(self)(*(a[idx] for a in self._arrays()))

    def concat(self, other):
        """This batch followed by ``other``'s replicas."""
        if self.K == 0:
            return other
        if other.K == 0:
            return self
        return type(self)(*(np.concatenate([a, b]) for a, b in
                            zip(self._arrays(), other._arrays(), strict=True)))

    def __repr__(self) -> str:
        return f"{type(self).__name__}(K={self.K})"


class BatchedGaussian(_ArrayBatch):
    """``K`` Gaussian beliefs of one dimension ``d`` (the replicas of an exact Kalman
    filter's plate variable): means ``(K, d)`` and covariances ``(K, d, d)``, so that the
    Kalman rules of a plate (:mod:`pgm.inference.association`) move every replica with a
    few batched matrix products. Any single-graph rule for
    :class:`~pgm.core.expfam.Gaussian` still runs on it, once per replica (``row``,
    ``stack``).

    >>> from pgm.core.expfam import Gaussian
    >>> b = BatchedGaussian.stack([Gaussian(np.zeros(2), np.eye(2))] * 3)
    >>> b.K, b.dim, b.row(1).cov().shape
    (3, 2, (2, 2))
    """

    row_type: ClassVar[type | None] = Gaussian
    _fields = ("m", "P")
    __slots__ = ("m", "P")

    def __init__(self, mean: np.ndarray, cov: np.ndarray):
        mean = np.asarray(mean, dtype=float)
        cov = np.asarray(cov, dtype=float)
        if mean.ndim != 2 or cov.shape != mean.shape + mean.shape[1:]:
            raise ValueError(f"BatchedGaussian: means (K, d) and covariances (K, d, d), got "
                             f"{mean.shape} and {cov.shape}")
        #: the means ``(K, d)`` and covariances ``(K, d, d)``
        self.m = mean
        self.P = cov

    @classmethod
    def empty(cls, dim: int) -> BatchedGaussian:
        """No replica, dimension ``dim``."""
        return cls(np.zeros((0, dim)), np.zeros((0, dim, dim)))

    @classmethod
    def stack(cls, rows: Sequence[Any]) -> BatchedGaussian:
        """The batch of the Gaussians ``rows``."""
        if not rows:
            return cls(np.zeros((0, 0)), np.zeros((0, 0, 0)))
        return super().stack(rows)

    @property
    def dim(self) -> int:
        """Dimension of each replica's state."""
        return self.m.shape[1]

    @property
    def log_mass(self) -> np.ndarray:
        """``(K,)`` zeros: each replica's belief is a density."""
        return np.zeros(self.K)

    def mean(self) -> np.ndarray:
        """The ``(K, d)`` means."""
        return self.m

    def cov(self) -> np.ndarray:
        """The ``(K, d, d)`` covariances."""
        return self.P

    def estimate(self) -> np.ndarray:
        """The point estimates of the belief protocol: the ``(K, d)`` means."""
        return self.m


class BatchedInverseGamma(_ArrayBatch):
    """``K`` inverse-Gamma noise beliefs of ``d`` components (a plate's per-target noise
    for mean-field VB): shapes ``alpha`` and scales ``beta``, both ``(K, d)``. Forgetting
    and the plug-in variance ``β/α`` act on all replicas at once with the arithmetic of
    :class:`~pgm.core.expfam.InverseGamma`, element by element, so a replica holds what
    a single graph would.

    >>> b = BatchedInverseGamma.stack([InverseGamma.from_sigma([1.0, 2.0])] * 3)
    >>> b.K, b.row(2).r_hat().tolist()
    (3, [1.0, 4.0])
    """

    row_type: ClassVar[type | None] = InverseGamma
    _fields = ("alpha", "beta")
    __slots__ = ("alpha", "beta")

    def __init__(self, alpha: np.ndarray, beta: np.ndarray):
        alpha = np.asarray(alpha, dtype=float)
        beta = np.asarray(beta, dtype=float)
        if alpha.ndim != 2 or alpha.shape != beta.shape:
            raise ValueError(f"BatchedInverseGamma: alpha and beta (K, d), got {alpha.shape} "
                             f"and {beta.shape}")
        self.alpha = alpha
        self.beta = beta

    def r_hat(self) -> np.ndarray:
        """``β/α`` per replica and component, ``(K, d)``."""
        return self.beta / self.alpha

    @property
    def dim(self) -> int:
        """Components per replica."""
        return self.alpha.shape[1]

    @property
    def log_mass(self) -> np.ndarray:
        """``(K,)`` zeros: each replica's belief is a density."""
        return np.zeros(self.K)

    def mean(self) -> np.ndarray:
        """``E[σ²]`` per replica and component ``(K, d)`` (NaN where ``α ≤ 1``)."""
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(self.alpha > 1, self.beta / (self.alpha - 1), np.nan)

    def cov(self) -> np.ndarray:
        """``(K, d, d)``: each replica's :meth:`InverseGamma.cov`."""
        return np.stack([self.row(k).cov() for k in range(self.K)]) if self.K else \
            np.zeros((0,) + self.alpha.shape[1:] * 2)

    def estimate(self) -> np.ndarray:
        """The plug-in variances ``β/α`` ``(K, d)`` (:meth:`InverseGamma.estimate`)."""
        return self.r_hat()

    def forget(self, rho: float, alpha_min: float = 0.0) -> BatchedInverseGamma:
        """:meth:`InverseGamma.forget` of every replica."""
        a, b = rho * self.alpha, rho * self.beta
        scale = np.maximum(1.0, alpha_min / a)
        return BatchedInverseGamma(a * scale, b * scale)


_REPLICATED: dict[type, type] = {}
#: the batched form of each belief type that has one (row type -> batched class)
_BATCHED: dict[type, type] = {}


def register_batched(cls: type) -> type:
    """Class decorator: ``cls`` is the batched form of ``cls.row_type`` (what a plate keeps
    for a variable whose replicas hold that belief). A belief type without one is kept
    :class:`Replicated`, one object per replica."""
    row_type = getattr(cls, "row_type", None)
    if not isinstance(row_type, type):
        raise ValueError(f"{cls.__name__} names no row_type (the belief of one replica)")
    _BATCHED[row_type] = cls
    return cls


for _cls in (BatchedParticles, BatchedGaussian, BatchedInverseGamma):
    register_batched(_cls)


def batched_type(row_type: type) -> type:
    """The batched belief class for ``row_type``: its registered form
    (:func:`register_batched`: :class:`BatchedParticles` for :class:`~pgm.Particles`,
    :class:`BatchedGaussian` for :class:`~pgm.core.expfam.Gaussian`,
    :class:`BatchedInverseGamma`), else ``Replicated[row_type]`` (a subclass of
    ``Particles`` has no batched form unless it is given one: the engine refuses it in a
    plate)."""
    cls = _BATCHED.get(row_type)
    if cls is not None:
        return cls
    cls = _REPLICATED.get(row_type)
    if cls is None:
        cls = type(f"Replicated[{row_type.__name__}]", (Replicated,),
                   {"row_type": row_type,
                    "__doc__": f"A batch of {row_type.__name__} beliefs, one per replica."})
        _REPLICATED[row_type] = cls
    return cls
