"""Every registered rule runs under its contract; rules that break it are caught."""

from collections import Counter

import numpy as np
import pytest

from pgm import FactorGraph, FrameContext, LikelihoodFactor, Particles, Variable
from pgm.core.errors import RuleContractError
from pgm.core.expfam import Gaussian
from pgm.factors import GaussianPrior, LinearGaussianLikelihood, LinearGaussianTransition
from pgm.factors.couplings import AffineCoupling
from pgm.factors.multitarget import InverseGammaPrior, NoiseForgetting, VBNoise
from pgm.inference import DEFAULT_RULES, Engine
from pgm.inference.conformance import checked
from pgm.models import linear_gaussian, phd, vb_phd

F = np.array([[1.0, 1, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1], [0, 0, 0, 1]])
H = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0]])


class Bump(LikelihoodFactor):
    """A test appearance factor on a set: prefers px near 50."""

    def log_likelihood(self, x, ctx):
        return -0.5 * ((x[:, 0] - 50.0) / 20.0) ** 2


def _lg_frames(n=4):
    return [FrameContext(t + 1, measurements=np.array([0.1 * t])) for t in range(n)]


def _two_parts():
    return FactorGraph(
        [Variable("a", 1), Variable("b", 1)],
        [GaussianPrior("a", mean=[1.0], cov=1.0), LinearGaussianTransition("a", F=[[1.0]], Q=0.1),
         LinearGaussianLikelihood("a", H=[[1.0]], R=[[4.0]]),
         GaussianPrior("b", mean=[0.0], cov=1.0), LinearGaussianTransition("b", F=[[1.0]], Q=0.1),
         LinearGaussianLikelihood("b", H=[[1.0]], R=[[0.5]]),
         AffineCoupling("a", "b", offset=[0.0], std=[1.0])])


def _parts_frames(n=4):
    return [FrameContext(t + 1, measurements={"a": np.array([0.5]), "b": np.array([0.0])})
            for t in range(n)]


def _vb_akf():
    return FactorGraph(
        [Variable("x", 4), Variable("noise", 2, role="noise")],
        [GaussianPrior("x", mean=np.zeros(4), cov=np.eye(4)),
         LinearGaussianTransition("x", F=F, Q=0.01 * np.eye(4)),
         LinearGaussianLikelihood("x", H=H, R=np.eye(2)),
         InverseGammaPrior("noise", sigma=[1.0, 1.0], alpha=10.0),
         NoiseForgetting("noise", rho=0.9, alpha_min=2.0),
         VBNoise("noise", "x", tol=1e-6, max_iter=5)])


def _set_frames(n=6):
    rng = np.random.default_rng(3)
    truth = np.array([[40.0, 60.0], [120.0, 80.0]])
    return [FrameContext(t + 1, measurements=truth + [2.0 * t, 0.0] + rng.normal(0, 2, (2, 2)))
            for t in range(n)]


def _phd(module):
    g = module.build_graph(module.Params(area=200.0 * 200.0, sigma=3.0, birth_rate=0.2,
                                         particles_per_target=200, n_birth=50))
    return g.with_factors(Bump("targets", name="bump"))


def _plate_frames(n=6):
    from pgm.observation.detections import Detections
    from pgm.synthetic.scenes import multi_target_scene

    seq = multi_target_scene(seed=1, n_frames=n, n_objects=2, occluder=False)
    return [FrameContext(f, seq.frames[f - 1],
                         detections=Detections(seq.boxes_at(f)[1], np.ones(2)))
            for f in range(1, n + 1)]


def _plate(n_parts):
    from pgm.core.plate import Lifecycle
    from pgm.models import multi_pf

    return multi_pf.build_graph(multi_pf.Params(n_parts=n_parts, num_particles=20,
                                                lifecycle=Lifecycle(confirm_hits=1)))


def _sort(vb_noise: bool, motion: str = "kalman"):
    from pgm.models import sort

    return sort.build_graph(sort.Params(min_hits=1, vb_noise=vb_noise, motion=motion,
                                        num_particles=50))


