"""Proposals as rules of the engine: the oracle is the Kalman filter.

On the linear-Gaussian model the locally optimal proposal gives the Kalman filter's
means and marginal log-likelihood with a smaller Monte-Carlo variance than the bootstrap
filter at equal N; a wrong but broad proposal (mixed with the transition) stays
unbiased. Tolerances come from the spread of independent runs (standard errors).
"""

from __future__ import annotations

import numpy as np
import pytest

from pgm import FactorGraph, Plate
from pgm.core.frame import FrameContext
from pgm.factors import LinearGaussianProposal, ProposalFactor
from pgm.inference import Engine, kalman_filter, linear_gaussian_matrices
from pgm.models import linear_gaussian as lg

T, R, N = 25, 24, 100


@pytest.fixture(scope="module")
def problem():
    """Informative measurements (R = 0.02 against a position step of sd 0.18): where the
    bootstrap filter's weights degenerate and a proposal that sees the measurement pays."""
    params = lg.Params(R=np.array([[0.02]]))
    graph = lg.build_graph(params)
    _, ys = lg.simulate(np.random.default_rng(1), params, T)
    kf = kalman_filter(**linear_gaussian_matrices(graph, "x"), ys=ys)
    return params, graph, ys, kf


def _runs(graph, ys, seed=123):
    means, loglik = np.zeros((R, T, 2)), np.zeros(R)
    frames = [FrameContext(t + 1, measurements=ys[t]) for t in range(T)]
    for r, stream in enumerate(np.random.default_rng(seed).spawn(R)):
        recs = list(Engine(graph, stream, num_particles=N).run(frames))
        means[r] = [rec.estimates["x"] for rec in recs]
        loglik[r] = sum(rec.log_evidence["x"] for rec in recs)
    return means, loglik


def _with(graph, proposal):
    return graph.with_factors(proposal)


@pytest.mark.slow
def test_optimal_proposal_matches_kalman_with_less_variance(problem):
    p, graph, ys, kf = problem
    optimal = _with(graph, LinearGaussianProposal("x", F=p.F, Q=p.Q, H=p.H, R=p.R))
    m_boot, ll_boot = _runs(graph, ys)
    m_opt, ll_opt = _runs(optimal, ys)
    for means, loglik in ((m_boot, ll_boot), (m_opt, ll_opt)):
        se = means.std(axis=0, ddof=1) / np.sqrt(R)
        assert np.all(np.abs(means.mean(axis=0) - kf.filtered_means) < 6 * se + 1e-9)
        ll_se = loglik.std(ddof=1) / np.sqrt(R)
        assert abs(loglik.mean() - kf.marginal_log_likelihood) < 6 * ll_se + 1e-3
    # the variance of the log-likelihood estimate and the mean squared error of the
    # filtered means fall (the measured ratios are printed with -s)
    var_ratio = ll_opt.var(ddof=1) / ll_boot.var(ddof=1)
    mse = lambda m: float(np.mean((m - kf.filtered_means) ** 2))  # noqa: E731
    print(f"log-likelihood variance ratio optimal/bootstrap {var_ratio:.3f}; mean MSE "
          f"{mse(m_opt):.2e} / {mse(m_boot):.2e}")
    assert var_ratio < 0.5
    assert mse(m_opt) < mse(m_boot)


@pytest.mark.slow
def test_a_broad_wrong_proposal_stays_unbiased(problem):
    p, graph, ys, kf = problem
    broad = _with(graph, LinearGaussianProposal("x", F=p.F, Q=p.Q, inflate=9.0, fraction=0.5))
    means, loglik = _runs(broad, ys, seed=7)
    se = means.std(axis=0, ddof=1) / np.sqrt(R)
    assert np.all(np.abs(means.mean(axis=0) - kf.filtered_means) < 6 * se + 1e-9)
    ll_se = loglik.std(ddof=1) / np.sqrt(R)
    assert abs(loglik.mean() - kf.marginal_log_likelihood) < 6 * ll_se + 1e-3


