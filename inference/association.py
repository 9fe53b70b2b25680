"""Exact Kalman replicas and data association: the rules of tracking by detection.

The rules the engine applies to a plate whose box state holds a
:class:`~pgm.core.batched.BatchedGaussian` (``Engine(..., belief_types={"box":
Gaussian})``; the factors are :mod:`pgm.factors.association`'s):

* **predict** — :class:`~pgm.factors.LinearGaussianTransition` on every replica at once,
  ``m ← F m``, ``P ← F P Fᵀ + Q`` (a SORT ``cx, cy, s, r`` state whose area would turn
  non-positive has its area rate set to zero first, as SORT does); when the frame
  carries the camera's image motion, the states are first moved through it
  (:func:`pgm.core.motion.linear_state_warp`: ``m ← T m + c``, ``P ← T P Tᵀ``, the
  camera-motion compensation of BoT-SORT);
* **assign** — :class:`~pgm.factors.association.DetectionAssociation`: the predicted boxes
  against the frame's detections, Hungarian assignment on IoU, round by round
  (:class:`Assignment`, kept as ``engine.assignment`` for the frame);
* **weight** — :class:`~pgm.factors.association.AssignedDetectionLikelihood`: the Kalman
  update of each assigned replica with its detection (Joseph form), batched;
  with a :class:`~pgm.factors.multitarget.VBNoise` factor on it, the VB adaptive Kalman
  filter of seed 000 (each replica its own inverse-Gamma measurement noise) instead;
* **estimate** — the means; no resampling.

The lifecycle (``associate`` stage, :mod:`pgm.inference.plates`) reads the assignment.

>>> import numpy as np
>>> from pgm.core.batched import BatchedGaussian
>>> b = BatchedGaussian(np.zeros((2, 2)), np.stack([np.eye(2)] * 2))
>>> m, P = kalman_update_batch(b.mean, b.cov, np.eye(2), np.eye(2), np.ones((2, 2)))
>>> m.round(2).tolist()
[[0.5, 0.5], [0.5, 0.5]]
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.batched import BatchedGaussian, Replicated
from pgm.core.boxes import box_coding, encode_boxes, state_boxes
from pgm.core.expfam import InverseGamma
from pgm.core.frame import FrameContext
from pgm.core.motion import linear_state_warp
from pgm.factors import GaussianPrior, LinearGaussianTransition
from pgm.factors.association import AssignedDetectionLikelihood, DetectionAssociation
from pgm.factors.multitarget import VBNoise

from .engine import Engine
from .rules import DEFAULT_RULES

__all__ = ["Assignment", "assign", "kalman_update_batch", "detection_boxes", "iou_matrix"]


@dataclass
class Assignment:
    """A frame's detections given to a plate's replicas.

    Attributes
    ----------
    rows, cols : ndarray of int
        Matched replica and detection indices (round by round, each round in replica
        order).
    boxes : ndarray (M, 4)
        The frame's detection boxes, centre ``(cx, cy, w, h)``.
    scores : ndarray (M,)
        Their scores after the association's score map.
    iou : ndarray (K, M)
        IoU of each replica's predicted box with each detection.
    rounds : ndarray of int
        The round that made each match.
    """

    rows: np.ndarray
    cols: np.ndarray
    boxes: np.ndarray
    scores: np.ndarray
    iou: np.ndarray
    rounds: np.ndarray

    def detection_of(self, K: int) -> np.ndarray:  # noqa: N803
        """``(K,)`` the detection index assigned to each replica, −1 for none."""
        out = np.full(K, -1, dtype=int)
        out[self.rows] = self.cols
        return out


def detection_boxes(frame: FrameContext) -> np.ndarray:
    """The frame's detections as centre boxes ``(M, 4)``."""
    d = frame.detections
    if d is None:
        return np.zeros((0, 4))
    b = np.array(d.boxes, dtype=float).reshape(-1, 4)
    b[:, :2] += b[:, 2:] / 2.0
    return b


def assign(pred: np.ndarray, boxes: np.ndarray, scores: np.ndarray,
           rounds: list[dict[str, float]]) -> Assignment:
    """Assign detections ``boxes`` (centre, ``(M, 4)``) with mapped ``scores`` to predicted
    boxes ``pred`` ``(K, 4)`` in ``rounds`` (:class:`~pgm.factors.association.
    DetectionAssociation`): in each, the Hungarian assignment maximising IoU between
    the replicas still free and the round's detections; pairs below the gate are no
    match."""
    from scipy.optimize import linear_sum_assignment

    K, M = len(pred), len(boxes)  # noqa: N806
    iou = iou_matrix(pred, boxes) if K and M else np.zeros((K, M))
    free = np.ones(K, dtype=bool)
    rows: list[np.ndarray] = []
    cols: list[np.ndarray] = []
    made: list[np.ndarray] = []
    for i, r in enumerate(rounds):
        ks = np.flatnonzero(free)
        js = np.flatnonzero((scores >= r["min_score"]) & (scores < r["max_score"]))
        if not len(ks) or not len(js):
            continue
        sub = iou if len(ks) == K and len(js) == M else iou[np.ix_(ks, js)]
        a, b = linear_sum_assignment(sub, maximize=True)
        ok = sub[a, b] >= r["iou"]
        rows.append(ks[a[ok]])
        cols.append(js[b[ok]])
        made.append(np.full(int(ok.sum()), i))
        free[ks[a[ok]]] = False
    cat = lambda xs: np.concatenate(xs) if xs else np.zeros(0, dtype=int)  # noqa: E731
    return Assignment(cat(rows), cat(cols), boxes, scores, iou, cat(made))


def iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(K, M)`` IoU of centre boxes ``a`` ``(K, 4)`` and ``b`` ``(M, 4)`` (0 where a box is
    not finite or has no area)."""
    ha, hb = a[:, 2:] * 0.5, b[:, 2:] * 0.5
    wh = (np.minimum((a[:, :2] + ha)[:, None], (b[:, :2] + hb)[None])
          - np.maximum((a[:, :2] - ha)[:, None], (b[:, :2] - hb)[None]))
    np.maximum(wh, 0.0, out=wh)
    inter = wh[..., 0] * wh[..., 1]
    union = (a[:, 2] * a[:, 3])[:, None] + (b[:, 2] * b[:, 3])[None] - inter
    ok = union > 0  # False for NaN too
    if ok.all():
        out = np.minimum(inter / union, 1.0)
        if np.isfinite(out).all():
            return out
    with np.errstate(invalid="ignore", divide="ignore"):
        out = inter / np.where(ok, union, 1.0)
    return np.where(ok & np.isfinite(out), np.clip(out, 0.0, 1.0), 0.0)


def selects(H: np.ndarray) -> bool:
    """Whether ``H`` reads the first ``k`` components of the state (``[I 0]``)."""
    k = H.shape[0]
    return H.shape[1] >= k and bool(np.array_equal(H, np.eye(k, H.shape[1])))


def kalman_update_batch(m: np.ndarray, P: np.ndarray, H: np.ndarray, R: np.ndarray,
                        z: np.ndarray, select: bool | None = None
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Kalman updates of ``B`` Gaussians at once: means ``(B, d)``, covariances
    ``(B, d, d)``, measurements ``z`` ``(B, k)``, noise ``R`` ``(k, k)`` or ``(B, k, k)``;
    ``P ← P − K S Kᵀ``, symmetrised (as :func:`pgm.inference.kalman.kalman_update`).
    ``select``: whether ``H = [I 0]`` (:func:`selects`; found out when not given)."""
    k = H.shape[0]
    if select if select is not None else selects(H):  # H reads the box: slices, no products
        PHt = P[:, :, :k]
        S = P[:, :k, :k] + R
    else:
        PHt = P @ H.T  # (B, d, k)
        S = H @ PHt + R  # (B, k, k)
    K = np.linalg.solve(S, np.swapaxes(PHt, 1, 2)).swapaxes(1, 2)  # P Hᵀ S⁻¹ (S symmetric)
    r = z - m @ H.T
    m = m + np.einsum("bdk,bk->bd", K, r)
    P = P - K @ np.swapaxes(PHt, 1, 2)
    P = 0.5 * (P + np.swapaxes(P, 1, 2))
    return m, P


@DEFAULT_RULES.register(GaussianPrior, BatchedGaussian)
def prior_gaussians(engine: Engine, factor, frame: FrameContext) -> None:
    """Each replica's prior (its own, re-centred on its birth box), stacked."""
    priors = [g.factors[factor.name] for g in engine.replicas.graphs]
    engine.beliefs[factor.variables[0]] = BatchedGaussian(
        np.stack([p.mean() for p in priors]), np.stack([p.cov for p in priors]))


@DEFAULT_RULES.register(LinearGaussianTransition, BatchedGaussian)
def predict_gaussians(engine: Engine, factor, frame: FrameContext) -> None:
    """``m ← F m``, ``P ← F P Fᵀ + Q`` for every replica."""
    var = factor.variables[0]
    b: BatchedGaussian = engine.beliefs[var]
    m, P = b.mean, b.cov
    labels = engine.graph.variables[var].labels
    warp = linear_state_warp(labels, frame.camera_motion)
    if warp is not None:  # the camera moved: last frame's states into this frame's image
        T, c = warp
        m, P = m @ T.T + c, T @ P @ T.T
    if box_coding(labels) == "xysr" and "vs" in labels:  # keep the area positive
        s, vs = labels.index("s"), labels.index("vs")
        m = m.copy()
        m[m[:, s] + m[:, vs] <= 0, vs] = 0.0
    F = factor.F
    Q = factor.noise_cov(m) if hasattr(factor, "noise_cov") else factor.Q  # scale-aware
    engine.beliefs[var] = BatchedGaussian(m @ F.T, F @ P @ F.T + Q)


