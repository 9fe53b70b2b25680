"""Regularised resampling of a PHD intensity (Liu–West kernel per measurement): the kernel
keeps each target's mean and covariance, leaves unclaimed mass alone, travels with the
saved graph, and spreads an impoverished cloud so that it follows its target better."""

import json

import numpy as np
import pytest

from pgm import FactorGraph, FrameContext
from pgm.factors.multitarget import PHDLikelihood
from pgm.inference import Engine
from pgm.inference.phd_regularise import kernel_bandwidth, measurement_moments, regularise
from pgm.models import phd


def _two_targets(rng, n=4000):
    """Two clouds far apart (one per measurement) and a few particles no measurement
    claims (a missed target's mass)."""
    mu = np.array([[1000.0, 2.0, -500.0, 1.0], [-800.0, -1.0, 300.0, 0.5]])
    cov = np.array([np.diag([25.0, 0.5, 16.0, 0.3]), np.diag([9.0, 0.2, 36.0, 0.4])])
    cov[0, 0, 2] = cov[0, 2, 0] = 12.0  # a correlated spread
    x = np.concatenate([rng.multivariate_normal(mu[k], cov[k], n // 2) for k in range(2)]
                       + [rng.normal(0.0, 1.0, (20, 4))])
    w = np.full(len(x), 1.0 / n)
    omega = np.zeros((len(x), 2))
    omega[: n // 2, 0] = 0.9 * w[: n // 2]   # measurement 0 explains the first cloud
    omega[n // 2: n, 1] = 0.9 * w[n // 2: n]
    omega[n:, 0] = 0.1 * w[n:]              # the rest: mostly missed
    return x, {"omega": omega, "w": w, "x": x}, mu, cov


def test_the_kernel_keeps_each_targets_mean_and_covariance():
    """Oracle (Liu–West): ``a x + (1 − a) μ + h A ε`` has the cloud's mean and covariance.
    Every particle resampled once (identity ancestry), so the only change is the kernel's:
    the moments after equal those before to within their Monte-Carlo error."""
    rng = np.random.default_rng(0)
    x, last, _, _ = _two_targets(rng)
    n = 4000
    idx = np.arange(len(x))
    W, mu, cov = measurement_moments(x, last["omega"])
    out = regularise(np.random.default_rng(1), x, idx, last, len(x), float(last["w"].sum()))
    h = kernel_bandwidth(len(x) * W / last["w"].sum(), 4)
    assert np.all((h > 0) & (h < 1))
    for k, rows in enumerate((slice(0, n // 2), slice(n // 2, n))):
        moved, before = out[rows], x[rows]
        assert not np.allclose(moved, before)  # every claimed particle moved
        sd = np.sqrt(np.diag(cov[k]))
        # the kernel's shift of the mean: h sd / sqrt(n/2) per component; 5 of them
        tol = 5 * h[k] * sd / np.sqrt(n // 2)
        np.testing.assert_array_less(np.abs(moved.mean(0) - before.mean(0)), tol)
        # covariance: Var of a sample variance ~ 2 σ⁴ / n, relative 5 sqrt(2 / (n/2))
        rel = np.abs(np.cov(moved.T) - np.cov(before.T)) / np.outer(sd, sd)
        assert rel.max() < 5 * np.sqrt(2.0 / (n // 2)), rel
    np.testing.assert_array_equal(out[n:], x[n:])  # unclaimed mass: left as it was


def test_measurement_moments_are_the_weighted_moments():
    """Oracle: the one-product moments equal ``np.average`` and ``np.cov`` with weights,
    far from the origin too (the states are taken relative to one of them)."""
    rng = np.random.default_rng(2)
    x = rng.normal(size=(300, 3)) * [2.0, 0.5, 1.0] + [1e5, -3e4, 7.0]
    omega = rng.random((300, 4)) ** 4
    omega[:, 3] = 0.0  # a measurement nobody is associated with
    W, mu, cov = measurement_moments(x, omega)
    for k in range(3):
        np.testing.assert_allclose(W[k], omega[:, k].sum())
        np.testing.assert_allclose(mu[k], np.average(x, axis=0, weights=omega[:, k]))
        np.testing.assert_allclose(cov[k], np.cov(x.T, aweights=omega[:, k], bias=True),
                                   rtol=1e-7, atol=1e-9)
    assert W[3] == 0 and np.all(cov[3] == 0)


def test_regularise_travels_with_the_graph_and_checks_its_value():
    """``regularise`` is saved (only when on: older graphs save as before), loads to the
    same run, and a value other than True or False is a one-line ValueError."""
    H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    assert "regularise" not in PHDLikelihood("t", H=H, R=[1.0, 1.0]).params()
    g = phd.build_graph(phd.Params(regularise=True))
    loaded = FactorGraph.from_dict(json.loads(json.dumps(g.to_dict())))
    assert loaded == g
    assert [f.regularise for f in loaded.factors.values()
            if isinstance(f, PHDLikelihood)] == [True]
    with pytest.raises(ValueError, match="regularise"):
        PHDLikelihood("t", H=H, R=[1.0, 1.0], regularise="yes")


def _walkers(rng, steps=40):
    """Three targets at constant velocity, detected with p_D 0.95 and σ 3, clutter 4."""
    starts = np.array([[20.0, 1.0, 20.0, 0.6], [150.0, -0.8, 60.0, 0.5],
                       [80.0, 0.3, 160.0, -1.0]])
    truth, meas = [], []
    for t in range(steps):
        pos = starts[:, [0, 2]] + t * starts[:, [1, 3]]
        truth.append(pos)
        z = [p + 3.0 * rng.standard_normal(2) for p in pos if rng.random() < 0.95]
        z += list(rng.uniform(0, 200, size=(rng.poisson(4), 2)))
        meas.append(np.array(z).reshape(-1, 2))
    return truth, meas


def test_a_small_cloud_follows_its_target_better_when_regularised():
    """With few particles per target and little process noise the resampled cloud
    collapses (sample impoverishment); regularised, the extracted positions are closer
    to the truth. Measured (seeds 0-3, 40 particles per target): mean error 3.47 px
    plain against 2.56 regularised (378 and 393 estimates; the standard error of each
    mean about 0.09 px, so the difference is about ten of them)."""
    errors = {False: [], True: []}
    for seed in range(4):
        truth, meas = _walkers(np.random.default_rng(100 + seed))
        for reg in (False, True):
            params = phd.Params(area=200.0**2, sigma=3.0, q=0.01, clutter_rate=4.0,
                                p_detect=0.95, birth_velocity_std=1.0, n_birth=20,
                                particles_per_target=40, min_particles=40, regularise=reg)
            eng = Engine(phd.build_graph(params), np.random.default_rng(seed))
            for t, z in enumerate(meas):
                est = eng.step(FrameContext(t + 1, measurements=z)).estimates["targets"]
                got = est["extracted"][:, [0, 2]]
                if t >= 5 and len(got):
                    d = np.linalg.norm(got[:, None] - truth[t][None], axis=2).min(axis=1)
                    errors[reg].extend(d[d < 15.0])  # estimates of a target, not clutter
    plain, reg = np.mean(errors[False]), np.mean(errors[True])
    assert reg < plain, (plain, reg)