def test_a_proposal_runs_per_replica_in_a_plate_as_in_a_single_graph(problem):
    p, graph, ys, _ = problem
    g = _with(graph, LinearGaussianProposal("x", F=p.F, Q=p.Q, H=p.H, R=p.R, fraction=0.7))
    plated = FactorGraph(list(g.variables.values()), list(g.factors.values()), name=g.name,
                         meta=g.meta, plates=[Plate("t", ("x",))])
    frames = [FrameContext(t + 1, measurements=ys[t]) for t in range(8)]
    single = Engine(g, np.random.default_rng(3), num_particles=N)
    plate = Engine(plated, 0, num_particles=N)
    for i, frame in enumerate(frames):
        a = single.step(frame)
        if i == 0:
            plate.add(None, frame, rngs=[np.random.default_rng(3)])
            continue
        rec = plate.step(frame, lifecycle=False)
        assert np.array_equal(a.estimates["x"], rec.estimates["x"][0])
        assert a.log_evidence["x"] == rec.log_evidence["x"][0]


def test_bad_proposals_are_refused():
    with pytest.raises(ValueError, match="fraction"):
        LinearGaussianProposal("x", F=[[1.0]], Q=1.0, fraction=0.0)
    from pgm import GaussianPrior, Variable

    g = FactorGraph([Variable("x", 1)], [GaussianPrior("x", mean=[0.0], cov=1.0),
                                         LinearGaussianProposal("x", F=[[1.0]], Q=1.0)])
    with pytest.raises(ValueError, match="no transition"):
        Engine(g, 0)


def test_a_proposal_saves_loads_and_draws(problem, tmp_path):
    p, graph, _, _ = problem
    g = _with(graph, LinearGaussianProposal("x", F=p.F, Q=p.Q, H=p.H, R=p.R, fraction=0.5))
    g.save(tmp_path / "m.json")
    assert FactorGraph.load(tmp_path / "m.json") == g
    g.draw(tmp_path / "m.png")
    assert (tmp_path / "m.png").stat().st_size > 1000


class _PositionFromTheMeasurement(ProposalFactor):
    """A user's proposal of the position only (component 0) from a broad Gaussian around
    the measurement; the velocity comes from the transition."""

    def __init__(self, variable, *, std, fraction=0.5, name=None):
        super().__init__(variable, fraction=fraction, columns=(0,), name=name)
        self.std = float(std)

    def params(self):
        return {"std": self.std, "fraction": self.fraction}

    def sample(self, rng, ctx, *past):
        y = float(np.asarray(ctx.measurements).reshape(-1)[0])
        out = np.zeros_like(past[0])
        out[:, 0] = y + self.std * rng.standard_normal(len(out))
        return out

    def log_prob(self, x, ctx, *past):
        y = float(np.asarray(ctx.measurements).reshape(-1)[0])
        z = (x[:, 0] - y) / self.std
        return -0.5 * z * z - np.log(self.std) - 0.5 * np.log(2 * np.pi)


@pytest.mark.slow
def test_a_proposal_of_some_components_stays_unbiased(problem):
    """A proposal of the position alone (the velocity drawn from the transition; the
    weights corrected by the transition's marginal density of the position) gives the
    Kalman filter's means and log-likelihood, within the runs' standard errors, on a
    model whose transition draws position and velocity independently."""
    p, graph, ys, _ = problem
    Q = np.diag(np.diag(p.Q))  # position and velocity steps independent
    params = lg.Params(R=p.R, Q=Q)
    diag = lg.build_graph(params)
    kf = kalman_filter(**linear_gaussian_matrices(diag, "x"), ys=ys)
    means, loglik = _runs(diag.with_factors(_PositionFromTheMeasurement(
        "x", std=2.0 * float(np.sqrt(p.R[0, 0])))), ys, seed=11)
    se = means.std(axis=0, ddof=1) / np.sqrt(R)
    assert np.all(np.abs(means.mean(axis=0) - kf.filtered_means) < 6 * se + 1e-9)
    ll_se = loglik.std(ddof=1) / np.sqrt(R)
    assert abs(loglik.mean() - kf.marginal_log_likelihood) < 6 * ll_se + 1e-3


