"""Coupling factors: two variables of the same frame (parts of one object).

A coupling factor ``ψ(x_a, x_b)`` is used by particle belief propagation in two ways:

* ``propagate(rng, x_src, src)`` pushes message particles from one end to the other
  (the ``"mixture"`` fusion of Zhang & Kang [#zhang2015]: message particles join the
  target's own);
* ``log_prob(x_a, x_b)`` evaluates the potential, broadcasting over leading axes, so
  that ``log_prob(x_a[:, None], x_b[None, :])`` is the ``(N_a, N_b)`` log-matrix of the
  ``"product"`` fusion (particle BP, Ihler & McAllester [#ihler2009]).

``map(x_src, src)`` is the deterministic part of ``propagate``; the engine uses it to
carry a message particle's AR(2) history (the source particle's previous state pushed
through the same map). To write your own coupling, subclass :class:`~pgm.CouplingFactor`
and implement ``map`` and ``log_prob`` (and ``propagate`` if it adds noise);
``docs/tutorials/03_your_own_model.py`` shows one.

References
----------
.. [#zhang2015] M.-J. Zhang and B.-S. Kang, "Particle filter tracking method using graphical
   model", Journal of Computers (Computer Society of the R.O.C.), 2015 (accepted March 2015;
   venue inferred from the article's layout; volume, pages and DOI not confirmed).
.. [#ihler2009] A. Ihler and D. McAllester, "Particle belief propagation", Proc. AISTATS 2009,
   PMLR 5, 256–263 (no DOI).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.learned import LearnedState
from pgm.core.numerics import check_finite_param
from pgm.core.variable import Variable
from pgm.factors.kinds import CouplingFactor

__all__ = ["AffineCoupling", "RelativeBoxCoupling"]


def _vec(value, dim: int, what: str, *, nonneg: bool = True) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(dim, float(arr))
    check_finite_param(what, arr, nonneg=nonneg)
    if arr.shape != (dim,):
        raise ValueError(f"{what} must have {dim} entries, got shape {arr.shape}")
    return arr


@dataclass
class OffsetState(LearnedState):
    """What an adaptive :class:`AffineCoupling` learns: its offset (the declared one
    until it adapts)."""

    offset: np.ndarray | None = None


class AffineCoupling(CouplingFactor):
    r"""``x_a = A x_b + b + ε`` between two variables of equal dimension (eqs. (21), (25) of
    [#zhang2015]).

    .. math::
        \psi(x_a, x_b) = \mathcal N\big(x_a;\ A x_b + b,\ \mathrm{diag}(\sigma^2)\big)

    Parameters
    ----------
    a, b_var : str
        The two variables (``x_a`` is the first).
    offset : array_like (d,)
        ``b`` — for parts, the offset ``X_a − X_b`` of the initial boxes.
    A : array_like (d, d), optional
        Invertible linear map (identity by default).
    std : array_like (d,) or float, optional
        ``σ`` of the potential, used by ``log_prob`` (product fusion needs it > 0).
    jitter_std : array_like (d,) or float
        Standard deviation of the noise added by ``propagate`` (mixture fusion): none by
        default, position only when used (jitter on size brings back size drift).
    forgetting : float, optional
        Offset adaptation (off when ``None``): after a frame in which both parts score
        at least ``adapt_min_log_lik`` at their estimates,
        ``b ← forgetting · b + (1 − forgetting) · (x̂_a − A x̂_b)``.
    adapt_min_log_lik : float
        Log-likelihood threshold for "confidently visible".
    """

    State = OffsetState

    def __init__(self, a: str, b_var: str, *, offset, A=None, std=None, jitter_std=0.0,
                 forgetting: float | None = None, adapt_min_log_lik: float = -np.inf,
                 name: str | None = None):
        super().__init__(a, b_var, name=name)
        self.offset = np.atleast_1d(np.asarray(offset, dtype=float))
        d = self.offset.size
        check_finite_param(f"{self.name}.offset", self.offset)
        self.A = np.eye(d) if A is None else np.atleast_2d(np.asarray(A, dtype=float))
        check_finite_param(f"{self.name}.A", self.A)
        if self.A.shape != (d, d):
            raise ValueError(f"factor {self.name!r}: A must be ({d}, {d}), got {self.A.shape}")
        if abs(np.linalg.det(self.A)) < 1e-12:
            raise ValueError(f"factor {self.name!r}: A must be invertible")
        self._A_inv = np.linalg.inv(self.A)
        self._identity = bool(np.array_equal(self.A, np.eye(d)))
        self.std = None if std is None else _vec(std, d, f"{self.name}.std")
        self.jitter_std = _vec(jitter_std, d, f"{self.name}.jitter_std")
        self._jitter = bool(np.any(self.jitter_std > 0))
        if forgetting is not None:
            forgetting = float(check_finite_param(f"{self.name}.forgetting", forgetting))
            if not 0.0 < forgetting <= 1.0:
                raise ValueError(f"factor {self.name!r}: forgetting must be in (0, 1]")
        self.forgetting = forgetting
        self.adapt_min_log_lik = float(adapt_min_log_lik)

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"offset": self.offset}
        if not np.array_equal(self.A, np.eye(self.offset.size)):
            p["A"] = self.A
        if self.std is not None:
            p["std"] = self.std
        if np.any(self.jitter_std > 0):
            p["jitter_std"] = self.jitter_std
        if self.forgetting is not None:
            p["forgetting"] = self.forgetting
            p["adapt_min_log_lik"] = self.adapt_min_log_lik
        return p

    def check(self, variables: dict[str, Variable]) -> None:
        super().check(variables)
        for v in self.variables:
            self._check_dim(variables, v, self.offset.size, "the offset")

    def map(self, x_src: np.ndarray, src: str) -> np.ndarray:
        """Deterministic image of ``x_src`` (from variable ``src``) at the other end."""
        if src == self.variables[1]:
            return x_src + self.offset if self._identity else x_src @ self.A.T + self.offset
        if src == self.variables[0]:
            return x_src - self.offset if self._identity else (x_src - self.offset) @ self._A_inv.T
        raise ValueError(f"factor {self.name!r} does not link {src!r}")

    def propagate(self, rng: np.random.Generator, x_src: np.ndarray, src: str) -> np.ndarray:
        """Message particles: ``map`` plus jitter ``N(0, diag(jitter_std²))``."""
        out = self.map(x_src, src)
        if self._jitter:
            out = out + rng.standard_normal(out.shape) * self.jitter_std
        return out

    def log_prob(self, x_a: np.ndarray, x_b: np.ndarray) -> np.ndarray:
        """``log ψ(x_a, x_b)``, broadcasting over leading axes."""
        if self.std is None or np.any(self.std <= 0):
            raise ValueError(f"factor {self.name!r}: log_prob needs std > 0 on every component "
                             f"(product fusion requires a proper coupling potential)")
        r = (x_a - (x_b @ self.A.T + self.offset)) / self.std
        return (-0.5 * np.sum(r * r, axis=-1) - np.sum(np.log(self.std))
                - 0.5 * self.offset.size * np.log(2 * np.pi))

    @property
    def learns(self) -> bool:
        return self.forgetting is not None

    def update(self, estimates: dict[str, np.ndarray], scores: dict[str, float],
               frame=None) -> None:
        """Adapt the offset towards the current estimates (when configured and confident)."""
        if self.forgetting is None:
            return
        a, b = self.variables
        if min(scores.get(a, -np.inf), scores.get(b, -np.inf)) < self.adapt_min_log_lik:
            return
        current = np.asarray(estimates[a]) - np.asarray(estimates[b]) @ self.A.T
        self.offset = self.forgetting * self.offset + (1.0 - self.forgetting) * current


class RelativeBoxCoupling(CouplingFactor):
    r"""Relative geometry of two boxes ``(cx, cy, w, h, ...)`` (an option beside the fixed
    offset of [#zhang2015]).

    ``a``'s centre is ``b``'s centre plus ``r ⊙ (w_b, h_b)`` and ``a``'s size is
    ``s ⊙ (w_b, h_b)``; for models that carry an observable scale. With a fixed box
    size it coincides with :class:`AffineCoupling`.

    Parameters
    ----------
    rel_offset : (2,)
        ``r``: centre offset in units of ``b``'s size.
    rel_size : (2,)
        ``s``: size ratio ``a / b``.
    std : (4,), optional
        ``σ`` of the potential on ``(cx, cy, w, h)`` (product fusion).
    jitter_std : (4,) or float
        Noise added by ``propagate``.
    """

    def __init__(self, a: str, b_var: str, *, rel_offset, rel_size=(1.0, 1.0), std=None,
                 jitter_std=0.0, name: str | None = None):
        super().__init__(a, b_var, name=name)
        self.rel_offset = _vec(rel_offset, 2, f"{self.name}.rel_offset", nonneg=False)
        self.rel_size = _vec(rel_size, 2, f"{self.name}.rel_size")
        if np.any(self.rel_size <= 0):
            raise ValueError(f"factor {self.name!r}: rel_size must be positive")
        self.std = None if std is None else _vec(std, 4, f"{self.name}.std")
        self.jitter_std = _vec(jitter_std, 4, f"{self.name}.jitter_std")

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"rel_offset": self.rel_offset, "rel_size": self.rel_size}
        if self.std is not None:
            p["std"] = self.std
        if np.any(self.jitter_std > 0):
            p["jitter_std"] = self.jitter_std
        return p

    def check(self, variables: dict[str, Variable]) -> None:
        super().check(variables)
        for v in self.variables:
            if variables[v].dim < 4:
                raise ValueError(f"factor {self.name!r}: variable {v!r} must hold a box "
                                 f"(cx, cy, w, h, ...)")

    def map(self, x_src: np.ndarray, src: str) -> np.ndarray:
        out = np.array(x_src, dtype=float, copy=True)
        if src == self.variables[1]:  # b -> a
            size_b = x_src[..., 2:4]
            out[..., 0:2] = x_src[..., 0:2] + self.rel_offset * size_b
            out[..., 2:4] = self.rel_size * size_b
        elif src == self.variables[0]:  # a -> b
            size_b = x_src[..., 2:4] / self.rel_size
            out[..., 0:2] = x_src[..., 0:2] - self.rel_offset * size_b
            out[..., 2:4] = size_b
        else:
            raise ValueError(f"factor {self.name!r} does not link {src!r}")
        return out

    def propagate(self, rng: np.random.Generator, x_src: np.ndarray, src: str) -> np.ndarray:
        out = self.map(x_src, src)
        if np.any(self.jitter_std > 0):
            out[..., :4] += rng.standard_normal(out[..., :4].shape) * self.jitter_std
        return out

    def log_prob(self, x_a: np.ndarray, x_b: np.ndarray) -> np.ndarray:
        if self.std is None or np.any(self.std <= 0):
            raise ValueError(f"factor {self.name!r}: log_prob needs std > 0 on every component")
        pred = self.map(np.broadcast_to(x_b, np.broadcast_shapes(x_a.shape, x_b.shape)),
                        self.variables[1])
        r = (x_a[..., :4] - pred[..., :4]) / self.std
        return -0.5 * np.sum(r * r, axis=-1) - np.sum(np.log(self.std)) - 2.0 * np.log(2 * np.pi)
