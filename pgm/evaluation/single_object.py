"""Single-object tracking metrics in the OTB convention of Wu, Lim & Yang [#wu2013].

Scored over the annotated ground-truth frames only:

* **IoU** per frame (clipped to ``[0, 1]``);
* **success AUC** = the mean, over the 21 thresholds ``t in {0, 0.05, ..., 1}``, of the
  fraction of frames with ``IoU > t`` (strict). Because ``t = 1`` is included and the
  comparison is strict, even a perfect tracker scores ``20/21 ≈ 0.952``: this is the
  OTB toolkit's convention, kept so numbers compare with published ones;
* **precision@20** = the fraction of frames whose centre error is ``<= 20`` px.

Boxes are top-left ``(x, y, w, h)`` in the same coordinates for ground truth and
prediction (0-based internally; see :mod:`pgm.core.boxes`).

References
----------
.. [#wu2013] Y. Wu, J. Lim and M.-H. Yang, "Online object tracking: a benchmark", Proc. CVPR
   2013, 2411–2418. doi:10.1109/CVPR.2013.312
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pgm.core.boxes import centre_xywh, iou_xywh
from pgm.core.errors import InputError
from pgm.io.annotations import SingleTrack

__all__ = [
    "SUCCESS_THRESHOLDS",
    "PRECISION_THRESHOLDS",
    "success_curve",
    "success_auc",
    "precision_curve",
    "precision_at",
    "single_object_metrics",
]

SUCCESS_THRESHOLDS: np.ndarray = np.arange(21) / 20.0
"""IoU thresholds ``0, 0.05, ..., 1`` (computed as ``k / 20``, exactly rounded)."""

PRECISION_THRESHOLDS: np.ndarray = np.arange(51, dtype=float)
"""Centre-error thresholds ``0, 1, ..., 50`` px."""


def _as_1d(values: Any, what: str) -> np.ndarray:
    a = np.asarray(values, dtype=float).reshape(-1)
    if a.size == 0:
        raise InputError(f"no {what} to score (empty input)")
    return a


def success_curve(ious: Any, thresholds: np.ndarray = SUCCESS_THRESHOLDS) -> np.ndarray:
    """Fraction of frames with ``IoU > t`` for each threshold ``t`` (strict; NaN fails)."""
    a = _as_1d(ious, "IoUs")
    return np.mean(a[:, None] > np.asarray(thresholds, dtype=float)[None, :], axis=0)


def success_auc(ious: Any) -> float:
    """OTB success AUC: mean of :func:`success_curve` over the 21 thresholds.

    A frame with IoU ``u in [0, 1]`` passes ``#{k : u > k/20}`` of the 21 thresholds
    (``ceil(20 u)``), so ``AUC = mean(ceil(20 u)) / 21``: at most ``20/21`` — a perfect
    tracker does not reach 1 (the OTB convention).

    Parameters
    ----------
    ious : array_like, shape (n,)
        IoU per scored frame (0 for a missing prediction).

    Returns
    -------
    float
    """
    return float(np.mean(success_curve(ious)))


def precision_curve(centre_errors: Any,
                    thresholds: np.ndarray = PRECISION_THRESHOLDS) -> np.ndarray:
    """Fraction of frames with centre error ``<= t`` for each threshold (inf/NaN miss)."""
    e = _as_1d(centre_errors, "centre errors")
    return np.mean(e[:, None] <= np.asarray(thresholds, dtype=float)[None, :], axis=0)


def precision_at(centre_errors: Any, threshold: float = 20.0) -> float:
    """Fraction of frames whose centre error is ``<= threshold`` px.

    Parameters
    ----------
    centre_errors : array_like, shape (n,)
        Euclidean centre distance per scored frame; ``inf`` (missing prediction) and NaN
        count as misses.
    threshold : float
        Pixels (20 in OTB).

    Returns
    -------
    float
    """
    return float(precision_curve(centre_errors, np.array([float(threshold)]))[0])


def _finite_or_none(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def single_object_metrics(gt: SingleTrack, pred_frames: Any,
                          pred_boxes_xywh: Any) -> dict[str, Any]:
    """Score a single-object track against ground truth (OTB metrics).

    Parameters
    ----------
    gt : SingleTrack
        Ground truth (:func:`pgm.io.annotations.load_single_gt`): ``frames`` (K,) and
        top-left ``boxes`` (K, 4). Only these frames are scored.
    pred_frames : array_like of int, shape (M,)
        1-based frame numbers of the predictions (each at most once).
    pred_boxes_xywh : array_like, shape (M, 4)
        Predicted top-left ``(x, y, w, h)`` in the same coordinates as ``gt.boxes``.

    Returns
    -------
    dict
        JSON-serialisable (plain floats, ints, lists; ``None`` where undefined):

        ``n_frames``
            Scored (annotated) frames.
        ``n_missing``
            Annotated frames with no prediction (or a non-finite one): IoU 0 and centre
            error ``+inf`` — a miss for precision, left out of the centre-error mean
            and median.
        ``success_auc``, ``precision_at_20``, ``mean_iou``
            See the module docstring; ``success_auc`` of a perfect track is ``20/21``.
        ``success_curve``, ``precision_curve``
            21 and 51 values, at the ``thresholds`` below.
        ``mean_centre_error``, ``median_centre_error``
            See the module docstring.
        ``thresholds``
            ``{'success': [0, 0.05, ..., 1], 'precision': [0, 1, ..., 50]}``.
        ``frames``, ``ious``, ``centre_errors``
            Per scored frame (``None`` error for a missing prediction).

    Raises
    ------
    InputError
        Mismatched lengths, a prediction frame given twice, or empty ground truth.
    """
    g_frames = np.asarray(gt.frames, dtype=np.int64).reshape(-1)
    g_boxes = np.asarray(gt.boxes, dtype=float).reshape(-1, 4)
    if g_frames.size == 0:
        raise InputError("ground truth has no annotated frame to score")
    p_frames = np.asarray(pred_frames, dtype=np.int64).reshape(-1)
    p_boxes = np.asarray(pred_boxes_xywh, dtype=float).reshape(-1, 4)
    if p_frames.shape[0] != p_boxes.shape[0]:
        raise InputError(f"{p_frames.shape[0]} prediction frames but {p_boxes.shape[0]}"
                         " prediction boxes")
    order = np.argsort(p_frames, kind="stable")
    p_frames, p_boxes = p_frames[order], p_boxes[order]
    dup = np.flatnonzero(np.diff(p_frames) == 0)
    if dup.size:
        raise InputError(f"frame {int(p_frames[dup[0]])} has two predictions")

    pos = np.clip(np.searchsorted(p_frames, g_frames), 0, max(p_frames.size - 1, 0))
    if p_frames.size:
        found = p_frames[pos] == g_frames
        matched = p_boxes[pos]
    else:
        found = np.zeros(g_frames.shape, dtype=bool)
        matched = np.zeros_like(g_boxes)
    found &= np.all(np.isfinite(matched), axis=1)

    ious = np.where(found, np.clip(iou_xywh(g_boxes, matched), 0.0, 1.0), 0.0)
    diff = centre_xywh(matched) - centre_xywh(g_boxes)
    errors = np.where(found, np.hypot(diff[:, 0], diff[:, 1]), np.inf)
    finite = errors[np.isfinite(errors)]

    s_curve = success_curve(ious)
    p_curve = precision_curve(errors)
    return {
        "n_frames": int(g_frames.size),
        "n_missing": int(np.count_nonzero(~found)),
        "success_auc": float(np.mean(s_curve)),
        "precision_at_20": precision_at(errors, 20.0),
        "mean_iou": float(np.mean(ious)),
        "mean_centre_error": _finite_or_none(np.mean(finite)) if finite.size else None,
        "median_centre_error": _finite_or_none(np.median(finite)) if finite.size else None,
        "success_curve": [float(v) for v in s_curve],
        "precision_curve": [float(v) for v in p_curve],
        "thresholds": {"success": [float(v) for v in SUCCESS_THRESHOLDS],
                       "precision": [float(v) for v in PRECISION_THRESHOLDS]},
        "frames": [int(v) for v in g_frames],
        "ious": [float(v) for v in ious],
        "centre_errors": [float(v) if np.isfinite(v) else None for v in errors],
    }
