"""The generic engine: Kalman oracle, dispatch, schedule, hooks, reproducibility."""

import numpy as np
import pytest

from pgm import (
    AR2Transition,
    CouplingFactor,
    Factor,
    FactorGraph,
    FrameContext,
    GaussianPrior,
    LinearGaussianLikelihood,
    Particles,
    Variable,
)
from pgm.inference import DEFAULT_RULES, Engine, kalman_filter, linear_gaussian_matrices
from pgm.models import linear_gaussian as lg

T = 50


def _frames(ys):
    return [FrameContext(t + 1, measurements=ys[t]) for t in range(len(ys))]


@pytest.fixture(scope="module")
def lg_problem():
    params = lg.Params()
    graph = lg.build_graph(params)
    _, ys = lg.simulate(np.random.default_rng(1), params, T)
    kf = kalman_filter(**linear_gaussian_matrices(graph, "x"), ys=ys)
    return graph, ys, kf


@pytest.mark.slow
@pytest.mark.parametrize("scheme", ["systematic", "multinomial", "stratified", "residual"])
def test_particle_filter_matches_kalman(lg_problem, scheme):
    """Replicated PF runs: the mean over R runs is within 6 standard errors of the KF mean.

    The standard error is the spread of the R independent runs / sqrt(R), so the
    tolerance comes from the Monte-Carlo error itself, at every time step and for both
    state components; the same holds for the marginal log-likelihood.
    """
    graph, ys, kf = lg_problem
    R, N = 16, 2000
    means = np.zeros((R, T, 2))
    loglik = np.zeros(R)
    for r, stream in enumerate(np.random.default_rng(123).spawn(R)):
        eng = Engine(graph, stream, num_particles=N, resampling=scheme)
        recs = list(eng.run(_frames(ys)))
        means[r] = [rec.estimates["x"] for rec in recs]
        loglik[r] = sum(rec.log_evidence["x"] for rec in recs)
    se = means.std(axis=0, ddof=1) / np.sqrt(R)
    err = np.abs(means.mean(axis=0) - kf.filtered_means)
    assert np.all(err < 6 * se + 1e-9), f"max z = {np.max(err / se):.2f}"
    # each single run is also close: within 6 sqrt(var / N_eff_min) with N_eff >= N/2
    sd = np.sqrt(np.diagonal(kf.filtered_covs, axis1=1, axis2=2))
    assert np.all(np.abs(means - kf.filtered_means) < 6 * sd / np.sqrt(N / 4))
    ll_se = loglik.std(ddof=1) / np.sqrt(R)
    assert abs(loglik.mean() - kf.marginal_log_likelihood) < 6 * ll_se + 1e-3


def test_missing_measurements_predict_only(lg_problem):
    graph, ys, kf_full = lg_problem
    ys_gap = ys.copy()
    ys_gap[10:20] = np.nan
    kf = kalman_filter(**linear_gaussian_matrices(graph, "x"), ys=ys_gap)
    frames = [FrameContext(t + 1, measurements=None if np.isnan(ys_gap[t, 0]) else ys_gap[t])
              for t in range(T)]
    R, N = 12, 2000
    means = np.array([[rec.estimates["x"] for rec in Engine(graph, s, num_particles=N).run(frames)]
                      for s in np.random.default_rng(5).spawn(R)])
    se = means.std(axis=0, ddof=1) / np.sqrt(R)
    assert np.all(np.abs(means.mean(axis=0) - kf.filtered_means) < 6 * se + 1e-9)


def test_schedule_is_derived_from_the_graph(lg_problem):
    graph, _, _ = lg_problem
    eng = Engine(graph, np.random.default_rng(0), num_particles=10)
    assert [s for s, items in eng.schedule.first_frame if items] == \
        ["prior", "weight", "estimate", "resample"]
    assert [s for s, items in eng.schedule.phases if items] == \
        ["predict", "weight", "estimate", "resample"]
    assert "predict[transition:x]" in repr(eng.schedule)


def test_hooks_see_every_stage_in_order(lg_problem):
    graph, ys, _ = lg_problem
    eng = Engine(graph, np.random.default_rng(0), num_particles=50)
    seen = []
    for stage in ("prior", "predict", "weight", "inframe", "fuse", "estimate", "resample"):
        eng.add_hook(stage, lambda e, s, f, r: seen.append((f.index, s)))
    list(eng.run(_frames(ys[:2])))
    # stages with nothing to do still call their hooks, in schedule order
    assert seen == [(1, "prior"), (1, "weight"), (1, "inframe"), (1, "fuse"), (1, "estimate"),
                    (1, "resample"), (2, "predict"), (2, "weight"), (2, "inframe"),
                    (2, "fuse"), (2, "estimate"), (2, "resample")]
    with pytest.raises(ValueError, match="unknown stage"):
        eng.add_hook("bogus", lambda *a: None)


def test_seeded_runs_are_reproducible(lg_problem):
    graph, ys, _ = lg_problem
    a = [r.estimates["x"] for r in Engine(graph, np.random.default_rng(9), num_particles=300)
         .run(_frames(ys))]
    b = [r.estimates["x"] for r in Engine(graph, np.random.default_rng(9), num_particles=300)
         .run(_frames(ys))]
    c = [r.estimates["x"] for r in Engine(graph, np.random.default_rng(10), num_particles=300)
         .run(_frames(ys))]
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


