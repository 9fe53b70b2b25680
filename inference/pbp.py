r"""Particle belief propagation: coupling messages and their fusion.

Two fusion rules, chosen by the engine option ``fusion``:

``"mixture"`` (Zhang & Kang [#zhang2015], whose equation numbers are cited; the default)
    A message ``β → α`` is ``β``'s predicted particles pushed through the coupling
    (``factor.propagate``), each carrying ``β``'s own unnormalised likelihood
    (``message_weight="source"``, eq. 26) or ``α``'s likelihood at the message particle
    (``"target"``, eq. 20). ``α``'s posterior is the *mixture* of its own weighted
    particles and all incoming message particles, with all weights on one common
    scale (prior weight × unnormalised likelihood) normalised jointly (eqs. 17, 22–23,
    27–30; eq. 28 writes normalised weights for ``α``'s own particles and eq. 26
    unnormalised ones for messages, which one common scale reconciles); the estimate is
    the jointly weighted mean and the resample stage draws ``N_α`` particles from the
    union. With equal likelihoods a node keeps only
    ``1 / (1 + degree)`` of its own mass — a structural bias, exposed rather than hidden:
    ``record.info[α]["own_mass"]`` reports it every frame.

``"product"`` (nonparametric BP [#sudderth2003]; particle BP [#ihler2009])
    ``α``'s support stays its own particles, weighted by

    .. math::
        w_\alpha^{(i)} \propto \pi_\alpha^{(i)}\, p(z_\alpha \mid x_\alpha^{(i)})
        \prod_\beta \sum_j \bar\pi_{\beta\setminus\alpha}^{(j)}\,
        \psi_{\alpha\beta}\big(x_\alpha^{(i)}, x_\beta^{(j)}\big)

    with ``π̄_{β∖α}`` the cavity weights of ``β`` (its prior weight × likelihood ×
    every incoming message except ``α``'s). Each message is an ``(N_α, M)`` log-matrix
    reduced by logsumexp, in row chunks when large. Trees are exact after a
    leaves-to-root and a root-to-leaves sweep; loopy graphs use flooding rounds
    (:func:`pgm.inference.engine.message_order`).

Settings read from ``ctx.settings`` (:class:`~pgm.inference.settings.EngineSettings`):
``fusion``, ``message_weight`` (``"source"`` | ``"target"``), ``message_particles``
(``M``; default ``N_β``: one message particle per predicted particle).

References
----------
.. [#zhang2015] M.-J. Zhang and B.-S. Kang, "Particle filter tracking method using graphical
   model", Journal of Computers (Computer Society of the R.O.C.), 2015 (accepted March 2015;
   venue inferred from the article's layout; volume, pages and DOI not confirmed).
.. [#sudderth2003] E. B. Sudderth, A. T. Ihler, W. T. Freeman and A. S. Willsky,
   "Nonparametric belief propagation", Proc. CVPR 2003, vol. 1, 605–612.
   doi:10.1109/CVPR.2003.1211409
.. [#ihler2009] A. Ihler and D. McAllester, "Particle belief propagation", Proc. AISTATS 2009,
   PMLR 5, 256–263 (no DOI).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pgm.core.beliefs import Particles
from pgm.core.numerics import log_normalize, logsumexp
from pgm.factors import CouplingFactor

from .context import RuleContext
from .info import VariableInfo
from .rules import RuleTable

__all__ = ["MixtureMessage", "ProductMessage", "coupling_message", "fuse"]

#: the rules of this family (:func:`pgm.inference.default_rules` gathers every family's)
RULES = RuleTable()

_CHUNK_ELEMENTS = 1 << 21  # rows of the (N, M, d) difference tensor per chunk


@dataclass(frozen=True)
class MixtureMessage:
    """Message particles ``x`` ``(M, d)`` with log-weights on the common scale, and histories."""

    x: np.ndarray
    log_weights: np.ndarray
    history: tuple[np.ndarray, ...]


@dataclass(frozen=True)
class ProductMessage:
    """``log m(x_dst^(i))`` at the target's particles ``(N_dst,)``; ``x`` are the mapped
    source particles ``(M, d)`` (for drawing) with normalised ``log_weights``."""

    log_values: np.ndarray
    x: np.ndarray
    log_weights: np.ndarray


def _evidence(ctx: RuleContext, variable: str) -> tuple[np.ndarray, np.ndarray]:
    b = ctx.beliefs[variable]
    return ctx.evidence.get(variable, (b.log_weights, np.zeros(b.num)))


def _subsample(ctx: RuleContext, log_weights: np.ndarray) -> tuple[np.ndarray | None, np.ndarray]:
    """Indices of ``M`` message particles (``None``: all of them) and their prior
    log-weights (mass 1)."""
    n = log_weights.size
    m = ctx.settings.message_particles or n
    if m == n:
        return None, log_weights  # all particles; prior weights are the normalised posterior
    idx = ctx.resampler(ctx.rng, np.exp(log_normalize(log_weights)), m)
    return idx, np.full(m, -np.log(m))


@RULES.register(CouplingFactor, Particles)
def coupling_message(ctx: RuleContext, factor, frame, src: str, dst: str) -> dict | None:
    """Compute the message ``src → dst`` of a coupling factor (mixture or product)."""
    fusion = ctx.settings.fusion
    b_src: Particles = ctx.beliefs[src]
    prior_lw, log_lik = _evidence(ctx, src)
    if fusion == "mixture":
        idx, lw_prior = _subsample(ctx, prior_lw)
        pick = (lambda a: a) if idx is None else (lambda a: a[idx])  # noqa: E731
        x_msg = np.asarray(factor.propagate(ctx.rng, pick(b_src.x), src), dtype=float)
        n_hist = len(ctx.beliefs[dst].history)
        hist = [np.asarray(factor.map(pick(h), src), dtype=float)
                for h in b_src.history[:n_hist]]
        hist += [x_msg.copy() for _ in range(n_hist - len(hist))]
        mode = ctx.settings.message_weight
        if mode == "source":
            lw = lw_prior + pick(log_lik)
        elif mode == "target":
            lw = lw_prior + ctx.log_likelihood(dst, x_msg, frame)
        else:
            raise ValueError(f"message_weight must be 'source' or 'target', got {mode!r}")
        ctx.messages[(src, dst)] = MixtureMessage(x_msg, lw, tuple(hist))
        return None
    if fusion != "product":
        raise ValueError(f"unknown fusion {fusion!r}")
    cavity = prior_lw + log_lik
    for (a, b), msg in ctx.messages.items():
        if b == src and a != dst:
            cavity = cavity + msg.log_values
    idx, log_pi = _subsample(ctx, log_normalize(cavity))
    x_src = b_src.x if idx is None else b_src.x[idx]
    x_dst = ctx.beliefs[dst].x
    n, m = x_dst.shape[0], x_src.shape[0]
    rows = max(1, _CHUNK_ELEMENTS // max(1, m * x_dst.shape[1]))
    log_values = np.empty(n)
    dst_first = factor.variables[0] == dst
    for start in range(0, n, rows):
        xd = x_dst[start:start + rows, None, :]
        lp = factor.log_prob(xd, x_src[None]) if dst_first else factor.log_prob(x_src[None], xd)
        log_values[start:start + rows] = logsumexp(lp + log_pi[None, :], axis=1)
    ctx.messages[(src, dst)] = ProductMessage(log_values, factor.map(x_src, src), log_pi)
    return None


@RULES.register("fuse", Particles)
def fuse(ctx: RuleContext, variable: str, frame) -> VariableInfo | None:
    """Combine ``variable``'s own weighted particles with its incoming messages."""
    b: Particles = ctx.beliefs[variable]
    prior_lw, log_lik = _evidence(ctx, variable)
    incoming = [msg for (_, dst), msg in ctx.messages.items() if dst == variable]
    if ctx.settings.fusion == "product":
        lw = prior_lw + log_lik
        for msg in incoming:
            lw = lw + msg.log_values
        ctx.beliefs[variable] = b._trusted(b.x, log_normalize(lw), b.history, log_mass=0.0)
        return None
    lw = np.concatenate([prior_lw + log_lik] + [m.log_weights for m in incoming])
    lw = log_normalize(lw)
    x = np.concatenate([b.x] + [m.x for m in incoming])
    hist = tuple(np.concatenate([h] + [m.history[k] for m in incoming])
                 for k, h in enumerate(b.history))
    ctx.beliefs[variable] = b._trusted(x, lw, hist, log_mass=0.0)
    return VariableInfo(own_mass=float(np.exp(lw[:b.num]).sum()))
