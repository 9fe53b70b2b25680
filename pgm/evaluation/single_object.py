"""Single-object tracking metrics in the OTB convention of Wu, Lim & Yang [#wu2013].

Scored over the annotated ground-truth frames only:

* **IoU** per frame (clipped to ``[0, 1]``);
* **success AUC** = the mean, over the 21 thresholds ``t in {0, 0.05, ..., 1}``, of the
  fraction of frames with ``IoU > t`` (strict). Because ``t = 1`` is included and the
  comparison is strict, even a perfect tracker scores ``20/21 ≈ 0.952``: this is the
  OTB toolkit's convention, kept so numbers compare with published ones;
* **precision@20** = the fraction of frames whose centre error is ``<= 20`` px.

A sequence whose annotation marks frames where the object is **absent** (UAV123's ``NaN``
rows) is scored on its visible frames as above, and also by the long-term measures of
Lukežič et al. [#lukezic2020] (VOT's long-term challenge), which read the tracker's
confidence and reward reporting "absent": at a confidence threshold ``τ`` the tracker
reports its box on the frames whose confidence is at least ``τ``;

* **tracking precision** ``Pr(τ)`` = the mean IoU over the frames where it reports a box
  (an IoU of 0 where the object is absent);
* **tracking recall** ``Re(τ)`` = the mean IoU over the frames where the object is
  visible (0 where no box is reported);
* **F-score** = ``max_τ 2 Pr Re / (Pr + Re)``, with ``Pr`` and ``Re`` at that ``τ``.

The *absence signal* (:func:`absence_signal`) scores ``confidence < threshold`` as a
detector of the annotated absences: its precision and recall.

Boxes are top-left ``(x, y, w, h)`` in the same coordinates for ground truth and
prediction (0-based internally; see :mod:`pgm.core.boxes`).

References
----------
.. [#wu2013] Y. Wu, J. Lim and M.-H. Yang, "Online object tracking: a benchmark", Proc. CVPR
   2013, 2411–2418. doi:10.1109/CVPR.2013.312
.. [#lukezic2020] A. Lukežič, L. Čehovin Zajc, T. Vojíř, J. Matas and M. Kristan,
   "Performance evaluation methodology for long-term single-object tracking", IEEE
   Trans. Cybernetics 51(12), 2021, 6305–6318. doi:10.1109/TCYB.2020.2980618
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
    "long_term_metrics",
    "absence_signal",
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


def _predictions(pred_frames: Any, pred_boxes_xywh: Any
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predictions sorted by frame, checked (lengths, one per frame), and the order that
    sorted them (for values given alongside, such as confidences)."""
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
    return p_frames, p_boxes, order


def _at(p_frames: np.ndarray, values: np.ndarray, frames: np.ndarray
        ) -> tuple[np.ndarray, np.ndarray]:
    """``(found, value)`` of sorted predictions ``p_frames`` at ``frames`` (``found``
    false where a frame has no prediction; its value is then the first prediction's)."""
    pos = np.clip(np.searchsorted(p_frames, frames), 0, max(p_frames.size - 1, 0))
    if not p_frames.size:
        return np.zeros(frames.shape, dtype=bool), np.zeros((frames.size,) + values.shape[1:])
    return p_frames[pos] == frames, values[pos]


def _confidences(p_frames: Any, confidence: Any) -> np.ndarray:
    c = np.asarray(confidence, dtype=float).reshape(-1)
    if c.size != np.asarray(p_frames).size:
        raise InputError(f"{c.size} confidences for {np.asarray(p_frames).size} predictions")
    return c


def long_term_metrics(gt: SingleTrack, pred_frames: Any, pred_boxes_xywh: Any,
                      confidence: Any = None) -> dict[str, Any]:
    """The long-term measures of Lukežič et al. (module docstring) over the annotated
    frames, visible and absent.

    ``confidence`` ``(M,)``: the tracker's confidence per prediction (None: every finite
    box is reported, one threshold). Returns ``f_score``, ``precision``, ``recall`` and
    ``threshold`` (the confidence threshold of the best F; ``None`` without
    confidences), ``n_visible``, ``n_absent`` and ``n_reported`` (boxes reported at that
    threshold).

    >>> gt = SingleTrack([1, 2], [[0, 0, 10, 10], [0, 0, 10, 10]], absent=[3, 4])
    >>> r = long_term_metrics(gt, [1, 2, 3, 4], [[0, 0, 10, 10]] * 4, [0.9, 0.8, 0.1, 0.2])
    >>> r["f_score"], r["precision"], r["recall"], r["threshold"]
    (1.0, 1.0, 1.0, 0.8)
    """
    frames = np.union1d(gt.frames, gt.absent)
    if frames.size == 0:
        raise InputError("ground truth has no annotated frame to score")
    p_frames, p_boxes, order = _predictions(pred_frames, pred_boxes_xywh)
    found, boxes = _at(p_frames, p_boxes, frames)
    found &= np.all(np.isfinite(boxes), axis=1)
    visible = np.isin(frames, gt.frames)
    g = np.zeros((frames.size, 4))
    g[visible] = gt.boxes[np.searchsorted(gt.frames, frames[visible])]
    iou = np.where(found & visible, np.clip(iou_xywh(g, boxes), 0.0, 1.0), 0.0)
    if confidence is None:
        conf = np.where(found, 1.0, -np.inf)
        levels = np.array([1.0])
    else:
        _, conf = _at(p_frames, _confidences(pred_frames, confidence)[order], frames)
        conf = np.where(found & np.isfinite(conf), conf, -np.inf)
        levels = np.unique(conf[np.isfinite(conf)])
    n_vis = int(visible.sum())
    best = {"f_score": 0.0, "precision": None, "recall": 0.0 if n_vis else None,
            "threshold": None, "n_reported": 0}
    if levels.size:
        reported = conf[None, :] >= levels[:, None]  # (L, F)
        n_rep = reported.sum(axis=1)
        total = reported.astype(float) @ iou
        pr = np.divide(total, n_rep, out=np.zeros_like(total), where=n_rep > 0)
        re = total / n_vis if n_vis else np.zeros_like(total)
        f = np.divide(2 * pr * re, pr + re, out=np.zeros_like(total), where=pr + re > 0)
        k = int(np.argmax(f))
        best = {"f_score": float(f[k]), "precision": float(pr[k]) if n_rep[k] else None,
                "recall": float(re[k]) if n_vis else None,
                "threshold": None if confidence is None else float(levels[k]),
                "n_reported": int(n_rep[k])}
    return {**best, "n_visible": n_vis, "n_absent": int(frames.size - n_vis)}


