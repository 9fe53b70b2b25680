"""The AR(2) transition's heavy-tailed step: samples and density agree."""

import numpy as np
import pytest

from pgm.factors import AR2Transition


def test_jump_mixture_samples_match_the_density():
    f = AR2Transition("x", noise_std=[2.0, 3.0], damping=0.5, jump_prob=0.2, jump_scale=8.0)
    past1, past2 = np.array([[10.0, 5.0]]), np.array([[8.0, 5.0]])
    n = 200_000
    x = f.sample(np.random.default_rng(0), np.repeat(past1, n, 0), np.repeat(past2, n, 0))
    mean = past1[0] + 0.5 * (past1[0] - past2[0])
    var = (0.8 + 0.2 * 64) * np.array([4.0, 9.0])
    # Monte-Carlo tolerances: 5 standard errors of the mean and of the variance
    assert np.all(np.abs(x.mean(0) - mean) <= 5 * np.sqrt(var / n))
    kurt_var = np.var((x - mean) ** 2, axis=0)
    assert np.all(np.abs(x.var(0) - var) <= 5 * np.sqrt(kurt_var / n))
    # the density integrates to one and its histogram matches the samples (1-D cut)
    f1 = AR2Transition("x", noise_std=[2.0], damping=0.0, jump_prob=0.2, jump_scale=8.0)
    grid = np.linspace(-120, 120, 24001)[:, None]
    p = np.exp(f1.log_prob(grid, np.zeros((len(grid), 1))))
    assert np.trapezoid(p, grid[:, 0]) == pytest.approx(1.0, abs=1e-6)
    s = f1.sample(np.random.default_rng(1), np.zeros((n, 1)))[:, 0]
    frac = np.mean(np.abs(s) > 10)
    want = np.trapezoid(np.where(np.abs(grid[:, 0]) > 10, p, 0), grid[:, 0])
    assert frac == pytest.approx(want, abs=5 * np.sqrt(want * (1 - want) / n))


def test_jump_settings_are_checked_and_saved():
    for bad in ({"jump_prob": 1.0}, {"jump_prob": -0.1}, {"jump_scale": 0.0},
                {"jump_prob": float("nan")}):
        with pytest.raises(ValueError):
            AR2Transition("x", noise_std=[1.0], **bad)
    f = AR2Transition("x", noise_std=[1.0], jump_prob=0.1, jump_scale=5.0)
    assert f.params()["jump_prob"] == 0.1 and f.params()["jump_scale"] == 5.0
    assert "jump_prob" not in AR2Transition("x", noise_std=[1.0]).params()
