r"""Factors for plate models (one sub-graph per target): detections and mutual exclusion.

* :class:`DetectionLikelihood` — a target's box scored against *all* the frame's
  detections without deciding which one is its own (the association-free likelihood of
  probabilistic data association):

  .. math::

      p(Z_t \mid x) \propto (1 - p_D) + \frac{p_D}{\lambda} \sum_j
      \mathcal{N}\big(r_j(x); 0, I\big)

  with ``r_j`` the residual of detection ``j`` in units of the box's own height
  (centre) and in log-size — scale-aware, so one setting serves a person near the
  camera and one far away. ``p_D`` and the clutter density ``λ`` enter as one ratio,
  :attr:`strength` ``= p_D / ((1 - p_D) λ)``. A frame with no detection is no
  evidence (zero log-likelihood). The factor holds no per-target state, so a plate
  engine scores every replica's particles in one call.
* :class:`MutualExclusion` — kind ``"interaction"``: the pairwise Markov-random-field
  potential ``ψ(x_k, x_j) = exp(−κ · IoU(x_k, x_j))`` between the replicas of a plate
  (Khan, Balch & Dellaert [#khan2005] use such a potential inside MCMC), read in the
  mean-field way: each replica's particles are weighted against the *other* replicas'
  current estimates, ``exp(−κ · max_{j≠k} IoU(x_k^{(i)}, x̂_j))``, so that two
  replicas do not coalesce on one person.

References
----------
.. [#khan2005] Z. Khan, T. Balch and F. Dellaert, "MCMC-based particle filtering for
   tracking a variable number of interacting targets", IEEE Trans. Pattern Analysis and
   Machine Intelligence 27(11), 1805–1819, 2005. doi:10.1109/TPAMI.2005.223
"""

from __future__ import annotations

from abc import abstractmethod
from typing import Any

import numpy as np

from pgm.core.boxes import box_columns, cxcywh_to_xywh, iou_xywh
from pgm.core.factor import Factor
from pgm.core.frame import FrameContext
from pgm.core.numerics import check_finite_param
from pgm.core.variable import Variable

from .kinds import LikelihoodFactor

__all__ = ["InteractionFactor", "MutualExclusion", "DetectionLikelihood"]

def _box_columns(factor: Factor, variables: dict[str, Variable], var: str) -> list[int]:
    """Columns of ``cx, cy, w, h`` in ``var``; a ``ValueError`` naming ``factor`` if the
    variable is not a box."""
    return box_columns(variables[var].labels, f"factor {factor.name!r}: variable {var!r}")


class InteractionFactor(Factor):
    """A factor between the replicas of a plate (kind ``"interaction"``).

    Subclasses implement :meth:`log_potential`; the engine applies it at its
    ``interaction`` stage, after the likelihoods, to all replicas at once.
    """

    kind = "interaction"
    abstract = True

    @abstractmethod
    def log_potential(self, x: np.ndarray, estimates: np.ndarray,
                      ctx: FrameContext) -> np.ndarray:
        """Log-weight increment ``(K, N)`` of every replica's particles ``x`` ``(K, N, d)``
        given every replica's current estimate ``estimates`` ``(K, d)``."""


class MutualExclusion(InteractionFactor):
    """``exp(−strength · max_{j≠k} IoU(particle of k, estimate of j))`` (module docstring).

    Parameters
    ----------
    variable : str
        The plate's box variable (labels ``cx, cy, w, h``).
    strength : float
        ``κ`` (default 10: a particle overlapping another target by half loses
        ``e^{-5}`` of its weight).
    """

    def __init__(self, variable: str, *, strength: float = 10.0, name: str | None = None):
        super().__init__(variable, name=name)
        self.strength = check_finite_param("strength", float(strength), nonneg=True)

    def params(self) -> dict[str, Any]:
        return {"strength": self.strength}

    def check(self, variables: dict[str, Variable]) -> None:
        self._cols: list[int] = _box_columns(self, variables, self.variables[0])

    def overlap(self, x: np.ndarray, estimates: np.ndarray) -> np.ndarray:
        """``max_{j≠k} IoU`` of each particle of replica ``k`` with the other estimates,
        ``(K, N)``."""
        cols = getattr(self, "_cols", [0, 1, 2, 3])
        k = x.shape[0]
        a = cxcywh_to_xywh(x[..., cols])  # (K, N, 4)
        b = cxcywh_to_xywh(np.asarray(estimates, dtype=float)[:, cols])  # (K, 4)
        iou = iou_xywh(a[:, :, None, :], b[None, None, :, :])  # (K, N, K)
        iou[np.arange(k), :, np.arange(k)] = 0.0  # a replica does not exclude itself
        return iou.max(axis=2) if k else np.zeros(x.shape[:2])

    def log_potential(self, x, estimates, ctx):
        return -self.strength * self.overlap(x, estimates)


