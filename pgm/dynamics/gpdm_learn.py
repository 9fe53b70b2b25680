"""Learning a GPDM: the MAP objective and its bounded L-BFGS optimisation (see
:mod:`pgm.dynamics.gpdm`)."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np
import torch

from pgm.core.rng import as_generator

from .gpdm_data import Trajectory, box_differences
from .gpdm_model import (
    _DT,
    FIXED_DYNAMICS,
    GPDM,
    HYPER_BOUNDS,
    NOISE_UPPER,
    GPDMSettings,
    _from_unit,
    _objective_terms,
    _segments,
    _to_unit,
    _torch_threads,
)

# --------------------------------------------------------------------------- learning


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
