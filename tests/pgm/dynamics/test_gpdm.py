"""GPDM (Wang et al. 2008): closed-form oracles against scikit-learn, learning a planted latent
dynamic, storage, malformed files, and the constant-velocity fallback."""

from __future__ import annotations

import json

import numpy as np
import pytest
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, DotProduct, WhiteKernel

from pgm.dynamics.gpdm import (
    GPDM,
    GPDMSettings,
    Trajectory,
    apply_differences,
    box_differences,
    dynamics_kernel,
    fit_gpdm,
    gt_trajectories,
    learn_gpdm,
    load_gpdm,
    observation_kernel,
    predict,
    predict_constant_velocity,
)
from pgm.io.annotations import load_mot

ALPHA = np.array([1.3, 0.7, 0.2, 25.0])     # α1, α2, α3, α4 (α4: noise precision)
BETA = np.array([0.9, 40.0])                # β1, β2 (β2: noise precision)


def _fixed_model(n: int = 20, seed: int = 0, **settings) -> GPDM:
    rng = np.random.default_rng(seed)
    X = rng.standard_normal((n, 2))
    Y = np.stack([np.sin(X[:, 0]), np.cos(X[:, 1]), X[:, 0] * X[:, 1]], axis=1)
    Y = Y + 0.05 * rng.standard_normal(Y.shape)
    return GPDM(X=X, Y=Y, lengths=np.array([n]), alpha=ALPHA, beta=BETA,
                y_mean=np.array([0.1, -0.2, 0.3]), y_std=np.array([1.0, 2.0, 0.5]),
                settings=GPDMSettings(**settings))


def _sk_dynamics_kernel():
    return (ConstantKernel(ALPHA[0], "fixed") * RBF(1 / np.sqrt(ALPHA[1]), "fixed")
            + ConstantKernel(ALPHA[2], "fixed") * DotProduct(0.0, "fixed"))


def _sk_observation_kernel():
    return RBF(1 / np.sqrt(BETA[0]), "fixed")