@DEFAULT_RULES.register(DetectionAssociation, BatchedGaussian)
def assign_detections(engine: Engine, factor, frame: FrameContext) -> dict[str, Any]:
    """The ``assign`` stage: ``engine.assignment`` for this frame."""
    var = factor.variables[0]
    pred = state_boxes(engine.graph.variables[var].labels, engine.beliefs[var].mean)
    a = assign(pred, detection_boxes(frame), factor.scores(frame), factor.rounds)
    engine.assignment = a
    # per replica, the index of its detection (NaN: none), a float so that replicas born
    # later in the frame read NaN too
    matched = np.full(len(pred), np.nan)
    matched[a.rows] = a.cols
    return {"matched": matched}


def _assigned(engine: Engine, factor) -> tuple[np.ndarray, np.ndarray] | None:
    """The assigned replicas and their coded detection boxes, or None."""
    a: Assignment | None = engine.assignment
    if a is None or not len(a.rows):
        return None
    coding = box_coding(engine.graph.variables[factor.variables[0]].labels)
    return a.rows, encode_boxes(a.boxes[a.cols], coding)


@DEFAULT_RULES.register(AssignedDetectionLikelihood, BatchedGaussian)
def update_assigned(engine: Engine, factor, frame: FrameContext) -> None:
    """Kalman update of every replica a detection was assigned to."""
    got = _assigned(engine, factor)
    if got is None:
        return None
    rows, z = got
    var = factor.variables[0]
    b: BatchedGaussian = engine.beliefs[var]
    m0 = b.mean[rows]
    m, P = kalman_update_batch(m0, b.cov[rows], factor.H, factor.noise_cov(m0), z,
                               factor.selects)
    mean, cov = b.mean.copy(), b.cov.copy()
    mean[rows], cov[rows] = m, P
    engine.beliefs[var] = BatchedGaussian(mean, cov)
    return None


@DEFAULT_RULES.register(VBNoise, BatchedGaussian)
def vb_assigned(engine: Engine, factor, frame: FrameContext) -> dict[str, Any] | None:
    """Seed 000's VB adaptive measurement noise per replica, batched: for each assigned
    replica the fixed point of ``q(x) q(R)`` (:func:`pgm.inference.vb.vb_akf_update`, all
    replicas at once; ``R = diag(β / α)``)."""
    noise, target = factor.variables
    liks = [f for f in engine.graph.factors_of(target, "likelihood")
            if factor.likelihood in (None, f.name)]
    if len(liks) == 1 and not isinstance(liks[0], AssignedDetectionLikelihood):
        # a likelihood of the frame's own measurements: the single-graph VB-AKF, per replica
        from .batched import per_replica
        from .vb import _vb_gaussian

        return per_replica(_vb_gaussian, VBNoise)(engine, factor, frame)
    if len(liks) != 1:
        raise ValueError(f"factor {factor.name!r}: needs one likelihood on {target!r}")
    if getattr(factor, "tie", None) is not None:
        raise ValueError(f"factor {factor.name!r}: tied noise components are implemented "
                         f"for the VB-PHD (Intensity) rule only")
    got = _assigned(engine, liks[0])
    if got is None:
        return None
    rows, z = got
    H = liks[0].H
    b: BatchedGaussian = engine.beliefs[target]
    q: Replicated = engine.beliefs[noise]
    alpha0 = np.stack([q.row(int(k)).alpha for k in rows])
    beta0 = np.stack([q.row(int(k)).beta for k in rows])
    m0, P0 = b.mean[rows], b.cov[rows]
    # scale-aware noise: the noise belief is of the variance in units of the box's size
    # along each component's axis (R = diag(r · size²)); residuals are measured so too
    sizes = liks[0].scales(m0)
    size2 = 1.0 if sizes is None else sizes ** 2
    alpha = alpha0 + 0.5
    beta = beta0.copy()
    r_hat = beta / alpha
    it = 0
    for it in range(1, factor.max_iter + 1):  # noqa: B007 - the count is reported
        R = np.einsum("bk,kl->bkl", r_hat * size2, np.eye(H.shape[0]))
        m, P = kalman_update_batch(m0, P0, H, R, z, liks[0].selects)
        resid = z - m @ H.T
        hph = np.einsum("kd,bde,ke->bk", H, P, H)
        beta = beta0 + 0.5 * resid ** 2 / size2 + 0.5 * hph / size2
        new_r = beta / alpha
        change = np.max(np.abs(new_r - r_hat) / r_hat)
        r_hat = new_r
        if change < factor.tol:
            break
    mean, cov = b.mean.copy(), b.cov.copy()
    mean[rows], cov[rows] = m, P
    engine.beliefs[target] = BatchedGaussian(mean, cov)
    items = list(q.rows())
    for i, k in enumerate(rows):
        items[int(k)] = InverseGamma(alpha[i], beta[i])
    engine.beliefs[noise] = type(q).stack(items)
    return {"iterations": it}


@DEFAULT_RULES.register("estimate", BatchedGaussian)
def estimate_gaussians(engine: Engine, variable: str, frame) -> np.ndarray:
    """The replicas' means ``(K, d)``."""
    return engine.beliefs[variable].mean.copy()


@DEFAULT_RULES.register("resample", BatchedGaussian)
def no_resample(engine: Engine, variable: str, frame) -> None:
    """Nothing to resample."""
    return None
