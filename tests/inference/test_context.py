"""What a rule sees (pgm.inference.context.RuleContext): the beliefs, the generator, the
settings and its state slots, never the engine; per replica of a plate, that replica's
own; newborn replicas run their first frame on a fresh context, and nothing is swapped on
the engine."""

import numpy as np
import pytest

from pgm import FactorGraph, Plate
from pgm.core.beliefs import Particles
from pgm.core.frame import FrameContext
from pgm.factors import LikelihoodFactor
from pgm.inference import DEFAULT_RULES, Engine, RuleContext
from pgm.inference.state import StateSlots
from pgm.models import linear_gaussian


class Pull(LikelihoodFactor):
    """A likelihood pulling the first component towards ``target`` (its rule is below)."""

    def __init__(self, variable, *, target, name=None):
        super().__init__(variable, name=name)
        self.target = float(target)

    def params(self):
        return {"target": self.target}

    def log_likelihood(self, x, ctx):
        return -0.5 * (x[:, 0] - self.target) ** 2


def _frames(n=5):
    rng = np.random.default_rng(1)
    return [FrameContext(t + 1, measurements=rng.normal(0.1 * t, 0.7, 1)) for t in range(n)]


def _graph(plate: bool) -> FactorGraph:
    g = linear_gaussian.build_graph(linear_gaussian.Params()).with_factors(
        Pull("x", target=2.0, name="pull"))
    if not plate:
        return g
    return FactorGraph(list(g.variables.values()), list(g.factors.values()), name=g.name,
                       meta=g.meta, plates=[Plate("target", tuple(g.variables))])


def _rules(seen: list):
    rules = DEFAULT_RULES.copy()

    @rules.register(Pull, Particles)
    def pull(ctx, factor, frame):
        seen.append(ctx)
        return factor.log_likelihood(ctx.beliefs[factor.variables[0]].x, frame)

    return rules


def test_a_rule_sees_a_context_not_the_engine():
    seen = []
    engine = Engine(_graph(False), 0, rules=_rules(seen), num_particles=100)
    for frame in _frames():
        engine.step(frame)
    assert len(seen) == 5 and all(c is engine.ctx for c in seen)
    ctx = seen[0]
    assert isinstance(ctx, RuleContext) and not isinstance(ctx, Engine)
    for name in ("step", "rules", "schedule", "add_hook", "_run", "runtime"):
        assert not hasattr(ctx, name), name  # no stage, rule table or step loop in reach
    assert ctx.beliefs is engine.beliefs and ctx.rng is engine.rng
    assert ctx.num_particles == {"x": 100} and ctx.ess_threshold == engine.ess_threshold
    with pytest.raises(AttributeError):
        ctx.anything_else = 1  # a fixed set of fields


def test_per_replica_rules_get_their_replicas_context_and_newborns_a_fresh_one():
    seen = []
    engine = Engine(_graph(True), 0, rules=_rules(seen), num_particles=100)
    frames = _frames()
    before = engine.ctx
    beliefs_before = engine.ctx.beliefs
    rngs = [np.random.default_rng(s) for s in (1, 2)]
    engine.add(None, frames[0], rngs=rngs, count=2)
    assert engine.ctx is before  # nothing swapped on the engine
    newborn = seen[:2]
    assert [c.rng for c in newborn] == rngs  # one context per replica, its own generator
    assert all(c.replicas is None and isinstance(c.state, StateSlots) for c in newborn)
    assert newborn[0].state is not newborn[1].state
    assert all(c.beliefs is not beliefs_before for c in newborn)
    assert newborn[0].beliefs["x"].x.shape == (100, 2)  # a replica's row: single-graph shape
    for frame in frames[1:]:
        engine.step(frame, lifecycle=False)
    assert len(seen) == 2 * 5
    later = seen[2:4]
    assert [c.rng for c in later] == rngs and later[0].state is engine.replicas.state[0]
    assert later[1].graph is engine.replicas.graphs[1]
    # the replicas' rows written back: replica 1 is the single-graph run with its generator
    single = Engine(_graph(False), np.random.default_rng(2), rules=_rules([]),
                    num_particles=100)
    for frame in frames:
        single.step(frame)
    np.testing.assert_array_equal(single.beliefs["x"].x, engine.beliefs["x"].x[1])
