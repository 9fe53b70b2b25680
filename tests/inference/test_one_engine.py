"""One engine for every graph: a plate is a batch axis of beliefs under the same rule table.

Oracles: one replica of a plate equals the engine on the graph without the plate, bit for
bit, for every shipped single-target graph (particle, part-graph mixture and product,
single-object with its learned filter, Kalman with and without a VB noise node); a
user's rule registered for a factor class runs inside a plate; a factor kind no stage
runs is refused at construction.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_conformance import _vb_akf  # the VB-AKF graph of the conformance cases

from pgm import FactorGraph, Plate, Variable
from pgm.core.batched import (
    BatchedGaussian,
    BatchedInverseGamma,
    BatchedParticles,
    Replicated,
    batched_type,
)
from pgm.core.beliefs import Particles
from pgm.core.expfam import Gaussian, InverseGamma
from pgm.core.frame import FrameContext
from pgm.factors import (
    GaussianPrior,
    LikelihoodFactor,
    LinearGaussianTransition,
)
from pgm.inference import DEFAULT_RULES, Engine
from pgm.inference.settings import EngineSettings
from pgm.models import colour_pf, linear_gaussian, part_graph, single_object
from pgm.synthetic.scenes import multi_target_scene

N = 40


def _plated(graph: FactorGraph) -> FactorGraph:
    """The same declaration with every variable in one plate."""
    return FactorGraph(list(graph.variables.values()), list(graph.factors.values()),
                       name=graph.name, meta=graph.meta,
                       plates=[Plate("target", tuple(graph.variables))])


@pytest.fixture(scope="module")
def scene():
    return multi_target_scene(seed=3, n_frames=12, n_objects=2, occluder=False)


def _box(scene) -> tuple[float, float, float, float]:
    x, y, w, h = scene.box(0, 1)
    return (x + w / 2, y + h / 2, w, h)


def _image_frames(scene):
    return [FrameContext(f, scene.frames[f - 1]) for f in range(1, scene.n_frames + 1)]


def _lg_frames(n=12, dim=1):
    rng = np.random.default_rng(1)
    return [FrameContext(t + 1, measurements=rng.normal(0.1 * t, 0.7, dim)) for t in range(n)]


def _cases(scene):
    box = _box(scene)
    lg = linear_gaussian.build_graph(linear_gaussian.Params())
    return {
        "colour-pf": (colour_pf.build_graph(colour_pf.Params(init_box=box, num_particles=N)),
                      _image_frames(scene), {}),
        "part-graph-mixture": (part_graph.build_graph(part_graph.Params(
            init_box=box, n_parts=3, num_particles=N)), _image_frames(scene), {}),
        "part-graph-product": (part_graph.build_graph(part_graph.Params(
            init_box=box, n_parts=2, num_particles=N)), _image_frames(scene),
            {"fusion": "product"}),
        # couplings that learn per replica, on the batched mixture path (one message
        # particle per particle: the engine's default settings)
        "part-graph-learned-offsets": (part_graph.build_graph(part_graph.Params(
            init_box=box, n_parts=2, num_particles=N, adapt_offsets=True)),
            _image_frames(scene), {"settings": EngineSettings(num_particles=N)}),
        "single-object": (single_object.build_graph(single_object.Params(
            init_box=box, num_particles=N)), _image_frames(scene), {}),
        "linear-gaussian-particles": (lg, _lg_frames(), {"num_particles": 200}),
        "linear-gaussian-kalman": (lg, _lg_frames(), {"belief_types": {"x": Gaussian}}),
        "vb-akf": (_vb_akf(), _lg_frames(dim=2), {"belief_types": {"x": Gaussian}}),
    }


CASE_NAMES = ["colour-pf", "part-graph-mixture", "part-graph-product",
              "part-graph-learned-offsets", "single-object",
              "linear-gaussian-particles", "linear-gaussian-kalman", "vb-akf"]


def _rows(belief):
    """Arrays that define a belief (particles and weights, or a Gaussian's moments)."""
    if isinstance(belief, Particles):
        return [belief.x, belief.log_weights, *belief.history]
    if isinstance(belief, Gaussian):
        return [belief.mean(), belief.cov()]
    if isinstance(belief, InverseGamma):
        return [np.asarray(belief.alpha), np.asarray(belief.beta)]
    raise AssertionError(type(belief))


@pytest.mark.parametrize("case", CASE_NAMES)
def test_one_replica_is_the_engine_without_the_plate_bit_for_bit(scene, case):
    graph, frames, kwargs = _cases(scene)[case]
    single = Engine(graph, np.random.default_rng(7), **kwargs)
    plate = Engine(_plated(graph), np.random.default_rng(99), **kwargs)
    assert plate.schedule.phases[-1][0] == "associate"
    for i, frame in enumerate(frames):
        a = single.step(frame)
        if i == 0:  # the replica is started on the first frame, as the engine starts
            plate.add(None, frame, rngs=[np.random.default_rng(7)])
            est = {v: plate.replicas.est[v] for v in graph.variables}
        else:
            est = plate.step(frame, lifecycle=False).estimates
        for v in graph.variables:
            assert np.array_equal(np.asarray(a.estimates[v]), np.asarray(est[v])[0]), (case, v)
    for v in graph.variables:
        b = plate.beliefs[v]
        assert isinstance(b, batched_type(type(single.beliefs[v])))
        for x, y in zip(_rows(single.beliefs[v]), _rows(b.row(0)), strict=True):
            assert np.array_equal(x, y), (case, v)


@pytest.mark.parametrize("case", ["part-graph-product", "vb-akf"])
def test_independent_replicas_are_separate_runs(scene, case):
    """Replicas whose rules run per replica (product fusion, VB per target) each equal a
    separate run with the same generator."""
    graph, frames, kwargs = _cases(scene)[case]
    seeds = [3, 4, 5]
    plate = Engine(_plated(graph), 0, **kwargs)
    for i, frame in enumerate(frames):
        if i == 0:
            plate.add(None, frame, rngs=[np.random.default_rng(s) for s in seeds], count=3)
        else:
            plate.step(frame, lifecycle=False)
    for k, seed in enumerate(seeds):
        single = Engine(graph, np.random.default_rng(seed), **kwargs)
        for frame in frames:
            single.step(frame)
        for v in graph.variables:
            for x, y in zip(_rows(single.beliefs[v]), _rows(plate.beliefs[v].row(k)),
                            strict=True):
                assert np.array_equal(x, y), (case, k, v)


class Prefer(LikelihoodFactor):
    """A user's likelihood factor with its own rule (the class's default would be used
    otherwise): prefers position near ``target``."""

    def __init__(self, variable, target=2.0, name=None):
        super().__init__(variable, name=name)
        self.target = float(target)

    def params(self):
        return {"target": self.target}

    def log_likelihood(self, x, ctx):
        raise AssertionError("the registered rule, not log_likelihood, must run")


def test_a_user_rule_registered_for_a_factor_class_runs_inside_a_plate():
    rules = DEFAULT_RULES.copy()
    calls = []

    @rules.register(Prefer, Particles)
    def prefer(engine, factor, frame):
        calls.append(engine.rng)
        x = engine.beliefs[factor.variables[0]].x
        return -0.5 * (x[:, 0] - factor.target) ** 2

    g = linear_gaussian.build_graph(linear_gaussian.Params())
    g = g.with_factors(Prefer("x", target=5.0, name="prefer"))
    plate = Engine(_plated(g), 0, rules=rules, num_particles=500)
    rngs = [np.random.default_rng(s) for s in (1, 2)]
    for i, frame in enumerate(_lg_frames(6)):
        if i == 0:
            plate.add(None, frame, rngs=rngs, count=2)
        else:
            plate.step(frame, lifecycle=False)
    assert len(calls) == 2 * 6 and calls[:2] == rngs  # once per replica, its own generator
    single = Engine(g, np.random.default_rng(2), rules=rules, num_particles=500)
    for frame in _lg_frames(6):
        single.step(frame)
    assert np.array_equal(single.beliefs["x"].x, plate.beliefs["x"].x[1])


def test_plate_beliefs_are_batched_and_operations_match_particles():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(3, 50, 2))
    lw = rng.normal(size=(3, 50))
    b = BatchedParticles(x, lw, (x + 1,))
    for k in range(3):
        p = Particles(x[k], lw[k], (x[k] + 1,))
        assert np.array_equal(b.row(k).x, p.x)
        assert b.log_mass[k] == p.log_mass
        assert np.array_equal(b.weights[k], p.weights)
        assert b.ess[k] == p.ess
        assert np.array_equal(b.mean()[k], p.mean())
        n, _ = b.normalized()
        assert np.array_equal(n.log_weights[k], p.normalized().log_weights)
    from pgm.inference.resampling import systematic

    gens = [np.random.default_rng(s) for s in range(3)]
    r = b.resample_rows(gens, systematic, 50, np.array([0, 2]))
    p0 = Particles(x[0], lw[0], (x[0] + 1,)).resample(np.random.default_rng(0), systematic, 50)
    assert np.array_equal(r.x[0], p0.x) and np.array_equal(r.history[0][0], p0.history[0])
    assert np.array_equal(r.x[1], x[1])  # not resampled
    assert np.array_equal(b.select([2, 0]).x, x[[2, 0]])
    assert b.concat(b.select([1])).K == 4
    assert batched_type(Gaussian).row_type is Gaussian
    assert batched_type(Gaussian) is BatchedGaussian  # means (K, d), covariances (K, d, d)
    g = BatchedGaussian.stack([Gaussian(np.arange(2.0) + k, np.eye(2) * (k + 1)) for k in range(3)])
    assert np.array_equal(g.row(2).mean(), [2.0, 3.0]) and np.array_equal(g.row(1).cov(), 2 * np.eye(2))
    assert g.select([2, 0]).concat(g).K == 5 and np.array_equal(g.select([2]).mean(), g.mean()[[2]])
    assert batched_type(InverseGamma) is BatchedInverseGamma
    q = BatchedInverseGamma.stack([InverseGamma.from_sigma([1.0, 2.0], 5.0)] * 2)
    np.testing.assert_array_equal(q.forget(0.8, 2.0).row(1).alpha,
                                  InverseGamma.from_sigma([1.0, 2.0], 5.0).forget(0.8, 2.0).alpha)
    other = type("OtherBelief", (), {})  # any other belief: one object per replica
    assert issubclass(batched_type(other), Replicated) and batched_type(other).row_type is other