class DetectionLikelihood(LikelihoodFactor):
    """Association-free likelihood of a box given all the frame's detections (module
    docstring).

    Parameters
    ----------
    variable : str
        A box variable (labels ``cx, cy, w, h``).
    pos_std : float
        Std of a detection's centre around the box, in box heights (0.1).
    size_std : float
        Std of a detection's log width and log height around the box's (0.15).
    strength : float
        ``p_D / ((1 − p_D) λ)`` (default 20).
    min_score : float
        Detections scoring below it are ignored (``-inf``, the default: none).
    extent : (x0, y0, x1, y1)
        Where the variable's box lies inside the detected object's box, in fractions of
        it (default ``(0, 0, 1, 1)``: the whole object; ``(0, 0, 1, 0.5)``: its upper
        half, for a part of a part graph). The object box the particle implies is
        compared with the detections.
    """

    def __init__(self, variable: str, *, pos_std: float = 0.1, size_std: float = 0.15,
                 strength: float = 20.0, min_score: float | None = None,
                 extent=(0.0, 0.0, 1.0, 1.0), name: str | None = None):
        super().__init__(variable, name=name)
        self.extent = np.asarray(extent, dtype=float).reshape(-1)
        check_finite_param("extent", self.extent)
        if self.extent.shape != (4,) or not (self.extent[2] > self.extent[0]
                                             and self.extent[3] > self.extent[1]):
            raise ValueError(f"factor {self.name!r}: extent must be (x0, y0, x1, y1) with "
                             f"x1 > x0 and y1 > y0, got {extent!r}")
        self.pos_std = check_finite_param("pos_std", float(pos_std), positive=True)
        self.size_std = check_finite_param("size_std", float(size_std), positive=True)
        self.strength = check_finite_param("strength", float(strength), nonneg=True)
        self.min_score = None if min_score is None else float(min_score)

    def params(self) -> dict[str, Any]:
        return {"pos_std": self.pos_std, "size_std": self.size_std,
                "strength": self.strength, "min_score": self.min_score,
                "extent": self.extent.tolist()}

    def check(self, variables: dict[str, Variable]) -> None:
        self._cols: list[int] = _box_columns(self, variables, self.variables[0])

    def object_boxes(self, box: np.ndarray) -> np.ndarray:
        """The object boxes ``(N, 4)`` (cx, cy, w, h) that part boxes ``box`` imply."""
        x0, y0, x1, y1 = self.extent
        if (x0, y0, x1, y1) == (0.0, 0.0, 1.0, 1.0):
            return box
        w = box[:, 2] / (x1 - x0)
        h = box[:, 3] / (y1 - y0)
        left = box[:, 0] - box[:, 2] / 2 - x0 * w
        top = box[:, 1] - box[:, 3] / 2 - y0 * h
        return np.stack([left + w / 2, top + h / 2, w, h], axis=1)

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        dets = ctx.detections
        n = x.shape[0]
        if dets is None or len(dets) == 0:
            return np.zeros(n)
        d = np.asarray(dets.boxes, dtype=float)
        if self.min_score is not None:
            d = d[np.asarray(dets.scores) >= self.min_score]
            if not len(d):
                return np.zeros(n)
        cols = getattr(self, "_cols", [0, 1, 2, 3])
        box = self.object_boxes(x[:, cols])
        h = np.maximum(box[:, 3:4], 1e-6)
        dcx = (d[None, :, 0] + d[None, :, 2] / 2 - box[:, 0:1]) / h
        dcy = (d[None, :, 1] + d[None, :, 3] / 2 - box[:, 1:2]) / h
        lw = np.log(np.maximum(box[:, 2:3], 1e-6))
        lh = np.log(h)
        dw = np.log(d[None, :, 2]) - lw
        dh = np.log(d[None, :, 3]) - lh
        r2 = (dcx ** 2 + dcy ** 2) / self.pos_std ** 2 + (dw ** 2 + dh ** 2) / self.size_std ** 2
        m = np.exp(-0.5 * r2).sum(axis=1)
        return np.log1p(self.strength * m)
