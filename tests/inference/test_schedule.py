"""The per-frame schedule derived from the factor kinds: a chain's stages in order, the
messages of a part graph both ways, VB likelihoods inside the fixed point."""

from __future__ import annotations

import pytest

from pgm import FactorGraph, Variable
from pgm.factors import GaussianPrior, LinearGaussianLikelihood, LinearGaussianTransition
from pgm.factors.couplings import AffineCoupling
from pgm.factors.multitarget import InverseGammaPrior, VBNoise
from pgm.inference.schedule import derive_schedule, message_order


def _stages(phases):
    return [s for s, items in phases if items]


def _chain(extra=()):
    return FactorGraph(
        [Variable("x", 1, role="state"), *[v for v, _ in extra]],
        [GaussianPrior("x", mean=[0.0], cov=1.0),
         LinearGaussianTransition("x", F=[[1.0]], Q=[[0.1]]),
         LinearGaussianLikelihood("x", H=[[1.0]], R=[[1.0]], name="lik"),
         *[f for _, fs in extra for f in fs]], name="chain")


def test_a_chain_predicts_weights_estimates_and_resamples_in_order():
    s = derive_schedule(_chain())
    order = _stages(s.phases)
    assert order.index("predict") < order.index("weight") < order.index("estimate") \
        < order.index("resample")
    assert "prior" in _stages(s.first_frame) and "predict" not in _stages(s.first_frame)


def test_two_coupled_parts_exchange_messages_both_ways():
    parts = [Variable(n, 1, role="part") for n in ("a", "b")]
    g = FactorGraph(parts, [GaussianPrior(n, mean=[0.0], cov=1.0) for n in "ab"]
                    + [LinearGaussianTransition(n, F=[[1.0]], Q=[[0.1]]) for n in "ab"]
                    + [AffineCoupling("a", "b", offset=[1.0], std=[0.5], name="ab")],
                    name="parts")
    msgs = message_order(g)
    assert {(src, dst) for _, src, dst in msgs} == {("a", "b"), ("b", "a")}
    inframe = dict(derive_schedule(g).phases)["inframe"]
    assert {(i[1], i[2]) for i in inframe} == {("a", "b"), ("b", "a")}


def test_a_likelihood_under_vb_is_updated_inside_the_fixed_point():
    noise = (Variable("r", 1, role="noise"),
             [InverseGammaPrior("r", sigma=1.0), VBNoise("r", "x", likelihood="lik", name="vb")])
    s = derive_schedule(_chain([noise]), inframe_iterations=2)
    weighted = [i for st, items in s.phases if st == "weight" for i in items]
    assert "lik" not in weighted  # the VB fixed point weighs it
    assert sum(i == "vb" for _, items in s.phases for i in items) == 2  # one per sweep


def test_bad_schedule_arguments():
    with pytest.raises(ValueError, match="inframe_iterations"):
        derive_schedule(_chain(), inframe_iterations=-1)
    with pytest.raises(ValueError, match="fusion"):
        derive_schedule(_chain(), fusion="sum")
