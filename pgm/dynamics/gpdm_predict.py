"""Prediction with a learned GPDM or constant velocity: box particles over future
frames (see :mod:`pgm.dynamics.gpdm`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from pgm.core.rng import as_generator

from .gpdm_data import apply_differences, box_differences
from .gpdm_model import GPDM, _float_in, _int_at_least

# --------------------------------------------------------------------------- prediction


def _check_history(history_boxes: Any, steps: Any, n_particles: Any, fps: Any, rng: Any
                   ) -> tuple[np.ndarray, int, int, float]:
    b = np.asarray(history_boxes, dtype=float)
    if b.ndim == 1:
        b = b[None]
    if b.ndim != 2 or b.shape[1] != 4 or b.shape[0] < 1:
        raise ValueError(f"history_boxes must have shape (T >= 1, 4), got {b.shape}")
    if not np.all(np.isfinite(b)) or np.any(b[:, 2:] <= 0):
        raise ValueError("history_boxes must be finite with positive width and height")
    return (b, _int_at_least("steps", steps, 1), _int_at_least("n_particles", n_particles, 1),
            _float_in("fps", fps, 0.0, 1e4))


def predict_constant_velocity(history_boxes: np.ndarray, steps: int, rng: np.random.Generator,
                              n_particles: int = 1, *, fps: float, average: int = 1,
                              noise: float = 0.0) -> np.ndarray:
    """Constant-velocity future boxes, shape ``(n_particles, steps, 4)``.

    The velocity of ``(cx, cy, w, h)`` in pixels per frame is the mean of the last
    ``average`` differences of ``history_boxes`` ``(T, 4)`` (zero with one box). With
    ``noise > 0`` every frame adds to each particle's velocity a Gaussian kick of
    standard deviation ``noise · (h, h, w, h) / fps`` (``noise`` in box heights per
    second), drawn from ``rng``; with ``noise = 0`` all particles are the same.
    """
    b, steps, n, fps = _check_history(history_boxes, steps, n_particles, fps, rng)
    rng = as_generator(rng)
    average = _int_at_least("average", average, 1)
    noise = _float_in("noise", noise, 0.0, 1e3, open_low=False)
    m = min(average, b.shape[0] - 1)
    v = (b[-1] - b[-1 - m]) / m if m > 0 else np.zeros(4)
    box = np.tile(b[-1], (n, 1))
    vel = np.tile(v, (n, 1))
    out = np.empty((n, steps, 4))
    for k in range(steps):                      # loop over frames, vectorised over particles
        if noise > 0:
            scale = box[:, [3, 3, 2, 3]] * (noise / fps)
            vel = vel + scale * rng.standard_normal((n, 4))
        box = box + vel
        box[:, 2:] = np.maximum(box[:, 2:], 1e-3 * b[-1, 2:])
        out[:, k] = box
    return out


def predict(model: GPDM, history_boxes: np.ndarray, steps: int, rng: np.random.Generator,
            n_particles: int = 20, *, fps: float, noise: bool = True) -> np.ndarray:
    """Sample future boxes of one target from the learned dynamics.

    Parameters
    ----------
    model : GPDM
    history_boxes : ndarray, shape (T, 4)
        The target's ``(cx, cy, w, h)`` in its last ``T`` consecutive frames, oldest
        first (only the last ``settings.history + 1`` are used).
    steps : int
        Frames to predict (a gap of ``steps − 1`` missing frames ends at the last one).
    rng : numpy.random.Generator
    n_particles : int
        Number of sampled futures.
    fps : float
        Frame rate of the video (observations are in box heights per second).
    noise : bool
        False: the mean latent path (``z ← μ_X(z)``), the same for every particle.

    Returns
    -------
    ndarray, shape (n_particles, steps, 4)
        Boxes ``(cx, cy, w, h)``. Latent particles start at the inferred current latent
        (:meth:`GPDM.infer_latent`), move by ``z ← μ_X(z) + σ_X(z) ε``, and each frame's
        box change is ``μ_Y(z)``. With fewer than ``settings.min_history`` boxes:
        :func:`predict_constant_velocity` with ``settings.cv_average`` and
        ``settings.cv_noise``.
    """
    if not isinstance(model, GPDM):
        raise ValueError(f"model must be a GPDM, got {type(model).__name__}")
    b, steps, n, fps = _check_history(history_boxes, steps, n_particles, fps, rng)
    rng = as_generator(rng)
    s = model.settings
    if b.shape[0] < s.min_history:
        return predict_constant_velocity(b, steps, rng, n, fps=fps, average=s.cv_average,
                                         noise=s.cv_noise if noise else 0.0)
    y = model.standardise(box_differences(b[-(s.history + 1):], fps))
    z = np.tile(model.infer_latent(y), (n, 1))
    box = np.tile(b[-1], (n, 1))
    out = np.empty((n, steps, 4))
    for k in range(steps):                      # loop over frames, vectorised over particles
        mu, var = model.dynamics(z)
        z = (mu + np.sqrt(var)[:, None] * rng.standard_normal(mu.shape)) if noise else mu
        box = apply_differences(box, model.mean_y(z), fps)
        out[:, k] = box
    return out
