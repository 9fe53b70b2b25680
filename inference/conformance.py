"""Rule conformance: run a model with every rule call checked against its contract.

The engine relies on a few promises that a rule's signature cannot express; this
module turns them into checks, so a new rule (yours, or one of the toolkit's) is
held to them by running any model with ``rules=checked(table)``:

* **likelihood** rules on a belief that likelihoods reweight (:class:`~pgm.Particles`)
  return a float array ``(N,)`` (``(K, N)`` on a plate's
  :class:`~pgm.core.batched.BatchedParticles`) (NaN counts as ``-inf``; ``+inf`` is refused), leave
  ``ctx.beliefs`` untouched — the same belief object, particles and weights
  unchanged — and the engine's evidence is then exactly that increment;
* **prior** rules leave a belief for their variable; **transition** rules keep a
  weighted particle belief's particle count and never produce NaN particles;
* **association** rules leave this frame's assignment in ``ctx.assignment``: matched
  replica and detection indices, as many of each, in range, none twice;
* **resample** rules keep a particle belief's total mass (``log_mass``, to 1e-9);
* **estimate** rules return a value; every rule returns ``None``, its diagnostics (an
  info object of :mod:`pgm.inference.info`, or a dict), or (likelihood) the increment.

A broken promise raises :class:`~pgm.core.errors.RuleContractError` naming the rule,
the factor or variable, and what went wrong. ``calls`` (a ``collections.Counter``)
counts the calls per registered key, so a test can also demand that every rule ran.

Example
-------
>>> import numpy as np
>>> from collections import Counter
from collections.abc import Mapping
>>> from pgm.core.frame import FrameContext
>>> from pgm.inference import DEFAULT_RULES, Engine
>>> from pgm.inference.conformance import checked
>>> from pgm.models import linear_gaussian
>>> calls = Counter()
>>> eng = Engine(linear_gaussian.build_graph(linear_gaussian.Params()),
...              np.random.default_rng(0), rules=checked(DEFAULT_RULES, calls))
>>> _ = eng.step(FrameContext(1, measurements=np.array([0.3])))
>>> sum(calls.values()) > 0
True
"""

from __future__ import annotations

import functools
from collections import Counter
from collections.abc import Mapping
from typing import Any

import numpy as np

from pgm.core.batched import BatchedParticles
from pgm.core.beliefs import Particles
from pgm.core.errors import RuleContractError
from pgm.factors import LikelihoodFactor, PriorFactor, TransitionFactor

from .context import RuleContext
from .engine import RuleTable, likelihood_reweights

__all__ = ["checked", "check_likelihood_increment"]


def _name(rule) -> str:
    return getattr(rule, "__qualname__", repr(rule))


def _fail(rule, what: str, msg: str):
    raise RuleContractError(f"rule {_name(rule)!r} ({what}): {msg}")


def check_likelihood_increment(out: Any, num: int | tuple[int, ...], rule=None,
                               what: str = "") -> np.ndarray:
    """Check a likelihood rule's return value: a float array ``(num,)`` (or of the shape
    ``num``, e.g. ``(K, N)`` for a plate), no ``+inf``."""
    shape = (num,) if isinstance(num, (int, np.integer)) else tuple(num)
    if not isinstance(out, np.ndarray):
        _fail(rule, what, f"returned {type(out).__name__}, not a log-likelihood increment "
                          f"of shape {shape}")
    if out.shape != shape:
        _fail(rule, what, f"returned shape {out.shape}, expected {shape}")
    if not np.issubdtype(out.dtype, np.floating):
        _fail(rule, what, f"returned dtype {out.dtype}, expected floats")
    if np.isposinf(out).any():
        _fail(rule, what, "returned +inf log-likelihoods")
    return out


_PARTICLES = (Particles, BatchedParticles)


def _snapshot(b: Any):
    if isinstance(b, _PARTICLES):
        return b, b.x.copy(), b.log_weights.copy(), tuple(h.copy() for h in b.history)
    return b, None, None, None


def _unchanged(snap) -> bool:
    b, x, lw, hist = snap
    if x is None:
        return True
    return (np.array_equal(b.x, x) and np.array_equal(b.log_weights, lw, equal_nan=True)
            and all(np.array_equal(h, h0) for h, h0 in zip(b.history, hist, strict=True)))