def test_kernels_equal_sklearn_kernels():
    rng = np.random.default_rng(1)
    a, b = rng.standard_normal((7, 2)), rng.standard_normal((5, 2))
    np.testing.assert_allclose(dynamics_kernel(a, b, ALPHA), _sk_dynamics_kernel()(a, b),
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(observation_kernel(a, b, BETA[0]),
                               _sk_observation_kernel()(a, b), rtol=1e-12, atol=1e-12)


def test_dynamics_predictive_equals_sklearn_gp():
    """μ_X, σ²_X (α₄⁻¹ included) = a GP regression of X_out on X_in with a white kernel."""
    model = _fixed_model()
    gp = GaussianProcessRegressor(_sk_dynamics_kernel() + WhiteKernel(1 / ALPHA[3], "fixed"),
                                  alpha=0.0, optimizer=None)
    gp.fit(model.X[:-1], model.X[1:])
    xs = np.random.default_rng(2).standard_normal((9, 2))
    mean, std = gp.predict(xs, return_std=True)
    mu, var = model.dynamics(xs)
    np.testing.assert_allclose(mu, mean, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(var, std[:, 0] ** 2, rtol=1e-8, atol=1e-10)


def test_observation_predictive_and_marginal_likelihood_equal_sklearn_gp():
    model = _fixed_model()
    gp = GaussianProcessRegressor(_sk_observation_kernel() + WhiteKernel(1 / BETA[1], "fixed"),
                                  alpha=0.0, optimizer=None)
    gp.fit(model.X, model.Y)
    xs = np.random.default_rng(3).standard_normal((9, 2))
    mean, std = gp.predict(xs, return_std=True)
    mu, var = model.observe(xs)
    np.testing.assert_allclose(mu, mean, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(var, std[:, 0] ** 2, rtol=1e-8, atol=1e-10)
    # μ_Y adds ȳ back (in heights per second)
    np.testing.assert_allclose(model.mean_y(xs), model.y_mean + model.y_std * mean, rtol=1e-8)
    # L_Y = −log p(Y | X, β) − (ND/2) ln 2π
    n, D = model.Y.shape
    expected = -gp.log_marginal_likelihood_value_ - 0.5 * n * D * np.log(2 * np.pi)
    assert model.objective_terms()["L_Y"] == pytest.approx(expected, rel=1e-10)


def test_dynamics_pairs_never_cross_a_sequence_boundary():
    model = _fixed_model()
    two = GPDM(X=model.X, Y=model.Y, lengths=np.array([12, 8]), alpha=ALPHA, beta=BETA,
               y_mean=model.y_mean, y_std=model.y_std)
    x_in = np.concatenate([model.X[:11], model.X[12:19]])
    x_out = np.concatenate([model.X[1:12], model.X[13:20]])
    gp = GaussianProcessRegressor(_sk_dynamics_kernel() + WhiteKernel(1 / ALPHA[3], "fixed"),
                                  alpha=0.0, optimizer=None).fit(x_in, x_out)
    xs = np.random.default_rng(4).standard_normal((5, 2))
    np.testing.assert_allclose(two.dynamics(xs)[0], gp.predict(xs), rtol=1e-8, atol=1e-10)


# ---- learning a planted latent dynamic ---------------------------------------------

OMEGA, PHASE_NOISE, OBS_NOISE = 0.3, 0.02, 0.05


def _planted(rng, n_seq, length):
    """Phase θ advancing by ω (+ N(0, 0.02²)); y = an injective nonlinear map + N(0, 0.05²)."""
    seqs = []
    for _ in range(n_seq):
        theta = rng.uniform(0, 2 * np.pi) + np.cumsum(
            OMEGA + PHASE_NOISE * rng.standard_normal(length))
        y = np.stack([np.cos(theta), np.sin(theta) + 0.3 * np.cos(2 * theta),
                      0.5 * np.sin(2 * theta)], axis=1)
        seqs.append(y + OBS_NOISE * rng.standard_normal(y.shape))
    return seqs


@pytest.mark.slow
def test_learning_recovers_a_planted_latent_dynamic():
    """One-step prediction error near the generating noise.

    The best possible one-step predictor has per-component RMSE ≈ sqrt(σ² + (σ_θ·|y'|)²)
    ≈ 0.052 (σ = 0.05 observation noise, σ_θ = 0.02 phase noise, |y'| ≤ 1), plus the
    error of the current phase estimated from 3 noisy observations (≈ σ/√3 per
    component at most). 2σ = 0.1 leaves room for both; repeating the last observation
    (≈ 0.25) or extrapolating it linearly (≈ 0.13: the curvature ω² plus √5σ of noise)
    cannot reach it. With 2 × 59 × 3 held-out residuals the RMSE's sampling error is
    about 5 %.
    """
    rng = np.random.default_rng(0)
    model = fit_gpdm(_planted(rng, 6, 40), GPDMSettings(max_iter=100), rng)
    assert model.info["iterations"] > 0
    trace = model.info["objective_trace"]
    assert trace[-1] < trace[0]
    errs, last, linear = [], [], []
    for y in _planted(np.random.default_rng(1), 2, 60):
        for t in range(3, len(y) - 1):
            z = model.infer_latent(model.standardise(y[t - 2:t + 1]))
            pred = model.mean_y(model.dynamics(z[None])[0])[0]
            errs.append(pred - y[t + 1])
            last.append(y[t] - y[t + 1])
            linear.append(2 * y[t] - y[t - 1] - y[t + 1])
    rmse = lambda e: float(np.sqrt(np.mean(np.square(e))))  # noqa: E731
    assert rmse(errs) < 2 * OBS_NOISE
    assert rmse(errs) < 0.8 * rmse(linear) and rmse(errs) < 0.5 * rmse(last)


def test_learn_gpdm_from_boxes_mirror_and_settings_recorded():
    rng = np.random.default_rng(5)
    trajs = []
    for k in range(4):                      # walkers at 1 height/s to the right, jittered
        t = np.arange(30)
        h = 100 + 2 * k + rng.normal(0, 0.5, 30)
        cx = 50 + 100 * t / 25 + rng.normal(0, 0.5, 30)
        boxes = np.stack([cx, 200 + rng.normal(0, 0.5, 30), 0.4 * h, h], axis=1)
        trajs.append(Trajectory(boxes, np.arange(1, 31), 25.0, k, "synthetic"))
    s = GPDMSettings(mirror=True, max_iter=20)
    model = learn_gpdm(trajs, s, rng)
    assert model.lengths.size == 8 and model.Y.shape == (8 * 29, 3)
    assert model.y_mean[0] == pytest.approx(0.0, abs=1e-9)      # mirroring cancels the flow
    assert model.info["sources"] == ["synthetic"] and model.settings == s


# ---- boxes, trajectories ------------------------------------------------------------


def test_box_differences_and_apply_differences_are_inverse():
    rng = np.random.default_rng(6)
    boxes = np.stack([100 + np.cumsum(rng.normal(2, 1, 12)), 200 + rng.normal(0, 1, 12),
                      40 + rng.normal(0, 1, 12), 100 + np.cumsum(rng.normal(0, 1, 12))], 1)
    y = box_differences(boxes, fps=7.0)
    back = apply_differences(boxes[:-1], y, fps=7.0)
    np.testing.assert_allclose(back[:, [0, 1, 3]], boxes[1:, [0, 1, 3]], atol=1e-9)
    # units: a 1-height-per-second walk to the right at 25 fps
    walk = np.array([[0, 0, 40, 100], [4, 0, 40, 100]], float)
    np.testing.assert_allclose(box_differences(walk, 25.0), [[1.0, 0.0, 0.0]])


def test_gt_trajectories_cut_at_gaps_and_ignore_rows(tmp_path):
    rows = []
    for f in range(1, 13):
        rows.append(f"{f},1,{10 + f},20,10,30,1,-1,-1,-1")     # person 1: frames 1–12
    for f in [*range(1, 6), *range(8, 20)]:                     # person 2: gap at 6–7
        flag = 0 if f == 15 else 1                              # flag 0 at 15: ignore
        rows.append(f"{f},2,100,50,12,36,{flag},-1,-1,-1")
    path = tmp_path / "gt.txt"
    path.write_text("\n".join(rows) + "\n")
    trajs = gt_trajectories(load_mot(path, kind="gt"), fps=25.0, min_length=4, source="S")
    spans = [(t.target, int(t.frames[0]), int(t.frames[-1])) for t in trajs]
    assert spans == [(1, 1, 12), (2, 1, 5), (2, 8, 14), (2, 16, 19)]
    # MOT 1-based top-left to 0-based centre boxes
    np.testing.assert_allclose(trajs[0].boxes[0], [10 + 1 - 1 + 5, 19 + 15, 10, 30])
    assert all(t.fps == 25.0 and t.source == "S" for t in trajs)


# ---- storage ------------------------------------------------------------------------


def test_save_load_round_trip(tmp_path):
    rng = np.random.default_rng(7)
    model = fit_gpdm(_planted(rng, 3, 20), GPDMSettings(max_iter=10, mirror=True), rng,
                     info={"note": "round trip"})
    path = model.save(tmp_path / "m.npz")
    loaded = load_gpdm(path)
    for name in ("X", "Y", "lengths", "alpha", "beta", "y_mean", "y_std"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(model, name))
    assert loaded.settings == model.settings and loaded.info["note"] == "round trip"
    json.dumps(loaded.info)
    hist = np.array([[100, 200, 40, 100], [103, 200, 40, 101], [106, 201, 40, 101.5]], float)
    a = predict(model, hist, 5, np.random.default_rng(3), 8, fps=25.0)
    b = predict(loaded, hist, 5, np.random.default_rng(3), 8, fps=25.0)
    np.testing.assert_array_equal(a, b)
    assert a.shape == (8, 5, 4) and np.all(np.isfinite(a))


def _arrays(model):
    return {n: np.asarray(getattr(model, n)) for n in
            ("X", "Y", "lengths", "alpha", "beta", "y_mean", "y_std")}


def _header(**change):
    h = {"format": "pgm-gpdm", "version": 1, "settings": GPDMSettings().to_dict(), "info": {}}
    h.update(change)
    return np.array(json.dumps(h))


@pytest.mark.parametrize("case, message", [
    ("missing", "missing field 'alpha'"),
    ("nan", "field 'X' has NaN"),
    ("text", "not a readable GPDM .npz"),
    ("object", "not a readable GPDM .npz"),
    ("format", "header format"),
    ("version", "unsupported GPDM file version"),
    ("json", "field 'header' is not valid JSON"),
    ("setting", "unknown GPDM setting"),
    ("nan-setting", "'obs_noise_floor' must be finite"),
    ("shape", "field 'lengths'"),
])
def test_malformed_files_are_refused_with_a_clear_message(tmp_path, case, message):
    arrays, header = _arrays(_fixed_model()), _header()
    path = tmp_path / f"{case}.npz"
    if case == "missing":
        del arrays["alpha"]
    elif case == "nan":
        arrays["X"] = arrays["X"].copy()
        arrays["X"][3, 1] = np.nan
    elif case == "object":
        header = np.array([{"format": "pgm-gpdm"}], dtype=object)
    elif case == "format":
        header = _header(format="something-else")
    elif case == "version":
        header = _header(version=99)
    elif case == "json":
        header = np.array("{not json")
    elif case == "setting":
        header = _header(settings={"latent_dim": 2, "colour": "red"})
    elif case == "nan-setting":
        header = np.array(json.dumps({"format": "pgm-gpdm", "version": 1,
                                      "settings": {"obs_noise_floor": float("nan")}}))
    elif case == "shape":
        arrays["lengths"] = np.array([5, 5])
    if case == "text":
        path.write_text("not a model\n")
    else:
        with open(path, "wb") as f:
            np.savez(f, header=header, **arrays)
    with pytest.raises(ValueError, match=message) as err:
        load_gpdm(path)
    assert str(path) in str(err.value)


def test_missing_file_is_a_value_error(tmp_path):
    with pytest.raises(ValueError, match="not found"):
        load_gpdm(tmp_path / "nope.npz")


@pytest.mark.parametrize("name, value", [("obs_noise_floor", float("nan")),
                                         ("dyn_noise_floor", 0.0), ("rel_tol", float("inf")),
                                         ("history", 0), ("mirror", "yes"),
                                         ("cv_noise", float("nan"))])
def test_settings_are_validated_by_name(name, value):
    with pytest.raises(ValueError, match=name):
        GPDMSettings(**{name: value})


def test_settings_refuse_an_unfixed_latent_scale():
    with pytest.raises(ValueError, match="latent_scale"):
        GPDMSettings(latent_scale="free")


def test_fixed_dynamics_keep_their_values():
    rng = np.random.default_rng(8)
    model = fit_gpdm(_planted(rng, 3, 20), GPDMSettings(max_iter=10, fix_dynamics=True), rng)
    np.testing.assert_allclose(model.alpha, [1.0, 1.0, 0.1, 100.0])


# ---- prediction and the constant-velocity fallback --------------------------------


def test_constant_velocity_extrapolates_exactly_without_noise():
    hist = np.array([[10, 20, 4, 10], [12, 21, 4, 10], [16, 23, 4, 10]], float)
    one = predict_constant_velocity(hist, 3, np.random.default_rng(0), fps=10.0)
    np.testing.assert_allclose(one[0], [[20, 25, 4, 10], [24, 27, 4, 10], [28, 29, 4, 10]])
    avg = predict_constant_velocity(hist, 1, np.random.default_rng(0), fps=10.0, average=3)
    np.testing.assert_allclose(avg[0, 0], [19, 24.5, 4, 10])       # mean of both differences
    still = predict_constant_velocity(hist[:1], 2, np.random.default_rng(0), 4, fps=10.0)
    np.testing.assert_allclose(still, np.broadcast_to(hist[0], (4, 2, 4)))


def test_predict_falls_back_to_constant_velocity_when_history_is_short():
    model = _fixed_model(min_history=3, cv_noise=0.5)
    for hist in (np.array([[10, 20, 4, 10.0]]), np.array([[10, 20, 4, 10.0], [12, 21, 4, 10]])):
        got = predict(model, hist, 4, np.random.default_rng(9), 6, fps=25.0)
        want = predict_constant_velocity(hist, 4, np.random.default_rng(9), 6, fps=25.0,
                                         average=3, noise=0.5)
        np.testing.assert_array_equal(got, want)


def test_predict_samples_vary_and_the_mean_path_is_deterministic():
    model = _fixed_model()
    hist = np.array([[100, 200, 40, 100], [103, 200, 40, 101], [106, 201, 40, 101.5]], float)
    sampled = predict(model, hist, 3, np.random.default_rng(0), 16, fps=25.0)
    mean = predict(model, hist, 3, np.random.default_rng(0), 2, fps=25.0, noise=False)
    assert np.ptp(sampled[:, -1, 0]) > 0
    np.testing.assert_allclose(mean[0], mean[1], rtol=1e-12)
    with pytest.raises(ValueError, match="fps"):
        predict(model, hist, 3, np.random.default_rng(0), 2, fps=float("nan"))
    with pytest.raises(ValueError, match="history_boxes"):
        predict(model, hist[:, :3], 3, np.random.default_rng(0), 2, fps=25.0)