CASES = {
    "particles": (lambda: linear_gaussian.build_graph(linear_gaussian.Params()), _lg_frames, {}),
    "kalman": (lambda: linear_gaussian.build_graph(linear_gaussian.Params()), _lg_frames,
               {"belief_types": {"x": Gaussian}}),
    "pbp-mixture": (_two_parts, _parts_frames, {"fusion": "mixture"}),
    "pbp-product": (_two_parts, _parts_frames, {"fusion": "product"}),
    "vb-akf": (_vb_akf, lambda: [FrameContext(t + 1, measurements=np.array([0.1 * t, 0.0]))
                                 for t in range(4)], {"belief_types": {"x": Gaussian}}),
    # the same noise node on a particle belief (mean-field VB with particles)
    "vb-particles": (_vb_akf, lambda: [FrameContext(t + 1, measurements=np.array([0.1 * t,
                                                                                  0.0]))
                                       for t in range(4)], {}),
    "phd": (lambda: _phd(phd), _set_frames, {}),
    # a plate's batched rules (births from detections, then every stage on K replicas)
    "plate": (lambda: _plate(1), _plate_frames, {}),
    # exact Kalman replicas with data association (SORT; Feng et al.'s (2015) VB noise per target)
    "sort": (lambda: _sort(vb_noise=False), _plate_frames, {}),
    "vb-sort": (lambda: _sort(vb_noise=True), _plate_frames, {}),
    "sort-particles": (lambda: _sort(vb_noise=False, motion="cv3"), _plate_frames, {}),
    "plate-parts": (lambda: _plate(2), _plate_frames, {}),
    "vb-phd": (lambda: _phd(vb_phd), _set_frames, {}),
}


def test_every_registered_rule_passes_its_contract():
    calls = Counter()
    rules = checked(DEFAULT_RULES, calls)
    for name, (graph, frames, kwargs) in CASES.items():
        eng = Engine(graph(), np.random.default_rng(0), rules=rules, num_particles=64, **kwargs)
        for frame in frames():
            eng.step(frame)
        assert eng.t > 0, name
    registered = {key for key, _ in DEFAULT_RULES.items()}
    missing = sorted((getattr(k, "__name__", k), b.__name__) for k, b in registered - set(calls))
    assert not missing, f"registered rules with no conformance case: {missing}"


def test_checked_engine_gives_the_same_results_as_the_plain_one():
    graph = linear_gaussian.build_graph(linear_gaussian.Params())
    plain = Engine(graph, np.random.default_rng(5), num_particles=64)
    check = Engine(graph, np.random.default_rng(5), num_particles=64,
                   rules=checked(DEFAULT_RULES))
    for frame in _lg_frames(6):
        a, b = plain.step(frame), check.step(frame)
        np.testing.assert_array_equal(a.estimates["x"], b.estimates["x"])


def _tempering_resampler(engine, factor, frame):
    """A scratch rule breaking the contract: tempers, then resamples in place."""
    var = factor.variables[0]
    b = engine.beliefs[var]
    ll = 0.5 * factor.log_likelihood(b.x, frame)
    rs = b.reweight(ll).normalized().resample(engine.rng, engine.resampler)
    engine.beliefs[var] = rs
    return ll


def _in_place_mover(engine, factor, frame):
    b = engine.beliefs[factor.variables[0]]
    ll = factor.log_likelihood(b.x, frame)
    b.x[:] = b.x[np.argsort(ll)]  # reorders particles inside the same object
    return np.sort(ll)


def _returns_nothing(engine, factor, frame):
    engine.beliefs[factor.variables[0]] = engine.beliefs[factor.variables[0]].reweight(
        factor.log_likelihood(engine.beliefs[factor.variables[0]].x, frame))


@pytest.mark.parametrize("bad_rule", [_tempering_resampler, _returns_nothing])
def test_the_engine_refuses_a_likelihood_rule_that_moves_particles(bad_rule):
    rules = DEFAULT_RULES.copy()
    rules.register(LinearGaussianLikelihood, Particles)(bad_rule)
    eng = Engine(linear_gaussian.build_graph(linear_gaussian.Params()), np.random.default_rng(0),
                 rules=rules, num_particles=50)
    with pytest.raises(RuleContractError, match="likelihood"):
        eng.step(_lg_frames(1)[0])


def test_the_checked_table_catches_a_rule_that_reorders_in_place():
    rules = DEFAULT_RULES.copy()
    rules.register(LinearGaussianLikelihood, Particles)(_in_place_mover)
    eng = Engine(linear_gaussian.build_graph(linear_gaussian.Params()), np.random.default_rng(0),
                 rules=checked(rules), num_particles=50)
    with pytest.raises(RuleContractError, match="never moves, reorders or resamples"):
        eng.step(_lg_frames(1)[0])


def test_evidence_is_exactly_the_returned_increment():
    seen = {}

    def doubled(engine, factor, frame):
        out = 2.0 * factor.log_likelihood(engine.beliefs[factor.variables[0]].x, frame)
        seen["ll"] = out
        return out

    rules = DEFAULT_RULES.copy()
    rules.register(LinearGaussianLikelihood, Particles)(doubled)
    eng = Engine(linear_gaussian.build_graph(linear_gaussian.Params()), np.random.default_rng(0),
                 rules=rules, num_particles=50)
    eng.step(_lg_frames(1)[0])
    np.testing.assert_array_equal(eng.evidence["x"][1], seen["ll"])
