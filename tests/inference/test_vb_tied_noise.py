"""Tied (isotropic) noise components of the VB-PHD noise belief (``VBNoise(tie=...)``)."""

import numpy as np
import pytest

from pgm import FactorGraph, FrameContext, Variable
from pgm.core.expfam import Gaussian
from pgm.factors.multitarget import (
    IntensityPrior,
    InverseGammaPrior,
    NoiseForgetting,
    PHDLikelihood,
    VBNoise,
    constant_velocity,
)
from pgm.inference import Engine
from pgm.inference.phd import PHDState
from pgm.models import phd, vb_phd

F, Q = constant_velocity(1.0, 0.5, "pv")
H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])


def pooled_vb_akf(m0, P0, alpha0, beta0, z, n_iter):
    """One VB-AKF update with ONE variance shared by the k components, written out:
    ``α = α̂ + k/2``; repeat Kalman with ``R = (β/α) I``, ``β = β̂ + ½ Σ_i [(z − Hm)_i² +
    (H P Hᵀ)_ii]``."""
    k = z.size
    alpha, beta = alpha0 + 0.5 * k, beta0
    for _ in range(n_iter):
        S = H @ P0 @ H.T + np.eye(k) * beta / alpha
        K = P0 @ H.T @ np.linalg.inv(S)
        m = m0 + K @ (z - H @ m0)
        P = P0 - K @ S @ K.T
        beta = beta0 + 0.5 * np.sum((z - H @ m) ** 2 + np.diag(H @ P @ H.T))
    return m, alpha, beta


def one_target(m0, P0, sigma, tie, n_iter):
    return FactorGraph(
        [Variable("targets", 4, role="set"), Variable("noise", 2, role="noise")],
        [IntensityPrior("targets", mean=m0, cov=P0, mass=1.0),
         PHDLikelihood("targets", H=H, R=[sigma**2] * 2, p_detect=1.0, clutter_rate=0.0,
                       area=1e6, birth_rate=0.0, n_birth=10, velocity_indices=(1, 3),
                       min_particles=0),
         InverseGammaPrior("noise", sigma=[sigma] * 2, alpha=10.0),
         NoiseForgetting("noise", rho=0.8),
         VBNoise("noise", "targets", tol=0.0, max_iter=n_iter, tie=tie)])


@pytest.mark.slow
def test_tied_vb_phd_reduces_to_the_pooled_vb_akf():
    """One target, p_D = 1, no clutter, no birth: the tied fixed point matches the VB-AKF
    with one shared variance (α gains k/2 per measurement, not ½) within Monte-Carlo error;
    the untied filter does not (its α gains ½)."""
    m0, P0 = np.array([0.0, 1.0, 0.0, 0.5]), np.diag([9.0, 1.0, 9.0, 1.0])
    z = np.array([4.0, -5.0])
    n_iter = 4
    m_ref, a_ref, b_ref = pooled_vb_akf(m0, P0, 10.0, 90.0, z, n_iter)
    out = {}
    for tie in ((0, 0), None):
        means, r_hats = [], []
        for stream in np.random.default_rng(3).spawn(8):
            eng = Engine(one_target(m0, P0, 3.0, tie, n_iter), stream, num_particles=50_000)
            rec = eng.step(FrameContext(1, measurements=z[None]))
            res = eng.state.get("targets", PHDState).last
            means.append(res["w"] @ res["x"] / res["w"].sum())
            q = rec.beliefs["noise"]
            r_hats.append(q.r_hat())
            if tie is not None:
                assert q.alpha[0] == q.alpha[1] and q.beta[0] == q.beta[1]
                np.testing.assert_allclose(q.alpha, a_ref)
                elbo = np.array(rec.info["conjugate:noise-targets"]["elbo"])
                assert np.all(np.diff(elbo) >= -1e-9), elbo
        out[tie] = np.array(means), np.array(r_hats)
    means, r_hats = out[(0, 0)]
    se_m = means.std(axis=0, ddof=1) / np.sqrt(len(means))
    se_r = r_hats[:, 0].std(ddof=1) / np.sqrt(len(r_hats))
    assert np.all(np.abs(means.mean(axis=0) - m_ref) < 6 * se_m + 1e-9)
    assert abs(r_hats[:, 0].mean() - b_ref / a_ref) < 6 * se_r + 1e-9
    # the untied belief is a different fixed point (per-axis residuals, alpha + 1/2)
    assert np.max(np.abs(out[None][1].mean(axis=0) - b_ref / a_ref)) > 20 * se_r


