"""Rules for batched beliefs: a plate's replicas in one pass, and any rule per replica.

The engine keeps a plate variable's belief batched (:mod:`pgm.core.batched`). This module
keeps, in its table :data:`RULES` (gathered by :func:`pgm.inference.default_rules`), the
rules for
:class:`~pgm.core.batched.BatchedParticles` that act on all ``K`` replicas at once — a
shared transition samples the ``K·N`` particles in one call of ``factor.sample``; a shared
likelihood scores them in one call, per-target templates are scored together by
``log_likelihood_batch`` (one pass per cluster of overlapping replicas); interaction
factors (mutual exclusion) reweight every replica against the others' estimates; mixture
messages of particle BP, fusion, estimates and ESS-triggered resampling per replica — and
:func:`per_replica`, which the rule table uses to run any single-graph rule once per
replica where no batched rule is registered (VB noise per target, product fusion, exact
Gaussian rules, a user's own rule).

**Randomness.** Each replica owns a ``numpy.random.Generator``, and a batched draw of
shape ``(K·N, ...)`` is made of ``K`` draws of shape ``(N, ...)``, one from each
replica's generator (:class:`ReplicaRNG`). A replica therefore consumes its stream
exactly as a single-graph run of the same graph would: ``K = 1`` reproduces that run bit
for bit, and ``K`` replicas without interaction reproduce ``K`` separate runs (tested).
A factor whose ``sample``/``propagate`` draws numbers whose leading axis is not the
particle count cannot be split this way and is refused with its name.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.batched import BatchedParticles
from pgm.core.boxes import box_columns as _box_columns
from pgm.core.frame import FrameContext
from pgm.core.graph import FactorGraph
from pgm.core.motion import warp_states
from pgm.factors import CouplingFactor, LikelihoodFactor, TransitionFactor
from pgm.factors.plates import InteractionFactor

from .context import RuleContext
from .info import Info, VariableInfo
from .particles import _predict_particles
from .pbp import MixtureMessage, coupling_message, fuse
from .resampling import ess_triggered
from .rules import RuleTable, register_replica_adapter, scores_in_groups

__all__ = ["ReplicaRNG", "per_replica", "RowMessages", "BatchedMixtureMessage", "score_group",
           "weight_batched", "box_columns"]

#: the rules of this family (:func:`pgm.inference.default_rules` gathers every family's)
RULES = RuleTable()


# -------------------------------------------------------------------------------------
# randomness split over replicas
# -------------------------------------------------------------------------------------
class ReplicaRNG:
    """A ``Generator`` look-alike whose draws split over replicas.

    A draw of ``size = (K·n, ...)`` is made of ``K`` draws of ``(n, ...)``, the ``k``-th
    from ``generators[k]``; array arguments (``loc``, ``scale``, ``low``, ``high``)
    whose leading axis is ``K·n`` are split the same way, others are passed to every
    replica. Only the methods the toolkit's factors use are offered.
    """

    def __init__(self, generators: Sequence[np.random.Generator], n: int,
                 owner: str = "a factor"):
        self.generators = list(generators)
        self.n = int(n)
        self.owner = owner

    @property
    def total(self) -> int:
        """``K·n``: the leading axis every draw must have."""
        return len(self.generators) * self.n

    def _sizes(self, size) -> tuple[int, ...]:
        shape = (size,) if np.ndim(size) == 0 and size is not None else tuple(size or ())
        if not shape or shape[0] != self.total:
            raise ValueError(
                f"{self.owner} drew random numbers of shape {shape}, whose leading axis is not "
                f"the particle count {self.total}; a plate splits draws per replica "
                f"along that axis (draw one value per particle, e.g. "
                f"rng.standard_normal((n, d)))")
        return (self.n,) + shape[1:]

    def _part(self, value, k: int):
        if np.ndim(value) > 0 and np.shape(value)[0] == self.total:
            return value[k * self.n:(k + 1) * self.n]
        return value

    def _draw(self, method: str, size, *args, out=None):
        if out is not None:
            size = out.shape
        per = self._sizes(size)
        parts = [getattr(g, method)(*(self._part(a, k) for a in args), size=per)
                 for k, g in enumerate(self.generators)]
        res = np.concatenate(parts) if parts else np.zeros((0,) + per[1:])
        if out is not None:
            out[...] = res
            return out
        return res

    def standard_normal(self, size=None, dtype=np.float64, out=None):
        """Standard normal draws, split over replicas."""
        return self._draw("standard_normal", size, out=out)

    def random(self, size=None, dtype=np.float64, out=None):
        """Uniform [0, 1) draws, split over replicas."""
        return self._draw("random", size, out=out)

    def normal(self, loc=0.0, scale=1.0, size=None):
        """Normal draws, split over replicas."""
        if size is None:
            size = np.broadcast(np.asarray(loc), np.asarray(scale)).shape
        return self._draw("normal", size, loc, scale)

    def uniform(self, low=0.0, high=1.0, size=None):
        """Uniform draws, split over replicas."""
        if size is None:
            size = np.broadcast(np.asarray(low), np.asarray(high)).shape
        return self._draw("uniform", size, low, high)

    def __getattr__(self, name: str):
        raise ValueError(f"{self.owner} calls rng.{name}(), which a plate cannot "
                         f"split per replica (use standard_normal, random, normal or uniform "
                         f"with one draw per particle)")


# -------------------------------------------------------------------------------------
# boxes
# -------------------------------------------------------------------------------------
def box_columns(graph: FactorGraph, variable: str) -> list[int]:
    """Columns of cx, cy, w, h in ``variable`` (a ``ValueError`` if it is not a box)."""
    return _box_columns(graph.variables[variable].labels, f"plate variable {variable!r}")


# -------------------------------------------------------------------------------------
# single-graph rules, once per replica
# -------------------------------------------------------------------------------------
class RowMessages:
    """Messages of one directed edge, one per replica (from a per-replica rule)."""

    def __init__(self, items: Sequence[Any]):
        self.items = list(items)

    def row(self, k: int) -> Any:
        return self.items[k]


def _merge(outs: list[Any]) -> Any:
    """The replicas' returns of one rule as one value: arrays stacked ``(K, ...)``, dicts
    and info objects (:mod:`pgm.inference.info`) merged key by key, ``None`` where every
    replica returned ``None``."""
    if all(o is None for o in outs):
        return None
    if all(isinstance(o, (dict, Info)) for o in outs):
        keys = list(dict.fromkeys(k for o in outs for k in o))
        merged = {k: _merge([o.get(k) for o in outs]) for k in keys}
        kind = type(outs[0])
        if issubclass(kind, Info) and all(type(o) is kind for o in outs):
            return kind().merge(merged)  # the replicas' typed diagnostics, one per field
        return merged
    if all(isinstance(o, (np.ndarray, float, int, bool, np.number, np.bool_)) for o in outs):
        try:
            return np.stack([np.asarray(o) for o in outs])
        except ValueError:  # shapes differ
            return list(outs)
    return list(outs)


@functools.cache
def per_replica(rule: Callable, key: type | str) -> Callable:
    """``rule`` (a single-graph rule for the replica's belief type) run once per replica:
    on each replica's view of the engine (its rows of the batched beliefs, its generator,
    its views of the factors that learn), writing the rows it changes back into the
    batched beliefs. Its returns are merged (likelihood increments stacked to ``(K, N)``)."""
    operation = isinstance(key, str)

    def run(ctx: RuleContext, item, frame: FrameContext, *args: Any) -> Any:
        outs, views = [], []
        for k in range(ctx.replicas.K):
            view = ctx.replica(k)
            rows, message_rows = dict(view.beliefs), dict(view.messages)
            target = item if operation else view.graph.factors[item.name]
            outs.append(rule(view, target, frame, *args))
            views.append((view, rows, message_rows))
        if not views:
            return None
        for v in dict.fromkeys(v for view, _, _ in views for v in view.beliefs):
            if any(view.beliefs.get(v) is not rows.get(v) for view, rows, _ in views):
                ctx.beliefs[v] = ctx.belief_type(v).stack([view.beliefs[v]
                                                           for view, _, _ in views])
        for m in dict.fromkeys(m for view, _, _ in views for m in view.messages):
            if any(view.messages.get(m) is not mrows.get(m) for view, _, mrows in views):
                ctx.messages[m] = RowMessages([view.messages[m] for view, _, _ in views])
        return _merge(outs)

    run.__qualname__ = f"per_replica({getattr(rule, '__qualname__', rule)})"
    run.row_rule = rule
    return run


register_replica_adapter(per_replica)

# -------------------------------------------------------------------------------------
# batched rules (all replicas at once)
# -------------------------------------------------------------------------------------
def _local(ctx: RuleContext, name: str) -> bool:
    return name in ctx.plate_spec.local


@RULES.register(TransitionFactor, BatchedParticles)
def predict_batched(ctx: RuleContext, factor, frame: FrameContext) -> None:
    """Move every replica's particles: one ``factor.sample`` call on ``(K·N, d)`` for a
    shared transition (draws split per replica), one call per replica for its own copy."""
    var = factor.variables[0]
    if ctx.graph.factors_of(var, "proposal"):  # proposals: the single-graph rule, per replica
        return per_replica(_predict_particles, TransitionFactor)(ctx, factor, frame)
    b: BatchedParticles = ctx.beliefs[var]
    reps = ctx.replicas
    K, n, d = b.x.shape  # noqa: N806
    flat = b.x.reshape(K * n, d)
    past = [h.reshape(K * n, d) for h in b.history]
    if frame.camera_motion is not None:  # past states into this frame's image coordinates
        labels = ctx.graph.variables[var].labels
        flat = warp_states(flat, labels, frame.camera_motion)
        past = [warp_states(h, labels, frame.camera_motion) for h in past]
    gens = reps.generators()
    if _local(ctx, factor.name):  # a transition that learns per target: one call each
        new = np.concatenate([np.asarray(reps.graphs[k].factors[factor.name].sample(
            gens[k], flat[k * n:(k + 1) * n], *(h[k * n:(k + 1) * n] for h in past)),
            dtype=float) for k in range(K)])
    else:
        rng = ReplicaRNG(gens, n, owner=f"transition {factor.name!r}")
        new = np.asarray(factor.sample(rng, flat, *past), dtype=float)
    if new.shape != flat.shape:
        raise ValueError(f"factor {factor.name!r}: sample() returned shape {new.shape}, "
                         f"expected {flat.shape}")
    n_hist = max(0, getattr(factor, "order", 1) - 1)
    ctx.beliefs[var] = BatchedParticles._trusted(
        new.reshape(K, n, d), b.log_weights,
        tuple(a.reshape(K, n, d) for a in ([flat] + past)[:n_hist]))


@RULES.register(LikelihoodFactor, BatchedParticles)
@scores_in_groups("replicas")
def weight_batched(ctx: RuleContext, factor, frame: FrameContext) -> np.ndarray:
    """``(K, N)`` log-likelihood increments of every replica's particles."""
    return score_group(ctx, [factor], frame)[0]