def test_marginal_densities_of_some_components():
    """The transitions' marginal densities of some components: a Gaussian block of a
    linear-Gaussian step; the damped step (with its jump mixture, and in box heights) of
    AR(2) centres, also under a scale step; couplings and sizes are refused."""
    from scipy.stats import norm

    from pgm.factors import AR2Transition, LinearGaussianTransition

    rng = np.random.default_rng(0)
    x1, x2, x = rng.normal(size=(3, 50, 4)) * 5 + np.array([100, 80, 40, 60])
    lgt = LinearGaussianTransition("v", F=np.eye(4), Q=np.diag([1.0, 2.0, 3.0, 4.0]))
    np.testing.assert_allclose(lgt.log_prob_columns(x, (1,), x1),
                               norm(x1[:, 1], np.sqrt(2.0)).logpdf(x[:, 1]))
    coupled = LinearGaussianTransition("v", F=np.eye(2), Q=[[1.0, 0.5], [0.5, 1.0]])
    with pytest.raises(ValueError, match="not drawn independently"):
        coupled.log_prob_columns(x[:, :2], (0,), x1[:, :2])
    ar = AR2Transition("v", noise_std=[2.0, 3.0, 0.0, 0.0], damping=0.5, scale_noise=0.01,
                       reference_size=(40.0, 60.0), jump_prob=0.3, jump_scale=10.0)
    mu = x1[:, :2] + 0.5 * (x1[:, :2] - x2[:, :2])
    narrow = norm(mu, [2.0, 3.0]).logpdf(x[:, :2]).sum(1)
    wide = norm(mu, [20.0, 30.0]).logpdf(x[:, :2]).sum(1)
    np.testing.assert_allclose(ar.log_prob_columns(x, (0, 1), x1, x2),
                               np.logaddexp(np.log(0.7) + narrow, np.log(0.3) + wide))
    rel = AR2Transition("v", noise_std=[0.05, 0.05, 0.0, 0.0], relative=True)
    np.testing.assert_allclose(rel.log_prob_columns(x, (0,), x1, x2),
                               norm(x1[:, 0] + 0.5 * (x1[:, 0] - x2[:, 0]),
                                    0.05 * x1[:, 3]).logpdf(x[:, 0]))
    with pytest.raises(ValueError, match="sizes of the scale step"):
        ar.log_prob_columns(x, (0, 2), x1, x2)


class _EveryOtherFrame(LinearGaussianProposal):
    """The locally optimal proposal on even frames only (``prepare`` returns 0 on odd
    ones), or a share ``bad`` on every frame."""

    def __init__(self, *args, bad=None, **kw):
        super().__init__(*args, **kw)
        self.bad = bad
        self.calls = []

    def prepare(self, ctx, past, *, confidence, factors):
        self.calls.append((ctx.index, confidence, sorted(factors)))
        if self.bad is not None:
            return self.bad
        return self.fraction if ctx.index % 2 == 0 else 0.0


def test_prepare_sets_the_share_per_frame_and_stays_unbiased(problem):
    """A share of 0 in a frame is the bootstrap filter there; over the frames the
    estimates stay the Kalman filter's (within the runs' standard error)."""
    p, graph, ys, kf = problem
    prop = _EveryOtherFrame("x", F=p.F, Q=p.Q, H=p.H, R=p.R)
    g = _with(graph, prop)
    frames = [FrameContext(t + 1, measurements=ys[t]) for t in range(T)]
    engine = Engine(g, 3, num_particles=N)
    recs = list(engine.run(frames))
    assert "proposed" in str(recs[1].info) and "proposed" not in str(recs[2].info)
    calls = engine.graph.factors[prop.name].calls  # frames 2.., no confidence declared
    assert [c[0] for c in calls] == list(range(2, T + 1))
    assert all(c[1] is None and prop.name in c[2] for c in calls)
    means, loglik = _runs(g, ys)
    se = means.std(axis=0, ddof=1) / np.sqrt(R)  # the same bounds as the tests above
    assert np.all(np.abs(means.mean(axis=0) - kf.filtered_means) < 6 * se + 1e-9)
    ll_se = loglik.std(ddof=1) / np.sqrt(R)
    assert abs(loglik.mean() - kf.marginal_log_likelihood) < 6 * ll_se + 1e-3
    for bad in (1.5, float("nan"), -0.1):
        g = _with(graph, _EveryOtherFrame("x", F=p.F, Q=p.Q, H=p.H, R=p.R, bad=bad))
        with pytest.raises(ValueError, match=r"prepare\(\)"):
            list(Engine(g, 0, num_particles=N).run(frames[:3]))
