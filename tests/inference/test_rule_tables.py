"""Rules as tables: where a rule's input -> output pair is exact, one row per case.

Each row builds a tiny graph, puts a known belief in the engine, applies the rule the
engine dispatches to (by factor class and belief type, as in a run) and compares with
the closed form (ReactiveMP's rule tests).
"""

import numpy as np
import pytest

from pgm import FactorGraph, FrameContext, Intensity, LikelihoodFactor, Particles, Variable
from pgm.core.expfam import Gaussian, InverseGamma
from pgm.factors import GaussianPrior, LinearGaussianLikelihood, LinearGaussianTransition
from pgm.factors.couplings import AffineCoupling
from pgm.factors.multitarget import IntensityPrior, InverseGammaPrior, NoiseForgetting, VBNoise
from pgm.inference import Engine


class Quadratic(LikelihoodFactor):
    def log_likelihood(self, x, ctx):
        return -0.5 * (x[:, 0] - 1.0) ** 2


def _engine(variables, factors, beliefs, **kw):
    eng = Engine(FactorGraph(variables, factors), np.random.default_rng(0), **kw)
    eng.beliefs.update(beliefs)
    return eng


def _apply(eng, name, frame=None):
    f = eng.graph.factors[name]
    return eng.rule_for(f)(eng, f, frame or FrameContext(1))


def kalman_update():
    eng = _engine([Variable("x", 1)],
                  [GaussianPrior("x", mean=[0.0], cov=1.0),
                   LinearGaussianLikelihood("x", H=[[1.0]], R=[[1.0]], name="lik")],
                  {"x": Gaussian(np.array([0.0]), np.array([[1.0]]))},
                  belief_types={"x": Gaussian})
    _apply(eng, "lik", FrameContext(1, measurements=np.array([1.0])))
    g = eng.beliefs["x"]
    return (g.mean(), g.cov()), (np.array([0.5]), np.array([[0.5]]))


def kalman_predict():
    F, Q = np.array([[1.0, 1.0], [0.0, 1.0]]), np.diag([0.1, 0.2])
    eng = _engine([Variable("x", 2)],
                  [GaussianPrior("x", mean=[0.0, 0.0], cov=1.0),
                   LinearGaussianTransition("x", F=F, Q=Q, name="cv")],
                  {"x": Gaussian(np.array([1.0, 2.0]), np.diag([1.0, 4.0]))},
                  belief_types={"x": Gaussian})
    _apply(eng, "cv")
    g = eng.beliefs["x"]
    return (g.mean(), g.cov()), (np.array([3.0, 2.0]), np.array([[5.1, 4.0], [4.0, 4.2]]))


def noise_forgetting():
    eng = _engine([Variable("x", 1), Variable("n", 2, role="noise")],
                  [GaussianPrior("x", mean=[0.0]),
                   LinearGaussianLikelihood("x", H=[[1.0]], R=[[1.0]]),
                   InverseGammaPrior("n", sigma=[1.0, 1.0], alpha=10.0),
                   NoiseForgetting("n", rho=0.5, alpha_min=3.0, name="forget"),
                   VBNoise("n", "x")],
                  {"n": InverseGamma(np.array([10.0, 4.0]), np.array([20.0, 8.0]))},
                  belief_types={"x": Gaussian})
    _apply(eng, "forget")
    q = eng.beliefs["n"]
    # rho = 0.5: (5, 10) stays; (2, 4) is below alpha_min = 3, so both scale by 3/2
    return (q.alpha, q.beta), (np.array([5.0, 3.0]), np.array([10.0, 6.0]))


def particle_likelihood():
    x = np.array([[0.0], [1.0], [3.0]])
    eng = _engine([Variable("x", 1)], [GaussianPrior("x", mean=[0.0]), Quadratic("x", name="q")],
                  {"x": Particles(x, np.log(np.full(3, 1 / 3)))})
    before = eng.beliefs["x"]
    ll = _apply(eng, "q")
    assert eng.beliefs["x"] is before  # the contract: the rule returns, the engine applies
    return ll, np.array([-0.5, 0.0, -2.0])


