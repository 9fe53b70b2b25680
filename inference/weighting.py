"""The weight stage of the engine: likelihood factors grouped by ``batch_key`` and scored
(one batched pass where their rules allow it, :data:`~pgm.inference.rules.GROUP_SCORING`),
each rule's increment checked against the weight-stage contract (:mod:`pgm.inference.
engine`), applied to the beliefs, and kept as the variables' local evidence. Each function
takes the :class:`~pgm.inference.engine.Engine` it serves (typed ``Any`` here: the engine
imports this module, not the other way).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgm.core.errors import DegenerateWeightsError, RuleContractError
from pgm.core.factor import Factor
from pgm.core.frame import FrameContext

from .context import RuleContext
from .info import Info
from .record import StepRecord
from .rules import GROUP_SCORING, Rule, likelihood_reweights
from .state import ProposalState

__all__ = ["stage_weight", "weight_groups", "score_group", "likelihood_increment",
           "prior_log_mass", "check_log_likelihood"]


def weight_groups(engine: Any, items) -> list[tuple[list[Factor], list[Rule], bool]]:
    """Likelihood factors grouped by ``batch_key``, each group with its factors' rules
    and whether it is scored in one batched pass (resolved once, then cached)."""
    key = tuple(items)
    groups = engine._groups_cache.get(key)
    if groups is None:
        by_key: dict[Any, list[str]] = {}
        groups = []
        for name in items:
            f = engine.graph.factors[name]
            bk = getattr(f, "batch_key", None)
            if bk is None:
                groups.append([name])
                continue
            bk = (type(f), bk)
            if bk not in by_key:
                by_key[bk] = []
                groups.append(by_key[bk])
            by_key[bk].append(name)
        resolved = []
        for names in groups:
            fs = [engine.graph.factors[n] for n in names]
            rules = [engine.rule_for(f) for f in fs]
            # in one pass: several factors of one graph, or a plate's replicas' copies
            kind = engine.runtime.group_scoring
            batched = ((len(fs) > 1 or kind == "replicas")
                       and all(GROUP_SCORING.get(r) == kind for r in rules))
            resolved.append((fs, rules, batched))
        groups = engine._groups_cache[key] = resolved
    return groups

def stage_weight(engine: Any, ctx: RuleContext, items, frame, record: StepRecord) -> None:
    """Apply the likelihood factors to the beliefs of ``ctx`` (the weight-stage contract:
    module docstring)."""
    before: dict[str, Any] = {}  # reweighted beliefs as they entered the stage
    log_lik: dict[str, np.ndarray] = {}
    applied: dict[str, list[str]] = {}  # the likelihoods each belief was reweighted by
    for fs, rules, batched in weight_groups(engine, items):
        vs = [f.variables[0] for f in fs]
        if batched:
            lls = score_group(engine, ctx, fs, frame)
        else:
            lls = [likelihood_increment(ctx, f, r, frame, record)
                   for f, r in zip(fs, rules, strict=True)]
        for f, v, ll in zip(fs, vs, lls, strict=True):
            if ll is None:  # a belief the rule updated itself
                continue
            b = ctx.beliefs[v]
            ll = check_log_likelihood(f, ll, b.log_weights.shape)
            before.setdefault(v, b)
            applied.setdefault(v, []).append(f.name)
            log_lik[v] = log_lik[v] + ll if v in log_lik else ll
            ctx.beliefs[v] = b.reweight(ll)
    for v, b0 in before.items():
        b = ctx.beliefs[v]
        ctx.evidence[v] = (b0.log_weights, log_lik[v])
        try:
            record.log_evidence[v] = b.log_mass - prior_log_mass(engine, ctx, v, b0)
            record.ess[v] = b.ess
            # (a replica of a plate no particle of which explains the frame keeps its
            # prediction)
            ctx.beliefs[v], bad = engine.runtime.normalize(ctx, v, b, b0)
        except DegenerateWeightsError as exc:  # named: which variable, frame, likelihoods
            raise DegenerateWeightsError(f"{exc}: variable {v!r} at frame {frame.index} after "
                                         f"the likelihoods {applied[v]}") from None
        if bad is not None and bad.any():
            ctx.evidence[v] = (b0.log_weights, np.where(bad[:, None], 0.0, log_lik[v]))
            record.variable_info(v).degenerate = np.flatnonzero(bad)

def prior_log_mass(engine: Any, ctx: RuleContext, variable: str, b0) -> Any:
    """The mass the frame's evidence is measured against: the belief's as the weight
    stage found it, or, after a proposal's weight correction, the mass before it."""
    if not engine._proposals:
        return b0.log_mass
    held = [None if (s := slot.find(variable, ProposalState)) is None else s.take()
            for slot in engine.runtime.state_slots(ctx)]
    if any(h is None for h in held):
        return b0.log_mass
    return held[0] if np.ndim(b0.log_mass) == 0 else np.array(held, dtype=float)

def score_group(engine: Any, ctx: RuleContext, fs: list[Factor], frame: FrameContext
                ) -> list[np.ndarray]:
    """Log-likelihoods of a group of factors scored in one batched pass."""
    return engine.runtime.score_group(ctx, fs, frame)

def likelihood_increment(ctx: RuleContext, factor: Factor, rule: Rule, frame: FrameContext,
                         record: StepRecord) -> np.ndarray | None:
    """Call one likelihood rule; its increment, or None where it updated the belief."""
    v = factor.variables[0]
    b = ctx.beliefs[v]
    out = rule(ctx, factor, frame)
    if not likelihood_reweights(type(b)):
        if isinstance(out, (dict, Info)) and out:  # its diagnostics (pgm.inference.info)
            record.info[factor.name] = out
        return None
    if ctx.beliefs[v] is not b:
        raise RuleContractError(
            f"likelihood rule {getattr(rule, '__qualname__', rule)!r} for factor "
            f"{factor.name!r} replaced the belief of {v!r}: on {type(b).__name__} a "
            f"likelihood rule returns its log-likelihood increment (N,) and never moves, "
            f"reorders or resamples particles")
    if not isinstance(out, np.ndarray):
        raise RuleContractError(
            f"likelihood rule {getattr(rule, '__qualname__', rule)!r} for factor "
            f"{factor.name!r} returned {type(out).__name__}, not its log-likelihood "
            f"increment (an array of shape {b.log_weights.shape})")
    return out


def check_log_likelihood(factor, ll, shape: tuple[int, ...]) -> np.ndarray:
    """A rule's log-likelihood increment as an array of ``shape`` (NaN read as -inf)."""
    ll = np.asarray(ll, dtype=float)
    if ll.shape != shape:
        raise ValueError(f"factor {factor.name!r}: log_likelihood returned shape {ll.shape}, "
                         f"expected {shape}")
    if np.isnan(ll).any():  # NaN evidence is no evidence: -inf, as Particles.reweight does
        ll = np.where(np.isnan(ll), -np.inf, ll)
    return ll
