"""The rules of particle beliefs (sequential Monte Carlo): prior, predict (with a
proposal factor's mixture and its importance weights), weight, resample and estimate on
:class:`~pgm.Particles`, in this family's table :data:`RULES`
(gathered by :func:`pgm.inference.default_rules`).
"""

from __future__ import annotations

import numpy as np

from pgm.core.beliefs import Particles
from pgm.core.motion import warp_states
from pgm.core.numerics import check_finite_param
from pgm.factors import LikelihoodFactor, PriorFactor, TransitionFactor

from .context import RuleContext
from .info import ProposalInfo, VariableInfo
from .resampling import ess_triggered
from .rules import RuleTable, scores_in_groups
from .state import ProposalState

__all__: list[str] = []

#: the rules of this family (:func:`pgm.inference.default_rules` gathers every family's)
RULES = RuleTable()


def _history_len(ctx: RuleContext, variable: str) -> int:
    trans = ctx.graph.factors_of(variable, "transition")
    return max(0, getattr(trans[0], "order", 1) - 1) if trans else 0


@RULES.register(PriorFactor, Particles)
def _prior_particles(ctx: RuleContext, factor, frame) -> None:
    var = factor.variables[0]
    n = ctx.num_particles[var]
    x = np.asarray(factor.sample(ctx.rng, n), dtype=float).reshape(n, -1)
    cls = ctx.belief_type(var)
    ctx.beliefs[var] = cls.uniform(x, mass=1.0, history_len=_history_len(ctx, var))


@RULES.register(TransitionFactor, Particles)
def _predict_particles(ctx: RuleContext, factor, frame) -> None:
    var = factor.variables[0]
    b: Particles = ctx.beliefs[var]
    if frame.camera_motion is not None:  # past states into this frame's image coordinates
        labels = ctx.graph.variables[var].labels
        b = b._trusted(warp_states(b.x, labels, frame.camera_motion), b.log_weights,
                       tuple(warp_states(h, labels, frame.camera_motion) for h in b.history))
    proposals = ctx.graph.factors_of(var, "proposal")
    if proposals:
        f = proposals[0].prepare(frame, (b.x,) + b.history, confidence=ctx.confidence,
                                 factors=ctx.graph.factors)
        f = float(check_finite_param(f"{proposals[0].name}.prepare()", f, nonneg=True))
        if f > 1:
            raise ValueError(f"factor {proposals[0].name!r}: prepare() returned the share "
                             f"{f}, above 1")
        if f > 0:
            return _propose_particles(ctx, factor, proposals[0], frame, b, f)
    x_new = np.asarray(factor.sample(ctx.rng, b.x, *b.history), dtype=float)
    if x_new.shape != b.x.shape:
        raise ValueError(f"factor {factor.name!r}: sample() returned shape {x_new.shape}, "
                         f"expected {b.x.shape}")
    ctx.beliefs[var] = b.moved(x_new, history_len=max(0, factor.order - 1))


def _propose_particles(ctx: RuleContext, transition, proposal, frame, b: Particles,
                       f: float) -> ProposalInfo:
    """The predict stage with a proposal factor: each particle drawn from the proposal
    with probability ``f`` (from its :meth:`~pgm.factors.ProposalFactor.prepare`; else
    from the transition) and its weight multiplied by
    ``p(x_t | x_{t-1}) / ((1 - f) p + f q)`` (the mixture's importance weight;
    :class:`~pgm.factors.kinds.ProposalFactor`)."""
    var = transition.variables[0]
    past = (b.x,) + b.history
    cols = proposal.columns
    if cols is not None and max(cols) >= b.dim:
        raise ValueError(f"factor {proposal.name!r}: columns {list(cols)} do not fit variable "
                         f"{var!r} of dimension {b.dim}")
    x_q = np.asarray(proposal.sample(ctx.rng, frame, *past), dtype=float)
    if x_q.shape != b.x.shape:
        raise ValueError(f"factor {proposal.name!r}: sample() returned shape {x_q.shape}, "
                         f"expected {b.x.shape}")
    if f < 1.0 or cols is not None:
        x_p = np.asarray(transition.sample(ctx.rng, *past), dtype=float)
        if cols is not None:  # the other components from the transition
            x_p_cols = x_p.copy()
            x_p_cols[:, list(cols)] = x_q[:, list(cols)]
            x_q = x_p_cols
        x_new = (np.where((ctx.rng.random(b.num) < f)[:, None], x_q, x_p) if f < 1.0
                 else x_q)
    else:
        x_new = x_q
    log_p = np.asarray(transition.log_prob(x_new, *past) if cols is None else
                       transition.log_prob_columns(x_new, cols, *past), dtype=float)
    log_q = np.asarray(proposal.log_prob(x_new, frame, *past), dtype=float)
    log_mix = log_q if f == 1.0 else np.logaddexp(np.log1p(-f) + log_p, np.log(f) + log_q)
    moved = b.moved(x_new, history_len=max(0, transition.order - 1))
    # the evidence of this frame is measured against the mass before the correction
    ctx.state.get(var, ProposalState).prior_log_mass = moved.log_mass
    ctx.beliefs[var] = moved.reweight(log_p - log_mix)
    return ProposalInfo(proposed=f)


@RULES.register(LikelihoodFactor, Particles)
@scores_in_groups("graph")
def _weight_particles(ctx: RuleContext, factor, frame) -> np.ndarray:
    """The factor's log-likelihood at every particle: the increment the engine applies."""
    return factor.log_likelihood(ctx.beliefs[factor.variables[0]].x, frame)


@RULES.register("resample", Particles)
def _resample_particles(ctx: RuleContext, variable: str, frame) -> VariableInfo:
    b: Particles = ctx.beliefs[variable]
    n = ctx.num_particles[variable]
    if b.num != n:  # a fused mixture: always back to the variable's particle count
        ctx.beliefs[variable] = b.resample(ctx.rng, ctx.resampler, n)
        return VariableInfo(resampled=True)
    ess = b.ess
    if ess_triggered(ess, b.num, ctx.ess_threshold):
        ctx.beliefs[variable] = b.resample(ctx.rng, ctx.resampler, n)
        return VariableInfo(resampled=True, ess=ess)
    return VariableInfo(resampled=False, ess=ess)


@RULES.register("estimate", Particles)
def _estimate_particles(ctx: RuleContext, variable: str, frame) -> np.ndarray:
    return ctx.beliefs[variable].mean()
