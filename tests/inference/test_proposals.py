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
from pgm.factors import LinearGaussianProposal
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
