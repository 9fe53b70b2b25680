"""A linear-Gaussian state-space model declared as a factor graph.

The oracle model of the test suite and of the first tutorial section: a particle
filter run by the generic engine on this graph must agree with the exact Kalman
filter (:mod:`pgm.inference.kalman`) fed from the *same* graph.

.. math::
    x_1 \\sim \\mathcal N(m_0, P_0),\\quad x_t = F x_{t-1} + \\mathcal N(0, Q),\\quad
    y_t = H x_t + \\mathcal N(0, R)

Default: a 1-D constant-velocity target, state ``(position, velocity)``, position
observed.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from pgm.core.graph import FactorGraph
from pgm.core.variable import Variable
from pgm.factors import GaussianPrior, LinearGaussianLikelihood, LinearGaussianTransition
from pgm.inference.settings import EngineSettings

from . import config as _config

__all__ = ["CONFIG", "Params", "build_graph", "simulate"]


def _cv_F() -> np.ndarray:
    return np.array([[1.0, 1.0], [0.0, 1.0]])


def _cv_Q(q: float = 0.1) -> np.ndarray:
    return q * np.array([[1 / 3, 1 / 2], [1 / 2, 1.0]])


@dataclass(frozen=True)
class Params:
    """Matrices of the model (defaults: constant velocity, position observed)."""

    m0: np.ndarray = field(default_factory=lambda: np.zeros(2))
    P0: np.ndarray = field(default_factory=lambda: np.diag([1.0, 0.5]))
    F: np.ndarray = field(default_factory=_cv_F)
    Q: np.ndarray = field(default_factory=_cv_Q)
    H: np.ndarray = field(default_factory=lambda: np.array([[1.0, 0.0]]))
    R: np.ndarray = field(default_factory=lambda: np.array([[0.5]]))


def build_graph(params: Params, num_particles: int = 1000) -> FactorGraph:
    """The graph ``prior → x ← transition``, ``x — likelihood — y``."""
    d = np.asarray(params.m0).size
    x = Variable("x", d, role="state")
    return FactorGraph(
        [x],
        [GaussianPrior("x", mean=params.m0, cov=params.P0),
         LinearGaussianTransition("x", F=params.F, Q=params.Q),
         LinearGaussianLikelihood("x", H=params.H, R=params.R)],
        name="linear-gaussian",
        meta={"output": "x", "engine": EngineSettings(num_particles=num_particles).to_dict()},
    )


def simulate(rng: np.random.Generator, params: Params, num_timesteps: int):
    """Draw states ``(T, d)`` and measurements ``(T, k)`` from the model."""
    F, Q, H, R = (np.atleast_2d(params.F), np.atleast_2d(params.Q), np.atleast_2d(params.H),
                  np.atleast_2d(params.R))
    d, k = F.shape[0], H.shape[0]
    xs, ys = np.zeros((num_timesteps, d)), np.zeros((num_timesteps, k))
    x = rng.multivariate_normal(np.asarray(params.m0, float), np.atleast_2d(params.P0))
    for t in range(num_timesteps):
        if t > 0:
            x = F @ x + rng.multivariate_normal(np.zeros(d), Q)
        xs[t] = x
        ys[t] = H @ x + rng.multivariate_normal(np.zeros(k), R)
    return xs, ys


def _example(config, values):
    return build_graph(Params()), ""


#: what the application sees of this model (:mod:`pgm.models.config`)
CONFIG = _config.ModelConfig(
    "linear-gaussian", "state-space", sys.modules[__name__],
    "a linear-Gaussian state-space model (the Kalman filter's oracle); no video",
    build=lambda config, values, video: build_graph(
        Params(), **({"num_particles": video.particles} if video.particles else {})),
    example=_example)
