"""The GPDM as engine factors (pgm.dynamics.factors): the transition against an oracle
built from the model's own predictive maps, shapes and positivity, the noise scale,
JSON round trips, re-centring priors, and the random-draw contract of plates."""

from __future__ import annotations

import json

import numpy as np
import pytest

from pgm.core.errors import InputError
from pgm.core.graph import FactorGraph
from pgm.core.variable import Variable
from pgm.dynamics.factors import GPDMPrior, GPDMTransition, state_labels
from pgm.dynamics.gpdm import GPDMSettings, Trajectory, learn_gpdm
from pgm.factors.gaussian import GaussianPrior
from pgm.factors.kinds import PriorFactor
from pgm.inference.batched import ReplicaRNG

FPS = 25.0


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    """A tiny GPDM (d = 2) learned from four jittered synthetic walkers, saved as .npz."""
    rng = np.random.default_rng(0)
    trajs = []
    for k in range(4):
        t = np.arange(16)
        h = 100 + 5 * k + np.cumsum(rng.normal(0, 0.5, 16))
        cx = 50 + (60 + 20 * k) * np.sin(0.2 * t + k) + rng.normal(0, 0.5, 16)
        cy = 200 + 10 * np.cos(0.3 * t) + rng.normal(0, 0.5, 16)
        trajs.append(Trajectory(np.stack([cx, cy, 0.4 * h, h], 1), t + 1, FPS, k, "synth"))
    model = learn_gpdm(trajs, GPDMSettings(max_iter=5, check_every=5), rng)
    path = tmp_path_factory.mktemp("gpdm") / "tiny.npz"
    model.save(path)
    return path


def _particles(model, n, seed=1):
    rng = np.random.default_rng(seed)
    box = np.column_stack([rng.uniform(50, 500, n), rng.uniform(100, 400, n),
                           rng.uniform(20, 60, n), rng.uniform(60, 150, n)])
    z = model.X[rng.integers(0, model.X.shape[0], n)] + 0.1 * rng.standard_normal((n, 2))
    return np.concatenate([box, z], axis=1)


class RecordingRNG:
    """A Generator proxy that records ``(method, shape)`` of every draw."""

    def __init__(self, rng):
        self.rng = rng
        self.calls = []

    def __getattr__(self, name):
        method = getattr(self.rng, name)

        def call(*args, **kwargs):
            out = method(*args, **kwargs)
            self.calls.append((name, np.shape(out)))
            return out

        return call


# ---- (a) the transition's mean path equals μ_X then μ_Y through the box update ---------