def appearance_on_a_set():
    b = Intensity(np.array([[0.0], [2.0]]), np.log([0.5, 1.5]))
    eng = _engine([Variable("s", 1, role="set")],
                  [IntensityPrior("s", mean=[0.0]), Quadratic("s", name="q")], {"s": b})
    out = _apply(eng, "q")
    return (out, eng.beliefs["s"] is b), (None, True)


def particle_estimate():
    x = np.array([[0.0, 2.0], [4.0, -2.0]])
    eng = _engine([Variable("x", 2)], [GaussianPrior("x", mean=[0.0, 0.0])],
                  {"x": Particles(x, np.log([0.25, 0.75]))})
    return eng.rules.lookup("estimate", Particles)(eng, "x", None), np.array([3.0, -1.0])


def noise_estimate():
    eng = _engine([Variable("x", 1), Variable("n", 2, role="noise")],
                  [GaussianPrior("x", mean=[0.0]),
                   LinearGaussianLikelihood("x", H=[[1.0]], R=[[1.0]]),
                   InverseGammaPrior("n", sigma=[1.0, 1.0], alpha=10.0),
                   NoiseForgetting("n", rho=0.5), VBNoise("n", "x")],
                  {"n": InverseGamma(np.array([4.0, 10.0]), np.array([8.0, 5.0]))},
                  belief_types={"x": Gaussian})
    return eng.rules.lookup("estimate", InverseGamma)(eng, "n", None), np.array([2.0, 0.5])


def mixture_message():
    """A deterministic coupling moves the source particles by the offset and the message
    carries the source's prior weight + likelihood (the mixture fusion's message)."""
    x = np.array([[0.0], [1.0]])
    eng = _engine([Variable("a", 1), Variable("b", 1)],
                  [GaussianPrior("a", mean=[0.0]), GaussianPrior("b", mean=[0.0]),
                   AffineCoupling("a", "b", offset=[5.0], std=[1.0], name="c")],
                  {"a": Particles(x, np.log([0.5, 0.5])), "b": Particles(x, np.log([0.5, 0.5]))})
    eng.evidence["b"] = (np.log([0.5, 0.5]), np.array([0.0, -1.0]))
    f = eng.graph.factors["c"]
    eng.rules.lookup(type(f), Particles)(eng, f, FrameContext(1), "b", "a")
    msg = eng.messages[("b", "a")]
    return (msg.x, msg.log_weights), (x + 5.0, np.log([0.5, 0.5]) + [0.0, -1.0])


ROWS = [kalman_update, kalman_predict, noise_forgetting, particle_likelihood,
        appearance_on_a_set, particle_estimate, noise_estimate, mixture_message]


@pytest.mark.parametrize("row", ROWS, ids=lambda r: r.__name__)
def test_rule_table(row):
    got, expected = row()
    if isinstance(expected, tuple):
        for g, e in zip(got, expected, strict=True):
            if isinstance(e, np.ndarray):
                np.testing.assert_allclose(g, e, rtol=1e-12, atol=1e-12)
            else:
                assert g == e
    else:
        np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12)


def test_default_rules_gathers_every_family_once():
    """``default_rules()`` is a new table of every family's rules, no key registered by two
    families, and the engine's default table holds them all."""
    import pgm.inference as inf

    seen: dict = {}
    for family in inf.FAMILIES:
        for key, _ in family.RULES.items():
            assert key not in seen, (key, family.__name__, seen.get(key))
            seen[key] = family.__name__
    table = inf.default_rules()
    assert table is not inf.DEFAULT_RULES
    assert {k for k, _ in table.items()} == set(seen)
    assert set(seen) <= {k for k, _ in inf.DEFAULT_RULES.items()}
    table.remove(*next(iter(seen)))  # a new table: changing it leaves the default alone
    assert next(iter(seen)) in {k for k, _ in inf.DEFAULT_RULES.items()}