class MyParticles(Particles):
    """A user's belief subclass: inherits every particle rule."""


def test_dispatch_walks_the_mro_and_missing_rules_fail_early(lg_problem):
    graph, ys, _ = lg_problem
    eng = Engine(graph, np.random.default_rng(0), num_particles=20,
                 belief_types={"x": MyParticles})
    rec = eng.step(_frames(ys)[0])
    assert type(rec.beliefs["x"]) is MyParticles

    class Stiff(CouplingFactor):
        def map(self, x_src, src):
            return x_src

        def log_prob(self, x_a, x_b):
            return -0.5 * ((x_a - x_b) ** 2).sum(-1)

    g2 = FactorGraph([Variable("a", 1), Variable("b", 1)],
                     [GaussianPrior("a", mean=[0.0]), GaussianPrior("b", mean=[0.0]),
                      Stiff("a", "b")])
    rules = DEFAULT_RULES.copy()
    rules.remove(CouplingFactor, Particles)
    with pytest.raises(ValueError, match="factor 'coupling:a-b': no inference rule for "
                                         r"\(Stiff, Particles\)"):
        Engine(g2, np.random.default_rng(0), rules=rules)

    class Bare(Factor):  # a likelihood by kind only: not a LikelihoodFactor
        kind = "likelihood"

    g3 = FactorGraph([Variable("a", 1)], [GaussianPrior("a", mean=[0.0]), Bare("a")])
    with pytest.raises(ValueError, match=r"no inference rule for \(Bare, Particles\)"):
        Engine(g3, np.random.default_rng(0))
    calls = []
    rules.register(Stiff, Particles)(
        lambda eng, f, frame, src, dst: calls.append((f.name, src, dst)))
    eng2 = Engine(g2, np.random.default_rng(0), rules=rules, fusion="product",
                  inframe_iterations=2)
    eng2.step(FrameContext(1))
    # a two-node tree: one message each way
    assert calls == [("coupling:a-b", "b", "a"), ("coupling:a-b", "a", "b")]
    # the default table is untouched
    from pgm.inference.pbp import coupling_message

    assert DEFAULT_RULES.lookup(Stiff, Particles) is coupling_message


def test_second_order_transition_starts_with_zero_velocity():
    g = FactorGraph([Variable("x", 1)],
                    [GaussianPrior("x", mean=[5.0]),
                     AR2Transition("x", noise_std=[0.0], damping=1.0),
                     LinearGaussianLikelihood("x", H=[[1.0]], R=1.0)])
    eng = Engine(g, np.random.default_rng(0), num_particles=4)
    eng.step(FrameContext(1))
    b = eng.step(FrameContext(2)).beliefs["x"]
    assert np.allclose(b.x, 5.0) and len(b.history) == 1
    # move the particles by hand: the AR(2) model extrapolates their velocity
    eng.beliefs["x"] = Particles(b.x + 1.0, b.log_weights, b.history)
    b3 = eng.step(FrameContext(3)).beliefs["x"]
    assert np.allclose(b3.x, 7.0)


def test_engine_argument_errors(lg_problem):
    graph, _, _ = lg_problem
    with pytest.raises(ValueError, match="positive integer"):
        Engine(graph, np.random.default_rng(0), num_particles=0)
    with pytest.raises(ValueError, match="seed must be an int"):
        Engine(graph, "0")
    with pytest.raises(ValueError, match="non-negative"):
        Engine(graph, -1)
    with pytest.raises(ValueError, match="ess_threshold"):
        Engine(graph, np.random.default_rng(0), ess_threshold=float("nan"))
    with pytest.raises(ValueError, match="unknown resampling scheme"):
        Engine(graph, np.random.default_rng(0), resampling="magic")
    with pytest.raises(ValueError, match="unknown variables"):
        Engine(graph, np.random.default_rng(0), num_particles={"y": 3})


def test_engine_takes_an_int_seed_as_numpy_does(lg_problem):
    graph, _, _ = lg_problem
    frame = FrameContext(1, measurements=np.array([0.3]))
    a = Engine(graph, 5).step(frame).beliefs["x"]
    b = Engine(graph, np.random.default_rng(5)).step(frame).beliefs["x"]
    assert np.array_equal(a.x, b.x)



def test_hooks_see_the_frame_as_filled_so_far():
    """A hook reads this frame's record as the stages fill it: the ESS after weighting,
    the particle-BP messages after the in-frame stage, the estimates after estimation."""
    from test_pbp import gaussian_tree  # same folder: on sys.path

    graph, y, _, _ = gaussian_tree(2)
    eng = Engine(graph, np.random.default_rng(0), num_particles=200)
    seen = {}

    def hook(engine, stage, frame, record):
        seen[stage] = (sorted(record.messages), sorted(record.ess), sorted(record.estimates))

    for stage in ("weight", "inframe", "estimate"):
        eng.add_hook(stage, hook)
    rec = eng.step(FrameContext(1, measurements={k: np.array([v]) for k, v in y.items()}))
    assert seen["weight"] == ([], ["a", "b"], [])
    assert seen["inframe"][0] == [("a", "b"), ("b", "a")]
    assert seen["estimate"][2] == ["a", "b"]
    assert sorted(rec.messages) == [("a", "b"), ("b", "a")]