def absence_signal(gt: SingleTrack, pred_frames: Any, confidence: Any,
                   threshold: float = 0.5) -> dict[str, Any]:
    """How well ``confidence < threshold`` flags the frames annotated as absent, over the
    annotated frames (a frame the tracker gave no box or confidence for counts as
    flagged: it reported the target absent): ``precision`` (the share of flagged frames
    where the object is absent), ``recall`` (the share of absent frames flagged), the
    counts ``flagged`` and ``absent`` (``None`` where undefined). 0.5 is even odds for a
    calibrated confidence (the single-object models' ``P(IoU >= 0.5)``).

    >>> gt = SingleTrack([1, 2], [[0, 0, 10, 10], [0, 0, 10, 10]], absent=[3, 4])
    >>> r = absence_signal(gt, [1, 2, 3, 4], [0.9, 0.2, 0.1, 0.7])
    >>> r["precision"], r["recall"]
    (0.5, 0.5)
    """
    from .calibration import lost_signal

    frames = np.union1d(gt.frames, gt.absent)
    p_frames = np.asarray(pred_frames, dtype=np.int64).reshape(-1)
    c = _confidences(p_frames, confidence)
    order = np.argsort(p_frames, kind="stable")
    found, conf = _at(p_frames[order], c[order], frames)
    conf = np.where(found & np.isfinite(conf), conf, -np.inf)  # no box: reported absent
    r = lost_signal(conf, ~np.isin(frames, gt.absent), threshold)
    return {"threshold": r["threshold"], "flagged": r["flagged"], "absent": r["lost"],
            "precision": r["precision"], "recall": r["recall"]}


def single_object_metrics(gt: SingleTrack, pred_frames: Any, pred_boxes_xywh: Any,
                          confidence: Any = None, absence_threshold: float = 0.5
                          ) -> dict[str, Any]:
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
    confidence : array_like, shape (M,), optional
        The tracker's confidence per prediction: adds the long-term measures.
    absence_threshold : float
        The confidence below which a frame counts as reported absent
        (:func:`absence_signal`).

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
        ``n_absent``, ``long_term``
            With frames annotated as absent, or with ``confidence``: their number and
            :func:`long_term_metrics`.
        ``absence``
            With both: :func:`absence_signal` at ``absence_threshold``.

    Raises
    ------
    InputError
        Mismatched lengths, a prediction frame given twice, or empty ground truth.
    """
    g_frames = np.asarray(gt.frames, dtype=np.int64).reshape(-1)
    g_boxes = np.asarray(gt.boxes, dtype=float).reshape(-1, 4)
    if g_frames.size == 0:
        raise InputError("ground truth has no annotated frame to score")
    p_frames, p_boxes, _ = _predictions(pred_frames, pred_boxes_xywh)
    found, matched = _at(p_frames, p_boxes, g_frames)
    found &= np.all(np.isfinite(matched), axis=1)

    ious = np.where(found, np.clip(iou_xywh(g_boxes, matched), 0.0, 1.0), 0.0)
    diff = centre_xywh(matched) - centre_xywh(g_boxes)
    errors = np.where(found, np.hypot(diff[:, 0], diff[:, 1]), np.inf)
    finite = errors[np.isfinite(errors)]

    s_curve = success_curve(ious)
    p_curve = precision_curve(errors)
    extra: dict[str, Any] = {}
    if gt.absent.size or confidence is not None:
        extra["n_absent"] = int(gt.absent.size)
        extra["long_term"] = long_term_metrics(gt, pred_frames, pred_boxes_xywh, confidence)
        if gt.absent.size and confidence is not None:
            extra["absence"] = absence_signal(gt, pred_frames, confidence, absence_threshold)
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
        **extra,
    }
