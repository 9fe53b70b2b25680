"""The weight stage: the evidence increment is the log of the mean incremental weight
(a constant likelihood gives it exactly), and a likelihood rule that moves the belief
breaks its contract, by name."""

from __future__ import annotations

import numpy as np
import pytest

from pgm import FactorGraph, Particles, Variable
from pgm.core.errors import RuleContractError
from pgm.core.frame import FrameContext
from pgm.factors import GaussianPrior, LikelihoodFactor, LinearGaussianTransition
from pgm.inference import DEFAULT_RULES, Engine


class Flat(LikelihoodFactor):
    """``log p(z | x) = c`` for every particle."""

    abstract = True

    def __init__(self, variable, *, c=0.0, name=None):
        super().__init__(variable, name=name)
        self.c = float(c)

    def log_likelihood(self, x, ctx):
        return np.full(len(x), self.c)


def _graph(c):
    return FactorGraph([Variable("x", 1, role="state")],
                       [GaussianPrior("x", mean=[0.0], cov=1.0),
                        LinearGaussianTransition("x", F=[[1.0]], Q=[[0.1]]),
                        Flat("x", c=c, name="flat")], name="flat")


@pytest.mark.parametrize("c", [-3.0, 0.0, 2.5])
def test_a_constant_likelihood_gives_its_constant_as_the_evidence(c):
    eng = Engine(_graph(c), np.random.default_rng(0), num_particles=50)
    for t in range(1, 4):
        rec = eng.step(FrameContext(t))
        assert rec.log_evidence["x"] == pytest.approx(c, abs=1e-12)
        assert rec.ess["x"] == pytest.approx(50.0)


def test_a_likelihood_rule_that_moves_the_belief_is_refused_by_name():
    rules = DEFAULT_RULES.copy()

    @rules.register(Flat, Particles)
    def moving(ctx, factor, frame):
        b = ctx.beliefs["x"]
        ctx.beliefs["x"] = b.moved(b.x + 1.0)
        return np.zeros(b.num)

    eng = Engine(_graph(0.0), np.random.default_rng(0), num_particles=10, rules=rules)
    with pytest.raises(RuleContractError, match="moving.*replaced the belief"):
        eng.step(FrameContext(1))