def drifting_scene(rng, T, sig):
    """Three targets crossing a 400 x 400 field, p_D = 0.95, 2 clutter points per scan;
    detections with isotropic noise of std ``sig(t)``."""
    starts = [[50, 2, 60, 1], [300, -1.5, 100, 2], [200, 0, 350, -2]]
    L = np.linalg.cholesky(Q * 0.1)
    xs = [np.array(s, float) for s in starts]
    meas = []
    for t in range(T):
        if t:
            xs = [F @ x + L @ rng.standard_normal(4) for x in xs]
        z = [x[[0, 2]] + sig(t) * rng.standard_normal(2) for x in xs if rng.random() < 0.95]
        z += list(rng.uniform(0, 400, size=(rng.poisson(2), 2)))
        meas.append(np.array(z).reshape(-1, 2))
    return meas


def test_isotropic_vb_phd_learns_a_drifting_detection_noise():
    """Oracle: detections whose σ drifts 2 → 8 over 120 frames; the isotropic belief,
    started at σ = 5, follows it (mean |σ̂/σ − 1| over frames 30-120, seeds 0-1)."""
    T = 120
    sig = lambda t: 2.0 + 6.0 * t / T  # noqa: E731
    truth = np.array([sig(t) for t in range(T)])
    for seed in (0, 1):
        meas = drifting_scene(np.random.default_rng(seed), T, sig)
        params = vb_phd.Params(area=400.0**2, sigma=5.0, q=0.05, clutter_rate=2.0,
                               p_detect=0.95, birth_velocity_std=2.0, rho=0.9,
                               isotropic_noise=True)
        eng = Engine(vb_phd.build_graph(params), np.random.default_rng(seed))
        est = []
        for t, z in enumerate(meas):
            r = eng.step(FrameContext(t + 1, measurements=z)).estimates["noise"]
            assert r[0] == r[1]
            est.append(np.sqrt(r[0]))
        rel = np.abs(np.array(est)[30:] / truth[30:] - 1).mean()
        assert rel < 0.25, (seed, rel)
        # it rises with the truth (x2.2 between these windows; measured x1.5, lagging)
        assert np.mean(est[90:]) > 1.4 * np.mean(est[10:40])


def test_tie_settings_are_validated_saved_and_loaded(tmp_path):
    with pytest.raises(ValueError, match="tie"):
        VBNoise("noise", "targets", tie=[0.5, 1.0])
    g = vb_phd.build_graph(vb_phd.Params(isotropic_noise=True))
    assert g.factors_of("noise", "conjugate")[0].params()["tie"] == [0, 0]
    g.save(tmp_path / "m.json")
    back = FactorGraph.load(tmp_path / "m.json")
    assert back == g and back.factors_of("noise", "conjugate")[0].tie == (0, 0)
    # an untied factor saves as before (no "tie" key)
    assert "tie" not in vb_phd.build_graph(vb_phd.Params()).factors_of(
        "noise", "conjugate")[0].params()
    # tie of the wrong length for the noise variable
    with pytest.raises(ValueError, match="tie"):
        FactorGraph([Variable("targets", 4, role="set"), Variable("noise", 2, role="noise")],
                    [PHDLikelihood("targets", H=H, R=[1.0, 1.0]),
                     InverseGammaPrior("noise", sigma=[1.0, 1.0]),
                     VBNoise("noise", "targets", tie=[0, 0, 1])])
    with pytest.raises(ValueError, match="rho"):
        vb_phd.build_graph(vb_phd.Params(rho=float("nan")))
    with pytest.raises(ValueError, match="isotropic_noise"):
        vb_phd.build_graph(vb_phd.Params(isotropic_noise="yes"))
    sa = vb_phd.build_graph(vb_phd.Params(isotropic_noise=True, scale_aware=True))
    assert sa.factors_of("noise", "conjugate")[0].tie == (0, 0, 1)


def test_video_params_give_vb_the_isotropic_belief_and_leave_the_phd_alone():
    v = phd.video_params(vb_phd.Params, 640, 480, 25.0)
    assert v.isotropic_noise is True and v.rho == 0.9
    assert phd.video_params(vb_phd.Params, 640, 480, 25.0, rho=0.8).rho == 0.8
    p = phd.video_params(phd.Params, 640, 480, 25.0)
    assert not hasattr(p, "rho")


def test_tied_noise_on_a_gaussian_belief_is_refused():
    from pgm import GaussianPrior, LinearGaussianLikelihood, LinearGaussianTransition

    g = FactorGraph([Variable("x", 4), Variable("noise", 2, role="noise")],
                    [GaussianPrior("x", mean=np.zeros(4), cov=np.eye(4)),
                     LinearGaussianTransition("x", F=F, Q=Q),
                     LinearGaussianLikelihood("x", H=H, R=np.eye(2)),
                     InverseGammaPrior("noise", sigma=[1.0, 1.0]),
                     VBNoise("noise", "x", tie=[0, 0])])
    eng = Engine(g, np.random.default_rng(0), belief_types={"x": Gaussian})
    with pytest.raises(ValueError, match="tied"):
        eng.step(FrameContext(1, measurements=np.zeros(2)))
