"""Gaussian-process dynamical model (GPDM) of box motion: learning, storage, prediction.

Wang, Yin & Man [#wang2008] learn a GPDM (Wang, Fleet & Hertzmann, TPAMI 2008) of
people's frame-to-frame coordinate changes and draw a particle filter's proposals from
it. A prototype of the paper's recipe has *no finite MAP minimum* (observation noise → 0,
the latent shrinking, dynamics noise → 0) and never beat constant velocity. This module
implements the model with the fixes that this requires, and says where it departs from
the paper:

* **Observation** ``y_t = (Δcx, Δtop, Δh) / h_{t-1} · fps`` — the box's centre-x, top
  and height changes in *box heights per second* (:func:`box_differences`), not the
  paper's 6-D head/centroid/feet differences in pixels per frame (that vector has rank
  3; the three x-differences coincide and the y's are linear in ``Δtop`` and ``Δh``).
  ``Y`` is standardised (``ȳ`` and the per-dimension standard deviation kept) and the
  paper's scale matrix ``W`` is fixed to the identity (``W = 1``), so the ``tr(W²)/2κ²``
  and ``−N ln|W|`` terms vanish.
* **Bounded hyper-parameters.** The noise variances ``β₂⁻¹`` and ``α₄⁻¹`` have floors
  relative to the data variance (:attr:`GPDMSettings.obs_noise_floor` × 1 for the
  standardised ``Y``; :attr:`GPDMSettings.dyn_noise_floor` × 1 for the latent, which is
  initialised with unit mean square); every other hyper-parameter lives in a box
  (:data:`HYPER_BOUNDS`) through a logistic transform of its logarithm. The inverse
  squared length-scales ``α₂, β₁`` are capped at 10 (length-scale ≥ 0.32 of the unit
  latent scale): without the cap ``β₁`` keeps growing (GP-LVM overfitting — each
  training point gets its own basin) and held-out prediction worsens the longer L-BFGS
  runs (measured on the planted-dynamics test: one-step RMSE 0.07 at 50 iterations,
  0.09 at 300 with ``β₁ = 19.5``; with the cap 0.074 at 300). The paper's
  improper prior ``Σ ln α_j + Σ ln β_j`` is kept, but it has no minimum either (each
  term runs to −∞ as its parameter → 0 while the kernel stays finite), so without the
  box it would be one more unbounded direction.
* **A fixed latent scale** (:attr:`GPDMSettings.latent_scale`): ``"unit"`` (default)
  parametrises ``X = Z · sqrt(N d / ‖Z‖²)``, so the latent's mean square is 1 by
  construction and the shrinking direction does not exist; ``"prior"`` puts an
  ``N(0, I)`` prior on every latent point instead (it subsumes the paper's prior on each
  sequence's first point). *Measured:* the prior alone does not fix the scale — shrinking
  ``X`` lowers the prior term too, so the latent shrinks until the dynamics-noise floor
  stops it, the kernels turn narrow, and one-step error on the planted-dynamics test
  doubles between 50 and 200 L-BFGS iterations; ``"unit"`` has no such drift. Optionally
  the dynamics hyper-parameters are *fixed* (:attr:`GPDMSettings.fix_dynamics`, Wang et
  al. 2008's remedy for this overfitting: ``α₁ = 1, α₂ = 1, α₃ = 0.1`` in the unit-scale
  latent, ``α₄⁻¹ = max(dyn_noise_floor, 0.01)``; our values).
* **A stopping rule**: L-BFGS (torch autograd, float64, strong-Wolfe line search) in
  rounds of :attr:`GPDMSettings.check_every` iterations, stopped when the objective's
  relative change over a round falls below :attr:`GPDMSettings.rel_tol` or after
  :attr:`GPDMSettings.max_iter` iterations. The paper's SCG is not used.
* **Several sequences as one GP**: each trajectory's ``(X_in, X_out)`` pairs are
  concatenated (``N − S`` rows for ``S`` sequences); no dynamics pair crosses a
  boundary. Long training sets are cut into chunks and a random subset of chunks
  (:attr:`GPDMSettings.max_points` points, drawn with the ``numpy`` Generator passed
  in) is kept, as the exact GP costs ``O(N³)``.
* **Mirroring** (:attr:`GPDMSettings.mirror`): every training trajectory is added again
  with ``Δcx`` negated, removing the scene's mean horizontal flow (the prototype found
  rollouts drifting back to the training scene's ``ȳ``).
* **Balanced GPDM** (:attr:`GPDMSettings.balanced`): ``L_X`` is multiplied by ``D/d``.
* **Test-time latent** from the last :attr:`GPDMSettings.history` differences, not one
  and not the PCA projection: the latent path ``z_1..z_K`` maximising
  ``Σ_k log N(y_k; μ_Y(z_k), σ²_Y(z_k)) + Σ_k log N(z_k; μ_X(z_{k−1}), σ²_X(z_{k−1}))``
  (plus the latent prior), started from the best-scoring window of ``K`` consecutive
  training latents and refined by a few L-BFGS iterations; its last point is the
  current latent (:meth:`GPDM.infer_latent`).
* **Constant-velocity fallback**: with fewer than :attr:`GPDMSettings.min_history`
  boxes (track birth) :func:`predict` returns :func:`predict_constant_velocity`.

Model (``W = 1``, latent dimension ``d``, observation dimension ``D = 3``)::

    k_Y(x, x') = exp(−β₁/2 ‖x − x'‖²) + β₂⁻¹ δ
    k_X(x, x') = α₁ exp(−α₂/2 ‖x − x'‖²) + α₃ xᵀx' + α₄⁻¹ δ
    L = (D/2) ln|K_Y| + ½ tr(K_Y⁻¹ Y Yᵀ)
        + c [(d/2) ln|K_X| + ½ tr(K_X⁻¹ X_out X_outᵀ)]      (c = D/d if balanced, else 1)
        + ½ Σ_i ‖x_i‖²  ("prior")  or  ½ Σ_starts ‖x_1‖²  ("unit": ‖X‖² = N d fixed)
        + Σ_j ln α_j + Σ_j ln β_j
    μ_X(x) = X_outᵀ K_X⁻¹ k_X(x),  σ²_X(x) = k_X(x, x) − k_X(x)ᵀ K_X⁻¹ k_X(x)  (α₄⁻¹ included)
    μ_Y(x) = ȳ + s ⊙ Yᵀ K_Y⁻¹ k_Y(x)                           (Y standardised: ȳ, s)

``δ`` is a Kronecker delta on training indices, so a new point's cross-covariance has no
noise term and its self-covariance has it.

Prediction (:func:`predict`) samples latent particles ``z ← N(μ_X(z), σ²_X(z) I)`` and
maps each through ``μ_Y`` to a box change; vectorised over particles. The per-target
chain with shared learned dynamics departs from the paper, which stacks all ``n``
targets into one ``6n``-dimensional vector.

A learned model is stored as ``.npz`` (arrays and a JSON header; no pickle) by
:meth:`GPDM.save` and read back, validated, by :func:`load_gpdm`. ``pgm learn gpdm``
maps onto :func:`gt_trajectories` + :func:`learn_gpdm` + :meth:`GPDM.save`; a model
config loads the file with :func:`load_gpdm` and calls :func:`predict` or the
vectorised :meth:`GPDM.dynamics` / :meth:`GPDM.mean_y` directly.

References
----------
.. [#wang2008] J. Wang, Y. Yin and H. Man, "Multiple human tracking using particle filter with
   Gaussian process dynamical model", EURASIP J. Image and Video Processing 2008, Article
   ID 969456. doi:10.1155/2008/969456
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import time
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from pgm.core.boxes import xywh_to_cxcywh
from pgm.core.errors import InputError, one_line
from pgm.core.rng import as_generator

__all__ = ["GPDM", "GPDMSettings", "Trajectory", "HYPER_BOUNDS", "FIXED_DYNAMICS",
           "apply_differences", "box_differences", "dynamics_kernel", "fit_gpdm",
           "gt_trajectories", "learn_gpdm", "load_gpdm", "observation_kernel", "predict",
           "predict_constant_velocity"]

#: file format tag and version written into every saved model's header
FORMAT = "pgm-gpdm"
VERSION = 1
#: box (lower, upper) of each free hyper-parameter other than the two noise variances
#: (whose lower bound is their floor and upper bound :data:`NOISE_UPPER`)
HYPER_BOUNDS = {"alpha1": (1e-3, 1e3), "alpha2": (1e-2, 10.0), "alpha3": (1e-4, 1e2),
                "beta1": (1e-2, 10.0)}
#: upper bound of both noise variances (the data and the latent have unit scale)
NOISE_UPPER = 10.0
#: (α₁, α₂, α₃) held fixed when :attr:`GPDMSettings.fix_dynamics` is on
FIXED_DYNAMICS = (1.0, 1.0, 0.1)
_DT = torch.float64
#: ways of fixing the latent scale (:attr:`GPDMSettings.latent_scale`)
LATENT_SCALES = ("unit", "prior")
_ARRAYS = ("X", "Y", "lengths", "alpha", "beta", "y_mean", "y_std")


# --------------------------------------------------------------------------- settings


def _int_at_least(name: str, value: Any, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
        raise ValueError(f"parameter {name!r} must be an integer >= {low}, got {value!r}")
    return int(value)


def _float_in(name: str, value: Any, low: float, high: float, *, open_low: bool = True
              ) -> float:
    if isinstance(value, bool):
        raise ValueError(f"parameter {name!r} must be a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"parameter {name!r} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise ValueError(f"parameter {name!r} must be finite, got {value!r}")
    if (v <= low if open_low else v < low) or v > high:
        bracket = "(" if open_low else "["
        raise ValueError(f"parameter {name!r} must be in {bracket}{low}, {high}], got {value!r}")
    return v


def _bool(name: str, value: Any) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"parameter {name!r} must be True or False, got {value!r}")
    return bool(value)


@dataclass(frozen=True)
class GPDMSettings:
    """Settings of GPDM learning and prediction (typed and validated; JSON-able).

    Attributes
    ----------
    latent_dim : int
        Latent dimension ``d`` (the paper's: 2).
    obs_noise_floor : float
        Floor of the observation noise variance ``β₂⁻¹``, relative to the variance of
        the standardised observations (1), in (0, 1].
    dyn_noise_floor : float
        Floor of the dynamics noise variance ``α₄⁻¹``, relative to the initial latent
        mean square (1), in (0, 1].
    latent_scale : {"unit", "prior"}
        ``"unit"``: the latent's mean square is held at 1 (a reparametrisation);
        ``"prior"``: an ``N(0, I)`` prior on every latent point (see the module notes:
        it does not stop the shrinking by itself).
    fix_dynamics : bool
        Hold ``α₁..α₄`` at :data:`FIXED_DYNAMICS`.
    balanced : bool
        Balanced GPDM: the dynamics term weighted by ``D/d``.
    mirror : bool
        Add every training trajectory mirrored left–right (``Δcx`` negated).
    max_iter : int
        Cap on L-BFGS iterations.
    rel_tol : float
        Stop when the objective's relative change over one round is below this.
    check_every : int
        L-BFGS iterations per round of the stopping rule.
    max_points : int
        At most this many training points (random chunks beyond it are dropped).
    chunk_length : int
        Length of the chunks long trajectories are cut into when subsampling.
    history : int
        Differences used to infer the test-time latent (the last ``history``).
    refine_iter : int
        L-BFGS iterations refining the test-time latent path (0: the best training
        window as is).
    min_history : int
        Fewest boxes for a GPDM prediction (≥ 2: one difference); below it
        :func:`predict` falls back to constant velocity.
    cv_average : int
        Differences averaged by the constant-velocity fallback.
    cv_noise : float
        Velocity noise of the fallback, in box heights per second (per frame).
    """

    latent_dim: int = 2
    obs_noise_floor: float = 1e-2
    dyn_noise_floor: float = 1e-2
    latent_scale: str = "unit"
    fix_dynamics: bool = False
    balanced: bool = False
    mirror: bool = False
    max_iter: int = 200
    rel_tol: float = 1e-6
    check_every: int = 10
    max_points: int = 1000
    chunk_length: int = 50
    history: int = 3
    refine_iter: int = 3
    min_history: int = 2
    cv_average: int = 3
    cv_noise: float = 0.2

    def __post_init__(self) -> None:
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        set_("latent_dim", _int_at_least("latent_dim", self.latent_dim, 1))
        for name in ("obs_noise_floor", "dyn_noise_floor"):
            set_(name, _float_in(name, getattr(self, name), 0.0, 1.0))
        for name in ("fix_dynamics", "balanced", "mirror"):
            set_(name, _bool(name, getattr(self, name)))
        if self.latent_scale not in LATENT_SCALES:
            raise ValueError(f"parameter 'latent_scale' must be one of {LATENT_SCALES}, got "
                             f"{self.latent_scale!r} (a free latent scale leaves the MAP "
                             "objective without a finite minimum)")
        set_("max_iter", _int_at_least("max_iter", self.max_iter, 0))
        set_("rel_tol", _float_in("rel_tol", self.rel_tol, 0.0, 1.0, open_low=False))
        set_("check_every", _int_at_least("check_every", self.check_every, 1))
        set_("max_points", _int_at_least("max_points", self.max_points, 3))
        set_("chunk_length", _int_at_least("chunk_length", self.chunk_length, 2))
        set_("history", _int_at_least("history", self.history, 1))
        set_("refine_iter", _int_at_least("refine_iter", self.refine_iter, 0))
        set_("min_history", _int_at_least("min_history", self.min_history, 2))
        set_("cv_average", _int_at_least("cv_average", self.cv_average, 1))
        set_("cv_noise", _float_in("cv_noise", self.cv_noise, 0.0, 1e3, open_low=False))

    def to_dict(self) -> dict[str, Any]:
        """The settings as a JSON-able dict."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> GPDMSettings:
        """Settings from a dict; an unknown key is a ``ValueError`` naming it."""
        if not isinstance(d, dict):
            raise ValueError(f"GPDM settings must be a dict, got {type(d).__name__}")
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown GPDM setting(s) {unknown} (known: {sorted(known)})")
        return cls(**d)


# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class Trajectory:
    """One target's boxes in consecutive frames.

    Attributes
    ----------
    boxes : ndarray, shape (T, 4)
        ``(cx, cy, w, h)`` per frame, 0-based pixels.
    frames : ndarray of int, shape (T,)
        Consecutive frame numbers.
    fps : float
        Frame rate of the sequence.
    target : int
        Identity in the source.
    source : str
        Where it came from (e.g. the sequence name).
    """

    boxes: np.ndarray
    frames: np.ndarray
    fps: float
    target: int = -1
    source: str = ""

    def __post_init__(self) -> None:
        b = np.array(self.boxes, dtype=float)
        if b.ndim != 2 or b.shape[1] != 4 or b.shape[0] < 1:
            raise ValueError(f"Trajectory boxes must have shape (T, 4), got {b.shape}")
        if not np.all(np.isfinite(b)) or np.any(b[:, 2:] <= 0):
            raise ValueError("Trajectory boxes must be finite with positive width and height")
        f = np.array(self.frames, dtype=np.int64).reshape(-1)
        if f.shape[0] != b.shape[0]:
            raise ValueError(f"Trajectory has {b.shape[0]} boxes but {f.shape[0]} frames")
        if np.any(np.diff(f) != 1):
            raise ValueError("Trajectory frames must be consecutive")
        object.__setattr__(self, "boxes", b)
        object.__setattr__(self, "frames", f)
        object.__setattr__(self, "fps", _float_in("fps", self.fps, 0.0, 1e4))

    def __len__(self) -> int:
        return int(self.boxes.shape[0])


def gt_trajectories(table: Any, *, fps: float, min_length: int = 10, source: str = ""
                    ) -> list[Trajectory]:
    """Per-person trajectories of consecutive frames from a MOTChallenge ground truth.

    Parameters
    ----------
    table : MotTable
        ``pgm.io.annotations.load_mot(path, kind='gt')`` (read by attribute:
        ``frames``, ``ids``, ``boxes`` top-left ``(x, y, w, h)`` and ``scored``; rows not
        scored — MOT15 flag-0 ignore regions, MOT16 non-pedestrian classes and
        ``consider`` = 0 — are dropped, so a person's track is cut where its rows are).
    fps : float
        The sequence's frame rate (``seqinfo.ini``), kept on each trajectory.
    min_length : int
        Keep runs of at least this many consecutive frames (≥ 2).
    source : str
        Stored on each trajectory.

    Returns
    -------
    list of Trajectory
        Sorted by identity, then first frame; a person with a gap gives several.
    """
    min_length = _int_at_least("min_length", min_length, 2)
    fps = _float_in("fps", fps, 0.0, 1e4)
    frames = np.asarray(table.frames, dtype=np.int64).reshape(-1)
    ids = np.asarray(table.ids, dtype=np.int64).reshape(-1)
    boxes = np.asarray(table.boxes, dtype=float).reshape(-1, 4)
    scored = getattr(table, "scored", None)
    if scored is None:
        ignore = getattr(table, "ignore", None)
        scored = np.ones(frames.shape[0], bool) if ignore is None else ~np.asarray(ignore)
    keep = np.asarray(scored, dtype=bool).reshape(-1)
    frames, ids, boxes = frames[keep], ids[keep], boxes[keep]
    order = np.lexsort((frames, ids))
    frames, ids, boxes = frames[order], ids[order], boxes[order]
    same_id = ids[1:] == ids[:-1]
    if np.any(same_id & (frames[1:] == frames[:-1])):
        i = int(np.flatnonzero(same_id & (frames[1:] == frames[:-1]))[0])
        raise ValueError(f"identity {int(ids[i])} has two boxes in frame {int(frames[i])}"
                         + (f" of {source}" if source else ""))
    cuts = np.flatnonzero(~same_id | (frames[1:] - frames[:-1] != 1)) + 1
    starts = np.concatenate([[0], cuts])
    stops = np.concatenate([cuts, [frames.shape[0]]])
    cxcywh = xywh_to_cxcywh(boxes)
    return [Trajectory(cxcywh[a:b], frames[a:b], fps, int(ids[a]), source)
            for a, b in zip(starts, stops, strict=True) if b - a >= min_length]


def box_differences(boxes: np.ndarray, fps: float) -> np.ndarray:
    """Observations ``(Δcx, Δtop, Δh)`` in box heights per second, shape ``(T − 1, 3)``.

    ``y_t = (cx_t − cx_{t−1}, top_t − top_{t−1}, h_t − h_{t−1}) / h_{t−1} · fps`` for
    ``(cx, cy, w, h)`` boxes of consecutive frames (``top = cy − h/2``). Inverse of
    :func:`apply_differences`.
    """
    b = np.asarray(boxes, dtype=float)
    if b.ndim != 2 or b.shape[1] != 4:
        raise ValueError(f"boxes must have shape (T, 4), got {b.shape}")
    h = b[:, 3]
    top = b[:, 1] - h / 2.0
    d = np.stack([np.diff(b[:, 0]), np.diff(top), np.diff(h)], axis=1)
    return d / h[:-1, None] * float(fps)


def apply_differences(boxes: np.ndarray, y: np.ndarray, fps: float) -> np.ndarray:
    """Boxes ``(..., 4)`` moved by observations ``y`` ``(..., 3)`` in heights per second.

    The width keeps the box's aspect ratio; the height stays positive (at least 1 % of
    the previous height).
    """
    b = np.asarray(boxes, dtype=float)
    y = np.asarray(y, dtype=float)
    h = b[..., 3]
    step = y * (h / float(fps))[..., None]
    new_h = np.maximum(h + step[..., 2], 0.01 * h)
    top = b[..., 1] - h / 2.0 + step[..., 1]
    out = np.empty(np.broadcast_shapes(b.shape, y.shape[:-1] + (4,)))
    out[..., 0] = b[..., 0] + step[..., 0]
    out[..., 1] = top + new_h / 2.0
    out[..., 2] = b[..., 2] * (new_h / h)
    out[..., 3] = new_h
    return out


# --------------------------------------------------------------------------- kernels


def _sqdist(a, b):
    if isinstance(a, torch.Tensor):
        d = (a * a).sum(-1)[:, None] + (b * b).sum(-1)[None, :] - 2.0 * (a @ b.T)
        return d.clamp_min(0.0)
    d = (a * a).sum(-1)[:, None] + (b * b).sum(-1)[None, :] - 2.0 * (a @ b.T)
    return np.maximum(d, 0.0)


def observation_kernel(a: np.ndarray, b: np.ndarray, beta1: float) -> np.ndarray:
    """``exp(−β₁/2 ‖a_i − b_j‖²)``, shape ``(len(a), len(b))`` (no noise term)."""
    a, b = np.atleast_2d(np.asarray(a, float)), np.atleast_2d(np.asarray(b, float))
    return np.exp(-0.5 * float(beta1) * _sqdist(a, b))


def dynamics_kernel(a: np.ndarray, b: np.ndarray, alpha: Sequence[float]) -> np.ndarray:
    """``α₁ exp(−α₂/2 ‖a_i − b_j‖²) + α₃ a_iᵀb_j`` (no noise term; ``alpha[3]`` unused)."""
    a, b = np.atleast_2d(np.asarray(a, float)), np.atleast_2d(np.asarray(b, float))
    a1, a2, a3 = (float(v) for v in alpha[:3])
    return a1 * np.exp(-0.5 * a2 * _sqdist(a, b)) + a3 * (a @ b.T)


def _k_obs_t(a, b, beta1):
    return torch.exp(-0.5 * beta1 * _sqdist(a, b))


def _k_dyn_t(a, b, a1, a2, a3):
    return a1 * torch.exp(-0.5 * a2 * _sqdist(a, b)) + a3 * (a @ b.T)


def _to_unit(v: float, lo: float, hi: float) -> float:
    """Raw parameter ``r`` with ``lo (hi/lo)^sigmoid(r) = v`` (``v`` clipped inside)."""
    u = math.log(v / lo) / math.log(hi / lo)
    u = min(max(u, 1e-6), 1 - 1e-6)
    return math.log(u / (1 - u))


def _from_unit(r, lo: float, hi: float):
    return lo * torch.exp(torch.sigmoid(r) * math.log(hi / lo))


# --------------------------------------------------------------------------- the model


def _segments(lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Indices ``(in, out, starts)`` of the dynamics pairs of concatenated sequences."""
    ends = np.cumsum(lengths)
    starts = ends - lengths
    n = int(ends[-1]) if lengths.size else 0
    last = np.zeros(n, dtype=bool)
    last[ends - 1] = True
    idx = np.arange(n)
    return idx[~last], idx[~last] + 1, starts


@dataclass(eq=False)
class GPDM:
    """A learned GPDM (arrays in the paper's notation; ``W = 1``).

    Attributes
    ----------
    X : ndarray, shape (N, d)
        Latent points of the training sequences, concatenated.
    Y : ndarray, shape (N, D)
        Standardised training observations (``(y − y_mean) / y_std``).
    lengths : ndarray of int, shape (S,)
        Length of each sequence in ``X``/``Y`` (each ≥ 2); the dynamics pairs never
        cross from one to the next.
    alpha : ndarray, shape (4,)
        ``α₁..α₄`` (``α₄`` is the dynamics noise *precision*).
    beta : ndarray, shape (2,)
        ``β₁, β₂`` (``β₂`` is the observation noise precision).
    y_mean, y_std : ndarray, shape (D,)
        Standardisation of the observations (heights per second).
    settings : GPDMSettings
    info : dict
        JSON-able notes on the training run (sources, iterations, objective trace).
    """

    X: np.ndarray
    Y: np.ndarray
    lengths: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    y_mean: np.ndarray
    y_std: np.ndarray
    settings: GPDMSettings = field(default_factory=GPDMSettings)
    info: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        def arr(name, ndim, dtype=float):
            v = np.array(getattr(self, name), dtype=dtype)
            if v.ndim != ndim:
                raise ValueError(f"field {name!r} must have {ndim} dimension(s), got shape "
                                 f"{v.shape}")
            if dtype is float and not np.all(np.isfinite(v)):
                raise ValueError(f"field {name!r} has NaN or infinite values")
            v.setflags(write=False)
            object.__setattr__(self, name, v)
            return v

        X, Y = arr("X", 2), arr("Y", 2)
        lengths = arr("lengths", 1, np.int64)
        alpha, beta = arr("alpha", 1), arr("beta", 1)
        y_mean, y_std = arr("y_mean", 1), arr("y_std", 1)
        if not isinstance(self.settings, GPDMSettings):
            raise ValueError("field 'settings' must be a GPDMSettings")
        n, d = X.shape
        if Y.shape[0] != n or n < 2:
            raise ValueError(f"fields 'X' and 'Y' must have the same number (>= 2) of rows, "
                             f"got {X.shape} and {Y.shape}")
        if d != self.settings.latent_dim:
            raise ValueError(f"field 'X' has latent dimension {d} but settings say "
                             f"{self.settings.latent_dim}")
        if lengths.size < 1 or np.any(lengths < 2) or int(lengths.sum()) != n:
            raise ValueError(f"field 'lengths' must be sequence lengths >= 2 summing to {n}")
        if alpha.shape != (4,) or np.any(alpha <= 0):
            raise ValueError(f"field 'alpha' must hold 4 positive values, got {alpha}")
        if beta.shape != (2,) or np.any(beta <= 0):
            raise ValueError(f"field 'beta' must hold 2 positive values, got {beta}")
        D = Y.shape[1]
        if y_mean.shape != (D,) or y_std.shape != (D,) or np.any(y_std <= 0):
            raise ValueError(f"fields 'y_mean' and 'y_std' must have shape ({D},) with "
                             "y_std > 0")
        self._prepare()

    # ---- precomputation -----------------------------------------------------------

    def _prepare(self) -> None:
        X = torch.tensor(self.X, dtype=_DT)
        Y = torch.tensor(self.Y, dtype=_DT)
        a1, a2, a3, a4 = (float(v) for v in self.alpha)
        b1, b2 = (float(v) for v in self.beta)
        i_in, i_out, starts = _segments(self.lengths)
        x_in, x_out = X[i_in], X[i_out]
        eye = lambda m: torch.eye(m, dtype=_DT)  # noqa: E731
        kx = _k_dyn_t(x_in, x_in, a1, a2, a3) + (1.0 / a4) * eye(len(i_in))
        ky = _k_obs_t(X, X, b1) + (1.0 / b2) * eye(X.shape[0])
        lx, ly = torch.linalg.cholesky(kx), torch.linalg.cholesky(ky)
        self._t = {"x_in": x_in, "A_x": torch.cholesky_solve(x_out, lx),
                   "Kinv_x": torch.cholesky_inverse(lx), "X": X,
                   "A_y": torch.cholesky_solve(Y, ly), "Kinv_y": torch.cholesky_inverse(ly)}
        self._in, self._out, self._starts = i_in, i_out, starts
        # fitted values at the training latents, for the test-time latent's window search
        mu_y, var_y = self.observe(self.X)
        mu_x, var_x = self.dynamics(self.X)
        self._fit = {"mu_y": mu_y, "var_y": var_y, "mu_x": mu_x, "var_x": var_x}

    @property
    def latent_dim(self) -> int:
        return int(self.X.shape[1])

    @property
    def obs_dim(self) -> int:
        return int(self.Y.shape[1])

    # ---- predictive distributions (torch inside; vectorised over points) ------------

    def _dyn_t(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        a1, a2, a3, a4 = (float(v) for v in self.alpha)
        k = _k_dyn_t(z, self._t["x_in"], a1, a2, a3)
        mu = k @ self._t["A_x"]
        kzz = a1 + a3 * (z * z).sum(-1) + 1.0 / a4
        var = kzz - ((k @ self._t["Kinv_x"]) * k).sum(-1)
        return mu, var.clamp_min(1.0 / a4)

    def _obs_t(self, z: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        b1, b2 = (float(v) for v in self.beta)
        k = _k_obs_t(z, self._t["X"], b1)
        mu = k @ self._t["A_y"]
        var = (1.0 + 1.0 / b2) - ((k @ self._t["Kinv_y"]) * k).sum(-1)
        return mu, var.clamp_min(1.0 / b2)

    def dynamics(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Latent transition ``μ_X(x)`` ``(M, d)`` and ``σ²_X(x)`` ``(M,)`` (``α₄⁻¹`` included)."""
        with torch.no_grad():
            mu, var = self._dyn_t(torch.tensor(np.atleast_2d(x), dtype=_DT))
        return mu.numpy(), var.numpy()

    def observe(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Standardised observation mean ``(M, D)`` and variance ``σ²_Y(x)`` ``(M,)``.

        The variance includes ``β₂⁻¹``; in heights per second it is ``σ²_Y(x) y_std²``
        per dimension (the paper's ``σ²_Y W⁻²``).
        """
        with torch.no_grad():
            mu, var = self._obs_t(torch.tensor(np.atleast_2d(x), dtype=_DT))
        return mu.numpy(), var.numpy()

    def mean_y(self, x: np.ndarray) -> np.ndarray:
        """``μ_Y(x) = ȳ + s ⊙ Yᵀ K_Y⁻¹ k_Y(x)`` in box heights per second, ``(M, D)``."""
        return self.y_mean + self.y_std * self.observe(x)[0]

    def standardise(self, y: np.ndarray) -> np.ndarray:
        """Observations in heights per second to the model's standardised units."""
        return (np.asarray(y, float) - self.y_mean) / self.y_std

    # ---- test-time latent ---------------------------------------------------------

    def infer_latent(self, y: np.ndarray) -> np.ndarray:
        """Current latent ``(d,)`` from the last few standardised observations ``(K, D)``.

        Maximises the joint density of a latent path ``z_1..z_K`` (observation terms,
        GP dynamics between consecutive points and the latent prior) starting from the
        best window of ``K`` consecutive training latents, refined by
        :attr:`GPDMSettings.refine_iter` L-BFGS iterations; returns ``z_K``.
        """
        y = np.atleast_2d(np.asarray(y, dtype=float))
        if y.shape[1] != self.obs_dim or y.shape[0] < 1 or not np.all(np.isfinite(y)):
            raise ValueError(f"observations must be finite with shape (K, {self.obs_dim}), "
                             f"got {y.shape}")
        k = min(y.shape[0], int(self.lengths.max()))
        y = y[-k:]
        f = self._fit
        D, d = self.obs_dim, self.latent_dim
        # observation term of every y_k at every training latent: (K, N)
        r2 = ((y[:, None, :] - f["mu_y"][None, :, :]) ** 2).sum(-1)
        nll_obs = 0.5 * r2 / f["var_y"][None] + 0.5 * D * np.log(f["var_y"])[None]
        # dynamics term of each training pair (in -> out), placed at its 'in' index
        nll_dyn = np.zeros(self.X.shape[0])
        dx = ((self.X[self._out] - f["mu_x"][self._in]) ** 2).sum(-1)
        nll_dyn[self._in] = (0.5 * dx / f["var_x"][self._in]
                             + 0.5 * d * np.log(f["var_x"][self._in]))
        pos = np.arange(self.X.shape[0]) - np.repeat(self._starts, self.lengths)
        ends = np.flatnonzero(pos >= k - 1)
        score = np.zeros(ends.shape[0])
        for j in range(k):                       # K is a handful: loop over the window
            score += nll_obs[j, ends - (k - 1) + j]
            if j < k - 1:
                score += nll_dyn[ends - (k - 1) + j]
        best = int(ends[np.argmin(score)])
        z0 = self.X[best - k + 1: best + 1]
        if self.settings.refine_iter == 0:
            return z0[-1].copy()
        with _torch_threads(1):
            return self._refine(z0, y)

    def _refine(self, z0: np.ndarray, y: np.ndarray) -> np.ndarray:
        z = torch.tensor(z0, dtype=_DT, requires_grad=True)
        yt = torch.tensor(y, dtype=_DT)
        D, d = self.obs_dim, self.latent_dim
        prior = self.settings.latent_scale == "prior"

        def objective():
            mu_y, var_y = self._obs_t(z)
            j = 0.5 * (((yt - mu_y) ** 2).sum(-1) / var_y).sum() + 0.5 * D * var_y.log().sum()
            if z.shape[0] > 1:
                mu_x, var_x = self._dyn_t(z[:-1])
                j = j + 0.5 * (((z[1:] - mu_x) ** 2).sum(-1) / var_x).sum()
                j = j + 0.5 * d * var_x.log().sum()
            if prior:
                j = j + 0.5 * (z * z).sum()
            return j

        with torch.no_grad():
            start = float(objective())
        opt = torch.optim.LBFGS([z], lr=1.0, max_iter=self.settings.refine_iter,
                                line_search_fn="strong_wolfe")

        def closure():
            opt.zero_grad()
            loss = objective()
            loss.backward()
            return loss

        opt.step(closure)
        with torch.no_grad():
            end = float(objective())
        out = z.detach().numpy()[-1]
        if not (math.isfinite(end) and end <= start and np.all(np.isfinite(out))):
            return z0[-1].copy()
        return out.copy()

    # ---- the objective (for tests and diagnostics) ----------------------------------

    def objective_terms(self) -> dict[str, float]:
        """The terms of the negative log posterior at the stored parameters.

        ``L_Y`` (without ``(ND/2) ln 2π``), ``L_X`` (weighted if balanced; with the
        starts' prior when there is no latent prior), ``prior`` and ``hyper``.
        """
        with torch.no_grad():
            terms = _objective_terms(torch.from_numpy(np.array(self.X)),
                                     *(torch.tensor(float(v), dtype=_DT) for v in self.alpha),
                                     *(torch.tensor(float(v), dtype=_DT) for v in self.beta),
                                     torch.from_numpy(np.array(self.Y)), self._in, self._out,
                                     self._starts, self.settings)
        return {k: float(v) for k, v in terms.items()}

    # ---- storage ------------------------------------------------------------------

    def save(self, path: str | Path) -> Path:
        """Write the model to ``path`` (``.npz``: arrays + a JSON header; no pickle)."""
        p = Path(path)
        header = {"format": FORMAT, "version": VERSION, "settings": self.settings.to_dict(),
                  "info": _jsonable(self.info)}
        with open(p, "wb") as f:
            np.savez(f, header=np.array(json.dumps(header)),
                     **{name: np.asarray(getattr(self, name)) for name in _ARRAYS})
        return p


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer, int)):
        return int(obj)
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if obj is None or isinstance(obj, str):
        return obj
    return str(obj)


def load_gpdm(path: str | Path) -> GPDM:
    """Read a model written by :meth:`GPDM.save`, validating every field.

    Raises
    ------
    InputError
        (a ``ValueError``) naming the file and the problem: missing file, not an
        ``.npz``, a missing field, a field with NaN/inf, a bad shape, an unknown format
        or version, or invalid settings.
    """
    p = Path(path)
    if not p.is_file():
        raise InputError(f"GPDM model file not found: {p}")
    try:
        with np.load(p, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as e:
        raise InputError(f"{p}: not a readable GPDM .npz file ({one_line(e)})") from None
    for name in ("header",) + _ARRAYS:
        if name not in data:
            raise InputError(f"{p}: missing field {name!r}")
    try:
        header = json.loads(str(data["header"][()]))
        if not isinstance(header, dict):
            raise ValueError("not a JSON object")
    except (ValueError, TypeError, IndexError) as e:
        raise InputError(f"{p}: field 'header' is not valid JSON ({one_line(e)})") from None
    except RecursionError:
        raise InputError(f"{p}: field 'header' is nested too deeply") from None
    for key in ("format", "version", "settings"):
        if key not in header:
            raise InputError(f"{p}: missing header field {key!r}")
    if header["format"] != FORMAT:
        raise InputError(f"{p}: header format is {header['format']!r}, expected {FORMAT!r}")
    if header["version"] != VERSION:
        raise InputError(f"{p}: unsupported GPDM file version {header['version']!r} "
                         f"(this toolkit reads version {VERSION})")
    arrays = {}
    for name in _ARRAYS:
        v = data[name]
        if v.dtype.kind not in "fiu":
            raise InputError(f"{p}: field {name!r} must be numeric, got dtype {v.dtype}")
        if v.dtype.kind == "f" and not np.all(np.isfinite(v)):
            raise InputError(f"{p}: field {name!r} has NaN or infinite values")
        arrays[name] = v
    try:
        settings = GPDMSettings.from_dict(header["settings"])
    except (ValueError, TypeError) as e:
        raise InputError(f"{p}: header settings: {one_line(e)}") from None
    info = header.get("info", {})
    try:
        return GPDM(settings=settings, info=info if isinstance(info, dict) else {}, **arrays)
    except (ValueError, torch.linalg.LinAlgError) as e:
        raise InputError(f"{p}: {one_line(e)}") from None


# --------------------------------------------------------------------------- learning


def _objective_terms(X, a1, a2, a3, nx_prec, b1, ny_prec, Y, i_in, i_out, starts, s):
    """Terms of the negative log posterior (torch; ``nx_prec`` = α₄, ``ny_prec`` = β₂)."""
    n, D = Y.shape
    d = X.shape[1]
    eye = lambda m: torch.eye(m, dtype=_DT)  # noqa: E731
    ky = _k_obs_t(X, X, b1) + eye(n) / ny_prec
    ly = torch.linalg.cholesky(ky)
    l_y = D * torch.log(torch.diagonal(ly)).sum() + 0.5 * (Y * torch.cholesky_solve(Y, ly)).sum()
    x_in, x_out = X[i_in], X[i_out]
    kx = _k_dyn_t(x_in, x_in, a1, a2, a3) + eye(len(i_in)) / nx_prec
    lx = torch.linalg.cholesky(kx)
    l_x = (d * torch.log(torch.diagonal(lx)).sum()
           + 0.5 * (x_out * torch.cholesky_solve(x_out, lx)).sum())
    with_prior = s.latent_scale == "prior"
    if not with_prior:
        l_x = l_x + 0.5 * (X[starts] ** 2).sum()
    if s.balanced:
        l_x = l_x * (D / d)
    prior = 0.5 * (X * X).sum() if with_prior else torch.zeros((), dtype=_DT)
    hyper = (torch.log(a1) + torch.log(a2) + torch.log(a3) + torch.log(nx_prec)
             + torch.log(b1) + torch.log(ny_prec))
    return {"L_Y": l_y, "L_X": l_x, "prior": prior, "hyper": hyper}


def _pca_init(Y: np.ndarray, d: int) -> np.ndarray:
    """PCA of the (already centred) observations, scaled to unit mean square."""
    u, sv, _ = np.linalg.svd(Y - Y.mean(0), full_matrices=False)
    x = u[:, :d] * sv[:d]
    if x.shape[1] < d:                         # fewer observation dimensions than d
        x = np.concatenate([x, np.zeros((x.shape[0], d - x.shape[1]))], axis=1)
    # a deterministic sign per component (SVD's sign is arbitrary)
    x *= np.where(x[np.argmax(np.abs(x), axis=0), np.arange(d)] < 0, -1.0, 1.0)
    return x / max(float(np.sqrt(np.mean(x * x))), 1e-12)


def _subsample(seqs: list[np.ndarray], s: GPDMSettings, rng: np.random.Generator
               ) -> list[np.ndarray]:
    """At most ``max_points`` rows: random chunks of ``chunk_length`` (Generator-drawn)."""
    if sum(len(q) for q in seqs) <= s.max_points:
        return seqs
    chunks = [q[i:i + s.chunk_length] for q in seqs for i in range(0, len(q), s.chunk_length)]
    chunks = [c for c in chunks if len(c) >= 2]
    out, total = [], 0
    for i in rng.permutation(len(chunks)):
        if total + len(chunks[i]) > s.max_points:
            continue
        out.append(chunks[i])
        total += len(chunks[i])
    return out


@contextlib.contextmanager
def _torch_threads(n: int):
    """Run with ``n`` torch threads, restoring the caller's count afterwards.

    The matrices here are small (≤ ``max_points``); extra intra-op threads only add
    contention (a 20× slow-down was measured on a busy two-core machine).
    """
    old = torch.get_num_threads()
    torch.set_num_threads(n)
    try:
        yield
    finally:
        torch.set_num_threads(old)


def fit_gpdm(sequences: Sequence[np.ndarray], settings: GPDMSettings | None = None,
             rng: np.random.Generator | None = None, *, info: dict | None = None) -> GPDM:
    """Learn a GPDM from observation sequences (one GP over all of them).

    Parameters
    ----------
    sequences : sequence of ndarray, each (T_k, D)
        Observations (any units; they are standardised here). Sequences shorter than 2
        rows are skipped.
    settings : GPDMSettings, optional
    rng : numpy.random.Generator
        Draws the chunks kept when the data exceed ``settings.max_points`` (the latent
        initialisation is PCA, deterministic). Required.
    info : dict, optional
        JSON-able notes stored with the model (training time, objective trace and
        convergence are added).

    Returns
    -------
    GPDM
    """
    s = GPDMSettings() if settings is None else settings
    if not isinstance(s, GPDMSettings):
        raise ValueError("settings must be a GPDMSettings")
    rng = as_generator(rng)
    seqs = []
    for i, q in enumerate(sequences):
        a = np.asarray(q, dtype=float)
        if a.ndim != 2:
            raise ValueError(f"sequence {i} must have shape (T, D), got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ValueError(f"sequence {i} has NaN or infinite values")
        if seqs and a.shape[1] != seqs[0].shape[1]:
            raise ValueError(f"sequence {i} has {a.shape[1]} columns, expected "
                             f"{seqs[0].shape[1]}")
        if a.shape[0] >= 2:
            seqs.append(a)
    if not seqs:
        raise ValueError("no training sequence with at least 2 observations")
    t0 = time.perf_counter()
    seqs = _subsample(seqs, s, rng)
    raw = np.concatenate(seqs)
    y_mean = raw.mean(0)
    y_std = raw.std(0)
    if not np.any(y_std > 1e-12):  # the latent start (PCA of nothing) would be 0/0
        raise ValueError("the training sequences do not vary: every observation is the "
                         "same (boxes that all move alike, frame after frame); there is "
                         "no motion to learn")
    y_std = np.where(y_std > 1e-12, y_std, 1.0)
    Y = (raw - y_mean) / y_std
    lengths = np.array([len(q) for q in seqs], dtype=np.int64)
    X0 = _pca_init(Y, s.latent_dim)
    with _torch_threads(1):
        X, alpha, beta, report = _optimise(Y, lengths, X0, s)
    notes = dict(info or {})
    notes.update(report)
    notes.update({"n_points": int(Y.shape[0]), "n_sequences": int(len(lengths)),
                  "train_seconds": time.perf_counter() - t0})
    return GPDM(X=X, Y=Y, lengths=lengths, alpha=alpha, beta=beta, y_mean=y_mean,
                y_std=y_std, settings=s, info=notes)


def _optimise(Y: np.ndarray, lengths: np.ndarray, X0: np.ndarray, s: GPDMSettings):
    i_in, i_out, starts = _segments(lengths)
    Yt = torch.from_numpy(Y)
    Z = torch.tensor(X0, dtype=_DT, requires_grad=True)
    unit = s.latent_scale == "unit"
    n_coords = float(X0.size)

    def latent():
        return Z * torch.sqrt(n_coords / (Z * Z).sum()) if unit else Z
    fx, fy = s.dyn_noise_floor, s.obs_noise_floor
    b = HYPER_BOUNDS
    r_dyn = torch.tensor([_to_unit(1.0, *b["alpha1"]), _to_unit(1.0, *b["alpha2"]),
                          _to_unit(0.1, *b["alpha3"]), _to_unit(max(0.1, 2 * fx), fx, NOISE_UPPER)],
                         dtype=_DT, requires_grad=not s.fix_dynamics)
    r_obs = torch.tensor([_to_unit(1.0, *b["beta1"]), _to_unit(max(0.1, 2 * fy), fy, NOISE_UPPER)],
                         dtype=_DT, requires_grad=True)
    fixed_noise = max(fx, 0.01)

    def hypers():
        if s.fix_dynamics:
            a1, a2, a3 = (torch.tensor(v, dtype=_DT) for v in FIXED_DYNAMICS)
            nx = torch.tensor(fixed_noise, dtype=_DT)
        else:
            a1 = _from_unit(r_dyn[0], *b["alpha1"])
            a2 = _from_unit(r_dyn[1], *b["alpha2"])
            a3 = _from_unit(r_dyn[2], *b["alpha3"])
            nx = _from_unit(r_dyn[3], fx, NOISE_UPPER)
        b1 = _from_unit(r_obs[0], *b["beta1"])
        ny = _from_unit(r_obs[1], fy, NOISE_UPPER)
        return a1, a2, a3, 1.0 / nx, b1, 1.0 / ny

    def objective():
        terms = _objective_terms(latent(), *hypers(), Yt, i_in, i_out, starts, s)
        return terms["L_Y"] + terms["L_X"] + terms["prior"] + terms["hyper"]

    params = [Z, r_obs] + ([] if s.fix_dynamics else [r_dyn])
    opt = torch.optim.LBFGS(params, lr=1.0, max_iter=s.check_every, history_size=20,
                            line_search_fn="strong_wolfe", tolerance_grad=1e-9,
                            tolerance_change=1e-12)

    def closure():
        opt.zero_grad()
        loss = objective()
        loss.backward()
        return loss

    def snapshot():
        return [p.detach().clone() for p in params]

    with torch.no_grad():
        prev = float(objective())
    trace, best, best_val = [prev], snapshot(), prev
    n_iter, converged = 0, False
    group = opt.param_groups[0]
    while n_iter < s.max_iter:
        # the last round stops at the cap: --max-iter 1 is one iteration, not a round
        group["max_iter"] = min(s.check_every, s.max_iter - n_iter)
        group["max_eval"] = group["max_iter"] * 5 // 4
        opt.step(closure)
        done = int(opt.state[params[0]].get("n_iter", 0))
        with torch.no_grad():
            cur = float(objective())
        trace.append(cur)
        if math.isfinite(cur) and cur < best_val:
            best, best_val = snapshot(), cur
        if not math.isfinite(cur):
            break
        if abs(prev - cur) <= s.rel_tol * max(1.0, abs(prev)) or done == n_iter:
            converged = True
            n_iter = done
            break
        prev, n_iter = cur, done
    with torch.no_grad():
        for p, v in zip(params, best, strict=True):
            p.copy_(v)
        a1, a2, a3, a4, b1, b2 = (float(v) for v in hypers())
        X = latent()
    report = {"iterations": int(n_iter), "converged": bool(converged),
              "objective": best_val, "objective_trace": trace[:400]}
    return (X.detach().numpy().copy(), np.array([a1, a2, a3, a4]), np.array([b1, b2]), report)


def learn_gpdm(trajectories: Sequence[Trajectory], settings: GPDMSettings | None = None,
               rng: np.random.Generator | None = None) -> GPDM:
    """Learn a GPDM of box motion from trajectories (e.g. :func:`gt_trajectories`).

    Each trajectory becomes one sequence of :func:`box_differences` at its own frame
    rate (heights per second make sequences at different frame rates comparable,
    though the latent *step* is still one frame of each); with
    :attr:`GPDMSettings.mirror` each is added again with ``Δcx`` negated.
    """
    s = GPDMSettings() if settings is None else settings
    seqs, sources = [], set()
    for t in trajectories:
        if not isinstance(t, Trajectory):
            raise ValueError(f"trajectories must be Trajectory objects, got {type(t).__name__}")
        if len(t) < 3:
            continue
        y = box_differences(t.boxes, t.fps)
        seqs.append(y)
        sources.add(t.source)
        if s.mirror:
            seqs.append(y * np.array([-1.0, 1.0, 1.0]))
    if not seqs:
        raise ValueError("no trajectory with at least 3 boxes to learn from")
    info = {"sources": sorted(sources), "n_trajectories": len(trajectories),
            "observation": "(dcx, dtop, dh) / h * fps  [box heights per second]"}
    return fit_gpdm(seqs, s, rng, info=info)


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