def test_a_factor_kind_no_stage_runs_is_refused():
    from pgm.factors.plates import MutualExclusion

    g = colour_pf.build_graph(colour_pf.Params(init_box=(50, 50, 20, 20)))
    with pytest.raises(ValueError, match="in no plate"):
        g.with_factors(MutualExclusion("object"))
    plated = FactorGraph(list(g.variables.values()),
                         list(g.factors.values()) + [MutualExclusion("object")],
                         plates=[Plate("t", ("object",))])
    eng = Engine(plated, 0)  # the interaction factor is a scheduled stage
    assert any(stage == "interaction" and items for stage, items in eng.schedule.phases)


def test_variables_outside_the_plate_are_refused():
    g = linear_gaussian.build_graph(linear_gaussian.Params())
    y = [GaussianPrior("y", mean=[0.0], cov=1.0), LinearGaussianTransition("y", F=[[1.0]], Q=1.0)]
    half = FactorGraph(list(g.variables.values()) + [Variable("y", 1)],
                       list(g.factors.values()) + y, plates=[Plate("t", ("x",))])
    with pytest.raises(ValueError, match="outside the plate"):
        Engine(half, 0)


def test_a_particles_subclass_without_a_batched_form_is_refused_in_a_plate():
    class MyParticles(Particles):
        pass

    g = colour_pf.build_graph(colour_pf.Params(init_box=(50, 50, 20, 30)))
    with pytest.raises(ValueError, match="MyParticles has no batched form"):
        Engine(_plated(g), 0, belief_types={"object": MyParticles})