def score_group(ctx: RuleContext, fs: list, frame: FrameContext) -> list[np.ndarray]:
    """``(K, N)`` log-likelihoods of each factor of one weight group ``fs`` (equal
    ``batch_key``)."""
    reps = ctx.replicas
    K = reps.K  # noqa: N806
    local = [_local(ctx, f.name) for f in fs]
    if K * len(fs) > 1 and fs[0].batch_key is not None and all(local):
        # the copies of the group's factors scored together, one pass per cluster of
        # replicas whose particles' boxes overlap (a joint pass costs the area of its
        # boxes' union, so distant targets are not scored through the empty space
        # between them); replica-major, so that one replica's order is the
        # single-graph engine's
        out = [np.empty(ctx.beliefs[f.variables[0]].log_weights.shape) for f in fs]
        for members in _clusters(_extents(ctx, fs)):
            copies = [reps.graphs[k].factors[f.name] for k in members for f in fs]
            xs = [ctx.beliefs[f.variables[0]].x[k] for k in members for f in fs]
            lls = type(fs[0]).log_likelihood_batch(copies, xs, frame)
            for i, ll in enumerate(lls):
                out[i % len(fs)][members[i // len(fs)]] = ll
        return out
    out = []
    for f, own in zip(fs, local, strict=True):
        x = ctx.beliefs[f.variables[0]].x
        _, n, d = x.shape
        if not own:  # shared: all replicas' particles in one call
            out.append(np.asarray(f.log_likelihood(x.reshape(K * n, d), frame),
                                  dtype=float).reshape(K, n))
        else:
            out.append(np.stack([np.asarray(reps.graphs[k].factors[f.name].log_likelihood(
                x[k], frame), dtype=float) for k in range(K)]))
    return out


def _extents(ctx: RuleContext, fs: list) -> np.ndarray:
    """``(K, 4)`` rectangles ``x0, y0, x1, y1`` around every particle's box of the
    group ``fs`` in each replica."""
    lo, hi = [], []
    for f in fs:
        v = f.variables[0]
        bx = ctx.beliefs[v].x[..., box_columns(ctx.graph, v)]  # (K, N, 4)
        lo.append((bx[..., :2] - np.abs(bx[..., 2:]) / 2).min(axis=1))
        hi.append((bx[..., :2] + np.abs(bx[..., 2:]) / 2).max(axis=1))
    return np.concatenate([np.min(lo, axis=0), np.max(hi, axis=0)], axis=1)


@RULES.register(InteractionFactor, BatchedParticles)
def interact_batched(ctx: RuleContext, factor, frame: FrameContext) -> None:
    """Reweight every replica's particles against the other replicas' current estimates
    (a replica the potential leaves with no finite weight keeps its weights)."""
    v = factor.variables[0]
    b: BatchedParticles = ctx.beliefs[v]
    if b.K < 2:
        return
    pot = np.asarray(factor.log_potential(b.x, b.mean(), frame), dtype=float)
    ctx.beliefs[v], _ = b.reweight(pot).normalized(fallback=b)
    if v in ctx.evidence:
        lw0, ll = ctx.evidence[v]
        ctx.evidence[v] = (lw0, ll + pot)


def _batched_mixture(ctx: RuleContext) -> bool:
    s = ctx.settings
    return s.fusion == "mixture" and s.message_weight == "source" and not s.message_particles


@dataclass(frozen=True)
class BatchedMixtureMessage:
    """Mixture messages of all replicas: ``x`` ``(K, M, d)``, log-weights ``(K, M)`` on
    the common scale, histories ``(K, M, d)``."""

    x: np.ndarray
    log_weights: np.ndarray
    history: tuple[np.ndarray, ...]

    def row(self, k: int) -> MixtureMessage:
        return MixtureMessage(self.x[k], self.log_weights[k], tuple(h[k] for h in self.history))


def _evidence(ctx: RuleContext, v: str) -> tuple[np.ndarray, np.ndarray]:
    b = ctx.beliefs[v]
    return ctx.evidence.get(v, (b.log_weights, np.zeros_like(b.log_weights)))


@RULES.register(CouplingFactor, BatchedParticles)
def coupling_batched(ctx: RuleContext, factor, frame: FrameContext, src: str, dst: str):
    """The message ``src → dst`` of every replica (mixture with source weights batched;
    any other setting per replica, :func:`pgm.inference.pbp.coupling_message`)."""
    if not _batched_mixture(ctx):
        return per_replica(coupling_message, CouplingFactor)(ctx, factor, frame, src, dst)
    reps = ctx.replicas
    b = ctx.beliefs[src]
    K, n, d = b.x.shape  # noqa: N806
    flat = b.x.reshape(K * n, d)
    gens = reps.generators()
    if _local(ctx, factor.name):
        x_msg = np.concatenate([np.asarray(reps.graphs[k].factors[factor.name].propagate(
            gens[k], flat[k * n:(k + 1) * n], src)) for k in range(K)])
    else:
        x_msg = np.asarray(factor.propagate(ReplicaRNG(gens, n,
                                                       owner=f"coupling {factor.name!r}"),
                                            flat, src), dtype=float)
    d_dst = ctx.beliefs[dst].dim
    x_msg = x_msg.reshape(K, n, d_dst)
    n_hist = len(ctx.beliefs[dst].history)
    if _local(ctx, factor.name):  # each replica's own (learned) coupling
        hist = [np.stack([np.asarray(reps.graphs[k].factors[factor.name].map(h[k], src))
                          for k in range(K)]).reshape(K, n, d_dst)
                for h in b.history[:n_hist]]
    else:
        hist = [np.asarray(factor.map(h.reshape(K * n, d), src)).reshape(K, n, d_dst)
                for h in b.history[:n_hist]]
    hist += [x_msg.copy() for _ in range(n_hist - len(hist))]
    lw0, ll = _evidence(ctx, src)
    ctx.messages[(src, dst)] = BatchedMixtureMessage(x_msg, lw0 + ll, tuple(hist))
    return None


def _row_log_normalize(lw: np.ndarray) -> np.ndarray:
    """Per-row :func:`pgm.core.numerics.log_normalize` (the same arithmetic per row)."""
    lw = np.where(np.isnan(lw), -np.inf, lw)
    shifted = lw - lw.max(axis=1, keepdims=True)
    e = np.exp(shifted)
    return shifted - np.array([math.log(float(row.sum())) for row in e])[:, None]


@RULES.register("fuse", BatchedParticles)
def fuse_batched(ctx: RuleContext, variable: str, frame: FrameContext) -> VariableInfo | None:
    """Every replica's own weighted particles joined with its incoming mixture messages
    (product fusion: per replica, :func:`pgm.inference.pbp.fuse`)."""
    if not _batched_mixture(ctx):
        return per_replica(fuse, "fuse")(ctx, variable, frame)
    b: BatchedParticles = ctx.beliefs[variable]
    lw0, ll = _evidence(ctx, variable)
    incoming = [m for (_, dst), m in ctx.messages.items() if dst == variable]
    lw = _row_log_normalize(np.concatenate([lw0 + ll] + [m.log_weights for m in incoming],
                                           axis=1))
    x = np.concatenate([b.x] + [m.x for m in incoming], axis=1)
    hist = tuple(np.concatenate([h] + [m.history[i] for m in incoming], axis=1)
                 for i, h in enumerate(b.history))
    ctx.beliefs[variable] = BatchedParticles._trusted(x, lw, hist, log_mass=np.zeros(b.K))
    return VariableInfo(own_mass=np.array([float(np.exp(row[:b.num]).sum()) for row in lw]))


@RULES.register("estimate", BatchedParticles)
def estimate_batched(ctx: RuleContext, variable: str, frame: FrameContext) -> np.ndarray:
    """``(K, d)`` weighted means."""
    return ctx.beliefs[variable].mean()


@RULES.register("resample", BatchedParticles)
def resample_batched(ctx: RuleContext, variable: str, frame: FrameContext) -> VariableInfo:
    """ESS-triggered resampling per replica, each with its own generator (a fused
    mixture: every replica back to the variable's particle count)."""
    b: BatchedParticles = ctx.beliefs[variable]
    n = ctx.num_particles[variable]
    ess = b.ess
    if b.num != n:
        rows = np.arange(b.K)
    else:
        rows = np.array([k for k in range(b.K)
                         if ess_triggered(float(ess[k]), b.num, ctx.ess_threshold)], int)
    ctx.beliefs[variable] = b.resample_rows(ctx.replicas.generators(), ctx.resampler, n,
                                               rows)
    return VariableInfo(resampled=np.isin(np.arange(b.K), rows), ess=ess)

def _clusters(rects: np.ndarray) -> list[list[int]]:
    """Groups of indices of rectangles ``(K, 4)`` (x0, y0, x1, y1) connected by overlap,
    each group in increasing order, groups by their first member."""
    k = len(rects)
    if k == 0:
        return []
    ov = ((rects[:, None, 0] < rects[None, :, 2]) & (rects[None, :, 0] < rects[:, None, 2])
          & (rects[:, None, 1] < rects[None, :, 3]) & (rects[None, :, 1] < rects[:, None, 3]))
    from scipy.sparse.csgraph import connected_components

    _, label = connected_components(ov, directed=False)
    groups: dict[int, list[int]] = {}
    for i, lab in enumerate(label.tolist()):
        groups.setdefault(lab, []).append(i)
    return sorted(groups.values(), key=lambda g: g[0])