def test_noise_free_transition_equals_the_models_mean_maps(model_file):
    f = GPDMTransition("p", model=str(model_file), fps=FPS, obs_noise=False,
                       latent_noise_scale=0.0)
    m = f.model
    x = _particles(m, 30)
    rec = RecordingRNG(np.random.default_rng(0))
    out = f.sample(rec, x)
    assert rec.calls == []                                   # nothing random left
    # oracle: the GPDM's own predictive maps, the box update written out by hand
    z_new = m.dynamics(x[:, 4:])[0]
    y = m.y_mean + m.y_std * m.observe(z_new)[0]             # heights per second
    cx, cy, w, h = x[:, :4].T
    step = y * (h / FPS)[:, None]
    new_h = h + step[:, 2]
    top = cy - h / 2 + step[:, 1]
    expected = np.column_stack([cx + step[:, 0], top + new_h / 2, w * new_h / h, new_h, z_new])
    np.testing.assert_allclose(out, expected, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(out[:, 2] / out[:, 3], w / h, rtol=1e-12)   # aspect kept


# ---- (b) shapes, finiteness, positive heights, the noise it adds -----------------------


@pytest.mark.parametrize("obs_noise", [True, False])
@pytest.mark.parametrize("scale", [0.0, 1.0, 3.0])
def test_samples_are_finite_with_positive_heights(model_file, obs_noise, scale):
    f = GPDMTransition("p", model=str(model_file), fps=7.0, obs_noise=obs_noise,
                       latent_noise_scale=scale)
    x = _particles(f.model, 200, seed=2)
    x[0, 2:4] = 0.0                                          # a degenerate particle
    rng = np.random.default_rng(3)
    for _ in range(10):                                      # a few frames
        x = f.sample(rng, x)
        assert x.shape == (200, 6)
        assert np.all(np.isfinite(x)) and np.all(x[:, 2:4] > 0)


def test_observation_noise_has_the_models_predictive_std(model_file):
    f = GPDMTransition("p", model=str(model_file), fps=FPS, latent_noise_scale=0.0)
    m = f.model
    x = np.tile(_particles(m, 1, seed=4), (4000, 1))
    out = f.sample(np.random.default_rng(5), x)
    z_new = m.dynamics(x[:1, 4:])[0]
    var = m.observe(z_new)[1][0]
    h = x[0, 3]
    want = np.sqrt(var) * m.y_std[0] * h / FPS               # std of Δcx in pixels
    assert np.std(out[:, 0]) == pytest.approx(want, rel=0.06)
    np.testing.assert_allclose(out[:, 4:], np.broadcast_to(z_new, (4000, 2)))
    mean_step = (m.y_mean[0] + m.y_std[0] * m.observe(z_new)[0][0, 0]) * h / FPS
    assert np.mean(out[:, 0] - x[0, 0]) == pytest.approx(mean_step, abs=4 * want / 60)


def test_parameters_are_validated(model_file, tmp_path):
    for bad in ({"fps": 0.0}, {"fps": float("nan")}, {"latent_noise_scale": -1.0},
                {"obs_noise": "yes"}):
        kwargs = {"model": str(model_file), "fps": FPS, **bad}
        with pytest.raises(ValueError):
            GPDMTransition("p", **kwargs)
    with pytest.raises(ValueError, match="mean"):
        GPDMPrior("p", model=str(model_file), mean=[1, 2, 0, 4])
    bad_file = tmp_path / "bad.npz"
    bad_file.write_text("not a zip")
    with pytest.raises(InputError, match="bad.npz"):
        GPDMTransition("p", model=str(bad_file), fps=FPS)
    f = GPDMTransition("p", model=str(model_file), fps=FPS, name="gpdm-motion")
    for var in (Variable("p", 4, labels=("cx", "cy", "w", "h")),
                Variable("p", 6, labels=("x", "y", "w", "h", "z0", "z1"))):
        with pytest.raises(ValueError, match="gpdm-motion"):
            f.check({"p": var})
    f.check({"p": Variable("p", 6, labels=state_labels(2))})


# ---- (c) a saved declaration reloads the model by its path --------------------------


def _graph(path):
    q = 2
    return FactorGraph(
        [Variable("person", 4 + q, role="part", labels=state_labels(q))],
        [GPDMPrior("person", model=str(path), mean=[100, 200, 40, 100], box_std=0.1),
         GPDMTransition("person", model=str(path), fps=FPS, latent_noise_scale=0.5)],
        name="gpdm-test", meta={"output": "person"})


def test_graph_saves_to_json_and_loads_back_equal(model_file, tmp_path):
    g = _graph(model_file)
    out = tmp_path / "model.json"
    g.save(out)
    d = json.loads(out.read_text())
    assert {f["params"]["model"] for f in d["factors"]} == {str(model_file)}
    back = FactorGraph.load(out)
    assert back == g
    tr, tr_back = g.factors["transition:person"], back.factors["transition:person"]
    x = g.factors["prior:person"].sample(np.random.default_rng(0), 10)
    np.testing.assert_array_equal(
        x, back.factors["prior:person"].sample(np.random.default_rng(0), 10))
    np.testing.assert_array_equal(tr.sample(np.random.default_rng(1), x),
                                  tr_back.sample(np.random.default_rng(1), x))


def test_loading_a_graph_whose_model_file_is_gone_names_it(model_file, tmp_path):
    moved = tmp_path / "moved.npz"
    moved.write_bytes(model_file.read_bytes())
    out = tmp_path / "model.json"
    _graph(moved).save(out)
    moved.unlink()
    with pytest.raises(ValueError, match="moved.npz"):
        FactorGraph.load(out)


# ---- (d) re-centring priors on a new target -----------------------------------------


def test_gaussian_prior_born_at_replaces_named_components():
    labels = ("cx", "cy", "w", "h")
    p = GaussianPrior("o", mean=[1, 2, 3, 4], cov=[1, 2, 3, 4], name="start")
    q = p.born_at({"cx": 10.0, "h": 40.0}, labels)
    np.testing.assert_array_equal(q.mean(), [10, 2, 3, 40])
    np.testing.assert_array_equal(q.cov, p.cov)
    assert q.name == "start" and isinstance(q, GaussianPrior)
    np.testing.assert_array_equal(p.mean(), [1, 2, 3, 4])             # unchanged
    with pytest.raises(ValueError, match="vx"):
        p.born_at({"vx": 1.0}, labels)


def test_gpdm_prior_born_at_moves_the_box_and_shares_the_model(model_file):
    p = GPDMPrior("person", model=str(model_file), mean=[100, 200, 40, 100], name="birth")
    labels = state_labels(2)
    q = p.born_at({"cx": 300.0, "cy": 250.0, "w": 20.0, "h": 50.0}, labels)
    assert q.name == "birth" and q.model is p.model and q.params()["model"] == str(model_file)
    np.testing.assert_array_equal(q.mean()[:4], [300, 250, 20, 50])
    np.testing.assert_allclose(q.mean()[4:], p.model.X.mean(0))
    x = q.sample(np.random.default_rng(0), 50)
    assert x.shape == (50, 6)
    np.testing.assert_array_equal(x[:, :4], np.tile([300, 250, 20, 50], (50, 1)))  # box_std 0
    dist = np.linalg.norm(x[:, None, 4:] - p.model.X[None], axis=-1).min(1)
    assert np.all(dist < 6 * 0.05 * np.sqrt(2))              # near training latents
    np.testing.assert_array_equal(p.mean()[:4], [100, 200, 40, 100])  # unchanged
    with pytest.raises(ValueError, match="z0"):
        p.born_at({"z0": 1.0}, labels)
    with pytest.raises(ValueError, match="width and height"):
        p.born_at({"h": -1.0}, labels)


def test_prior_without_born_at_says_so():
    class Fixed(PriorFactor):
        abstract = True          # keeps this test class out of the factor registry

        def sample(self, rng, num):
            return np.zeros((num, 1))

        def mean(self):
            return np.zeros(1)

    with pytest.raises(ValueError, match="cannot be re-centred.*born_at"):
        Fixed("v", name="fixed").born_at({"cx": 1.0}, ("cx",))


def test_prior_picks_training_latents_uniformly(model_file):
    p = GPDMPrior("p", model=str(model_file), mean=[100, 200, 40, 100], box_std=0.2,
                  latent_jitter=0.0)
    x = p.sample(np.random.default_rng(1), 4000)
    X = p.model.X
    idx = np.argmin(np.linalg.norm(x[:, None, 4:] - X[None], axis=-1), axis=1)
    np.testing.assert_allclose(x[:, 4:], X[idx], atol=0)     # exactly training points
    counts = np.bincount(idx, minlength=len(X))
    assert counts.min() > 0.4 * 4000 / len(X)
    assert np.all(x[:, 2:4] > 0)
    np.testing.assert_allclose(x[:, 2] / x[:, 3], 0.4, rtol=1e-12)
    assert np.std(x[:, 0]) == pytest.approx(0.2 * 100, rel=0.06)


# ---- (e) every draw has the particle count as its leading axis ------------------------


ALLOWED = {"standard_normal", "random", "normal", "uniform"}


@pytest.mark.parametrize("obs_noise, scale, box_std, jitter",
                         [(True, 1.0, 0.1, 0.05), (False, 1.0, 0.0, 0.0),
                          (True, 0.0, 0.1, 0.0)])
def test_every_draw_has_the_particle_count_as_leading_axis(model_file, obs_noise, scale,
                                                           box_std, jitter):
    prior = GPDMPrior("p", model=str(model_file), mean=[100, 200, 40, 100], box_std=box_std,
                      latent_jitter=jitter)
    tr = GPDMTransition("p", model=str(model_file), fps=FPS, obs_noise=obs_noise,
                        latent_noise_scale=scale)
    for n in (1, 7):
        rec = RecordingRNG(np.random.default_rng(0))
        x = prior.sample(rec, n)
        tr.sample(rec, x)
        assert rec.calls, "nothing drawn"
        for method, shape in rec.calls:
            assert method in ALLOWED and shape[0] == n, (method, shape)


def test_batched_replicas_equal_separate_runs(model_file):
    """ReplicaRNG splits the draws per replica: a (K·n) call equals K separate calls."""
    prior = GPDMPrior("p", model=str(model_file), mean=[100, 200, 40, 100], box_std=0.1)
    tr = GPDMTransition("p", model=str(model_file), fps=FPS)
    K, n = 3, 5                                                      # noqa: N806
    seeds = [np.random.default_rng(s) for s in (10, 11, 12)]
    x = np.concatenate([prior.sample(np.random.default_rng(s), n) for s in (0, 1, 2)])
    batched = tr.sample(ReplicaRNG(seeds, n), x)
    separate = np.concatenate([tr.sample(np.random.default_rng(s), x[k * n:(k + 1) * n])
                               for k, s in enumerate((10, 11, 12))])
    np.testing.assert_allclose(batched, separate, rtol=0, atol=1e-9)
    assert batched.shape == (K * n, 6)
