"""Calibration of a probability: reliability diagram, expected calibration error, Brier.

A tracker that reports a confidence ``c`` per frame claims that the box overlaps the
truth (IoU ≥ 0.5) with probability ``c``. Binning the frames by ``c`` and comparing each
bin's mean confidence with its hit rate gives the reliability diagram; the expected
calibration error (ECE) is the frame-weighted mean absolute gap over the bins
(Guo et al. [#guo2017]), and the Brier score the mean squared error of ``c`` against the
0/1 outcome.

.. [#guo2017] C. Guo, G. Pleiss, Y. Sun and K. Q. Weinberger, "On calibration of modern
   neural networks", Proc. ICML 2017, PMLR 70, 1321–1330.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["reliability", "video_weights", "confidence_outcomes", "lost_signal"]


def confidence_outcomes(frames: Any, confidence: Any, scored_frames: Any, ious: Any
                        ) -> tuple[np.ndarray, np.ndarray]:
    """A track's confidence per frame (``frames``, ``confidence``) paired with its
    outcome at the scored frames (``scored_frames``, IoU with the truth ``ious``; NaN:
    no box, a miss): ``(c, hit)`` at the scored frames that have a confidence, ``hit``
    meaning IoU ≥ 0.5."""
    frames = np.asarray(frames, dtype=float).reshape(-1)
    confidence = np.asarray(confidence, dtype=float).reshape(-1)
    scored = np.asarray(scored_frames, dtype=float).reshape(-1)
    ious = np.asarray(ious, dtype=float).reshape(-1)
    if frames.size != confidence.size:
        raise ValueError(f"{confidence.size} confidences for {frames.size} frames")
    if scored.size != ious.size:
        raise ValueError(f"{ious.size} IoUs for {scored.size} scored frames")
    at = dict(zip(frames.tolist(), confidence.tolist(), strict=True))
    keep = np.array([f in at for f in scored.tolist()], dtype=bool)
    c = np.array([at[f] for f in scored[keep].tolist()], dtype=float)
    with np.errstate(invalid="ignore"):
        return c, ious[keep] >= 0.5


def video_weights(videos: Any) -> np.ndarray:
    """Per-frame weights under which every video (equal labels in ``videos``, one per
    frame) has the same total weight, normalised to a mean of 1: pass them to
    :func:`reliability` to pool several videos (seeds of one video share its weight),
    or to a fit so that the longest video does not decide it alone."""
    videos = np.asarray(videos)
    if videos.size == 0:
        raise ValueError("no frames to weight")
    _, inverse, counts = np.unique(videos, return_inverse=True, return_counts=True)
    w = 1.0 / counts[inverse]
    return w * (len(w) / w.sum())


def reliability(confidence: Any, outcome: Any, n_bins: int = 10,
                weights: Any = None) -> dict[str, Any]:
    """Reliability diagram of ``confidence`` in [0, 1] against 0/1 ``outcome``.

    ``weights`` (one non-negative number per frame; all equal when None) weight every
    statistic: e.g. ``1 / frames of its video`` pools several videos with each counting
    the same, the diagram of a frame drawn from a video drawn at random.

    Returns a JSON-serialisable dict: ``n``, ``ece``, ``brier``, ``mean_confidence``,
    ``hit_rate`` and ``bins`` (one entry per non-empty equal-width bin: ``lo``, ``hi``,
    ``n`` (frames), ``share`` (of the total weight), ``confidence`` (mean),
    ``hit_rate``).
    """
    c = np.asarray(confidence, dtype=float).reshape(-1)
    y = np.asarray(outcome, dtype=float).reshape(-1)
    if c.shape != y.shape:
        raise ValueError(f"{c.size} confidences but {y.size} outcomes")
    if c.size == 0:
        raise ValueError("no frames to assess calibration on")
    if not np.all(np.isfinite(c)) or np.any((c < 0) | (c > 1)):
        raise ValueError("confidences must be finite and in [0, 1]")
    if np.any((y != 0) & (y != 1)):
        raise ValueError("outcomes must be 0 or 1")
    if int(n_bins) < 1:
        raise ValueError(f"n_bins must be positive, got {n_bins}")
    if weights is None:
        w = np.full(c.size, 1.0 / c.size)
    else:
        w = np.asarray(weights, dtype=float).reshape(-1)
        if w.shape != c.shape:
            raise ValueError(f"{w.size} weights but {c.size} confidences")
        if not np.all(np.isfinite(w)) or np.any(w < 0) or not w.sum() > 0:
            raise ValueError("weights must be finite, non-negative and not all zero")
        w = w / w.sum()
    edges = np.linspace(0.0, 1.0, int(n_bins) + 1)
    idx = np.clip(np.searchsorted(edges, c, side="right") - 1, 0, int(n_bins) - 1)
    bins, ece = [], 0.0
    for b in range(int(n_bins)):
        sel = idx == b
        share = float(w[sel].sum())
        if not share > 0:
            continue
        mc, hr = float(w[sel] @ c[sel] / share), float(w[sel] @ y[sel] / share)
        ece += share * abs(mc - hr)
        bins.append({"lo": float(edges[b]), "hi": float(edges[b + 1]), "n": int(sel.sum()),
                     "share": share, "confidence": mc, "hit_rate": hr})
    return {"n": int(c.size), "ece": float(ece), "brier": float(w @ (c - y) ** 2),
            "mean_confidence": float(w @ c), "hit_rate": float(w @ y), "bins": bins}


def lost_signal(confidence: Any, hit: Any, threshold: float,
                weights: Any = None) -> dict[str, Any]:
    """How well ``confidence < threshold`` flags the frames where the tracker has lost its
    target (``hit`` false: its box overlaps the truth by less than half).

    Returns ``threshold``; ``flagged`` and ``lost`` (frame counts); ``precision`` (the
    share of flagged frames that are lost) and ``recall`` (the share of lost frames that
    are flagged), each weighted by ``weights`` (e.g. :func:`video_weights`) and ``None``
    where undefined (nothing flagged, nothing lost).

    >>> r = lost_signal([0.9, 0.2, 0.1, 0.8], [True, False, True, False], 0.5)
    >>> r["precision"], r["recall"]
    (0.5, 0.5)
    """
    c = np.asarray(confidence, dtype=float).reshape(-1)
    lost = ~np.asarray(hit, dtype=bool).reshape(-1)
    if c.shape != lost.shape:
        raise ValueError(f"{c.size} confidences but {lost.size} outcomes")
    t = float(threshold)
    if not 0.0 <= t <= 1.0:
        raise ValueError(f"the lost threshold must be in [0, 1], got {threshold!r}")
    w = np.ones(c.size) if weights is None else np.asarray(weights, dtype=float).reshape(-1)
    flagged = c < t
    both = float(np.sum(w[flagged & lost]))
    wf, wl = float(np.sum(w[flagged])), float(np.sum(w[lost]))
    return {"threshold": t, "flagged": int(flagged.sum()), "lost": int(lost.sum()),
            "precision": both / wf if wf > 0 else None,
            "recall": both / wl if wl > 0 else None}