def _wrap_factor_rule(key: type, rule):
    @functools.wraps(rule)
    def run(ctx: RuleContext, factor, frame, *message):
        what = f"factor {factor.name!r}"
        var = factor.variables[0] if not message else message[1]
        if issubclass(key, LikelihoodFactor) and not message:
            b = ctx.beliefs[var]
            if likelihood_reweights(type(b)):
                snaps = {v: _snapshot(x) for v, x in ctx.beliefs.items()}
                out = rule(ctx, factor, frame)
                for v, snap in snaps.items():
                    if ctx.beliefs.get(v) is not snap[0] or not _unchanged(snap):
                        _fail(rule, what, f"changed the belief of {v!r}: a likelihood rule "
                                          f"returns its increment and never moves, reorders "
                                          f"or resamples particles")
                return check_likelihood_increment(out, b.log_weights.shape, rule, what)
        before = ctx.beliefs.get(var)
        out = rule(ctx, factor, frame, *message)
        if out is not None and not isinstance(out, Mapping):
            _fail(rule, what, f"returned {type(out).__name__}; expected None, an info "
                              f"object or a dict")
        after = ctx.beliefs.get(var)
        if getattr(key, "kind", None) == "association":
            _check_assignment(ctx, rule, what, frame)
        if issubclass(key, PriorFactor) and after is None:
            _fail(rule, what, f"left no belief for {var!r}")
        if (issubclass(key, TransitionFactor) and likelihood_reweights(type(before))
                and isinstance(after, _PARTICLES)):
            if after.log_weights.shape != before.log_weights.shape:
                _fail(rule, what, f"changed the particle count of {var!r} "
                                  f"({before.log_weights.shape} -> {after.log_weights.shape})")
            if np.isnan(after.x).any():
                _fail(rule, what, f"produced NaN particles for {var!r}")
        return out

    return run


def _check_assignment(ctx: RuleContext, rule, what: str, frame) -> None:
    a = ctx.assignment
    if a is None:
        _fail(rule, what, "left no assignment in ctx.assignment")
    rows, cols = np.asarray(a.rows), np.asarray(a.cols)
    K = ctx.replicas.K if ctx.replicas is not None else 0  # noqa: N806
    M = 0 if frame.detections is None else len(frame.detections.scores)  # noqa: N806
    if rows.shape != cols.shape or rows.ndim != 1:
        _fail(rule, what, f"assigned {rows.shape} replicas to {cols.shape} detections")
    if (rows.size and (rows.min() < 0 or rows.max() >= K or cols.min() < 0
                       or cols.max() >= M)):
        _fail(rule, what, f"assigned indices out of range ({K} replicas, {M} detections)")
    if len(set(rows.tolist())) != rows.size or len(set(cols.tolist())) != cols.size:
        _fail(rule, what, "assigned a replica or a detection twice")


def _wrap_belief_rule(operation: str, rule):
    @functools.wraps(rule)
    def run(ctx: RuleContext, variable: str, frame):
        what = f"{operation} of {variable!r}"
        before = ctx.beliefs[variable]
        out = rule(ctx, variable, frame)
        if operation == "estimate":
            if out is None:
                _fail(rule, what, "returned no estimate")
            return out
        if out is not None and not isinstance(out, Mapping):
            _fail(rule, what, f"returned {type(out).__name__}; expected None, an info "
                              f"object or a dict")
        after = ctx.beliefs[variable]
        if (operation == "resample" and isinstance(before, _PARTICLES) and before.num
                and not np.allclose(after.log_mass, before.log_mass, rtol=0, atol=1e-9)):
            _fail(rule, what, f"changed the total mass (log {before.log_mass} -> "
                              f"{after.log_mass})")
        return out

    return run


def checked(rules: RuleTable, calls: Counter | None = None) -> RuleTable:
    """A copy of ``rules`` whose every rule checks its contract on each call.

    ``calls``, if given, counts calls per registered ``(key, belief type)``. The batched
    likelihood path (several factors of one class scored in one pass) is not taken
    with a checked table: every factor goes through its rule.
    """
    out = RuleTable()
    for (key, belief_type), rule in rules.items():
        wrapped = (_wrap_belief_rule(key, rule) if isinstance(key, str)
                   else _wrap_factor_rule(key, rule))
        if calls is not None:
            wrapped = _counting(wrapped, calls, (key, belief_type))
        out.register(key, belief_type)(wrapped)
    return out


def _counting(rule, calls: Counter, key):
    @functools.wraps(rule)
    def run(*args):
        calls[key] += 1
        return rule(*args)

    return run
