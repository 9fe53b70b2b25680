"""Multi-target tracking metrics: CLEAR MOT [#bernardin2008], identity [#ristani2016],
HOTA [#luiten2021] and the set distances OSPA [#schuhmacher2008] and OSPA⁽²⁾ [#beard2017].

The set distances (OSPA, OSPA⁽²⁾, cardinality error) are in
:mod:`pgm.evaluation.set_distances`; :func:`evaluate_mot` reports them beside the
library metrics.

CLEAR MOT (MOTA, MOTP, FP, FN, ID switches, fragmentations, MT/ML), Identity (IDF1, IDP,
IDR) and HOTA (HOTA, DetA, AssA, LocA) are **not re-implemented**: they come from the
``motrics`` library (MIT; a Rust core whose only Python dependency is numpy; abi3 wheels
for CPython >= 3.10), whose stated aim and CI check is parity with TrackEval, the
reference implementation of HOTA and the scorer behind the bench peers' figures.
Why this library:

* ``trackeval`` 1.3.0 on PyPI (the TrackEval code) requires ``opencv-python`` — which
  installs over our ``opencv-python-headless`` (both own the ``cv2`` package) — plus
  ``pycocotools``, ``pillow``, ``tabulate`` and ``matplotlib>=3.10.5``; ``sn-trackeval``
  has the same requirements; ``trackers`` (whose TrackEval-parity scorer produced the
  bench figures) pulls ``opencv-python``, ``supervision``, ``rich`` and ``requests``.
  None of them can be a dependency here.
* ``motmetrics`` 1.4.0 (already a dependency) has mature CLEAR and Identity metrics but no
  HOTA in its released version, reports MOTP as a distance ``1 - IoU`` and counts
  "mostly tracked" at >= 80 % where TrackEval uses > 80 %, and its IoU helper calls
  ``np.asfarray``, removed in numpy 2.
* Checked here: on TUD-Campus and TUD-Stadtmitte with py-motmetrics' own test hypotheses,
  every number ``motrics`` gives (HOTA, DetA, AssA, LocA, MOTA, MOTP, IDSW, Frag, MT, ML,
  IDF1) equals TrackEval 1.3.0's metric classes, and MOTA, IDF1, IDP, IDR, FP, FN, IDSW,
  Frag, MT and ML equal py-motmetrics' (``tests/test_mot_metrics.py``).
* Known difference, measured on the peers' outputs (``benchmarks/mot_sequences.py``): on
  SORT's TUD-Stadtmitte result ``motrics`` counts 41 ID switches (MOTA 0.513) where
  TrackEval 1.3.0's CLEAR class and the ``trackers`` scorer count 36 (MOTA 0.505); the
  two first diverge where ``motrics`` does not apply TrackEval's bonus for keeping the
  previous frame's match in the CLEAR assignment. HOTA, IDF1 and OSPA agree. Comparisons
  inside this toolkit score every tracker with the same code, so they stay fair; CLEAR
  figures may differ from TrackEval's by a few switches.

Conventions follow TrackEval: MOTP is the mean IoU of matched pairs (higher is better);
"mostly tracked" means matched in more than 80 % of the object's frames, "mostly lost"
less than 20 %; a fragmentation is a ground-truth track resuming after an unmatched (or
absent) frame; HOTA is averaged over the 19 thresholds ``alpha = 0.05, ..., 0.95``. A
sequence in which either side has no box scores MOTA 0 (TrackEval's early exit).

Protocol of ``bench/README.md`` (:func:`evaluate_mot`): IoU threshold 0.5 for CLEAR and
Identity; ground-truth rows with flag 0 (:attr:`MotTable.ignore`) are ignore regions,
handled as TrackEval's MOT-Challenge preprocessing handles distractors
(:func:`apply_ignore_regions`): in each frame, predictions are matched to **all**
ground-truth boxes (Hungarian, maximising IoU among pairs with IoU >= the threshold); a
prediction matched to a flag-0 box is dropped, then the flag-0 rows are dropped. The
ignore handling is written here because TrackEval does it only inside its file-based
dataset class, keyed on distractor classes (for MOT15 files it drops the flag-0 rows but
keeps the predictions on them, which then count as false positives). The same
preprocessed sets feed every metric, OSPA included. OSPA is on box foot points
(bottom-centre), in pixels. The VB-PHD paper [#feng2015] reports mean OSPA without its
cut-off ``c`` and order ``p``; the defaults here report ``(c, p) = (50, 1)`` and ``(100, 2)``.
Its "OSPAMT" is not implemented; the track-level OSPA⁽²⁾ stands in for it.

References
----------
.. [#bernardin2008] K. Bernardin and R. Stiefelhagen, "Evaluating multiple object tracking
   performance: the CLEAR MOT metrics", EURASIP J. Image and Video Processing 2008, Article
   ID 246309. doi:10.1155/2008/246309
.. [#ristani2016] E. Ristani, F. Solera, R. Zou, R. Cucchiara and C. Tomasi, "Performance
   measures and a data set for multi-target, multi-camera tracking", ECCV 2016 Workshops,
   LNCS 9914, 17–35. doi:10.1007/978-3-319-48881-3_2
.. [#luiten2021] J. Luiten, A. Ošep, P. Dendorfer, P. Torr, A. Geiger, L. Leal-Taixé and
   B. Leibe, "HOTA: A higher order metric for evaluating multi-object tracking", Int. J.
   Computer Vision 129(2), 548–578, 2021. doi:10.1007/s11263-020-01375-2
.. [#schuhmacher2008] D. Schuhmacher, B.-T. Vo and B.-N. Vo, "A consistent metric for
   performance evaluation of multi-object filters", IEEE Trans. Signal Processing 56(8),
   3447–3457, 2008. doi:10.1109/TSP.2008.920469
.. [#beard2017] M. Beard, B.-T. Vo and B.-N. Vo, "OSPA(2): Using the OSPA metric to
   evaluate multi-target tracking performance", Proc. ICCAIS 2017, 86–91.
   doi:10.1109/ICCAIS.2017.8217598
.. [#feng2015] P. Feng, W. Wang, S. M. Naqvi and J. A. Chambers, "Variational Bayesian PHD
   filter with deep learning network updating for multiple human tracking", Proc. Sensor
   Signal Processing for Defence (SSPD), Edinburgh, 2015 (venue inferred; DOI not confirmed).
"""

from __future__ import annotations

import configparser
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from pgm.core.boxes import iou_xywh
from pgm.core.errors import InputError
from pgm.evaluation.set_distances import cardinality_error, ospa2, ospa_components
from pgm.io.annotations import MotTable, load_mot, load_tracks

__all__ = [
    "foot_points",
    "apply_ignore_regions",
    "evaluate_mot",
    "evaluate_mot_files",
    "format_mot_table",
    "round_significant",
]

_EPS = float(np.finfo(float).eps)  # TrackEval's tolerance on the matching threshold


# --------------------------------------------------------------------------- boxes


def foot_points(boxes_xywh: Any) -> np.ndarray:
    """Bottom-centre ``(x + w/2, y + h)`` of top-left boxes, shape ``(..., 2)``."""
    b = np.asarray(boxes_xywh, dtype=float)
    return np.stack([b[..., 0] + b[..., 2] / 2.0, b[..., 1] + b[..., 3]], axis=-1)


def apply_ignore_regions(gt: MotTable, pred: MotTable, iou: float = 0.5
                         ) -> tuple[MotTable, MotTable, int]:
    """MOTChallenge preprocessing: predictions on ignore regions removed, then only the
    scored ground truth kept.

    In each frame that has ignore regions (MOT15: flag-0 rows; MOT16/17: classes 2, 7, 8,
    12) and predictions, predictions are matched to every ground-truth box of the frame
    (whatever its flag or class) by the Hungarian algorithm on IoU, pairs with
    ``IoU < iou`` excluded (TrackEval: scores below ``iou - eps`` set to 0 before the
    assignment, zero-score pairs discarded after it). A prediction matched to an ignore
    region is dropped: it is neither a false nor a true positive. Only the scored rows
    (:attr:`MotTable.scored`: MOT15 flag ≠ 0; MOT16/17 class 1 with ``consider`` = 1) are
    then kept: an unscored row is never a miss, and a prediction on one that is not an
    ignore region (an occluder, a car) stays a false positive.

    Returns
    -------
    (gt, pred, dropped)
        The scored ground truth, the kept predictions and the number of predictions
        dropped.
    """
    keep_pred = np.ones(len(pred), dtype=bool)
    if np.any(gt.ignore) and len(pred):
        for f in np.unique(gt.frames[gt.ignore]):
            gs, ps = gt.rows(int(f)), pred.rows(int(f))
            if ps.stop == ps.start:
                continue
            scores = iou_xywh(gt.boxes[gs][:, None, :], pred.boxes[ps][None, :, :])
            scores[scores < iou - _EPS] = 0.0
            rows, cols = linear_sum_assignment(-scores)
            ok = scores[rows, cols] > _EPS
            rows, cols = rows[ok], cols[ok]
            on_ignore = gt.ignore[gs][rows]
            keep_pred[ps.start + cols[on_ignore]] = False
    gt_out = gt if gt.scored.all() else gt.subset(gt.scored)
    pred_out = pred if keep_pred.all() else pred.subset(keep_pred)
    return gt_out, pred_out, int((~keep_pred).sum())


# --------------------------------------------------------------------------- evaluation


def _check_unique_ids(table: MotTable, what: str) -> None:
    if len(table) == 0:
        return
    pairs = np.stack([table.frames, table.ids], axis=1)
    uniq, counts = np.unique(pairs, axis=0, return_counts=True)
    if np.any(counts > 1):
        f, i = uniq[np.flatnonzero(counts > 1)[0]]
        raise InputError(f"{what}: identity {int(i)} has two boxes in frame {int(f)}")


def _per_frame(table: MotTable, frames: np.ndarray) -> tuple[list[list[int]], list[np.ndarray]]:
    """Frame-aligned ids and contiguous ``xyxy`` boxes, as ``motrics`` takes them."""
    xyxy = np.ascontiguousarray(np.concatenate(
        [table.boxes[:, :2], table.boxes[:, :2] + table.boxes[:, 2:4]], axis=1))
    ids_out, boxes_out = [], []
    for f in frames:
        s = table.rows(int(f))
        ids_out.append(table.ids[s].tolist())
        boxes_out.append(np.ascontiguousarray(xyxy[s]))
    return ids_out, boxes_out


def _tracks_of(table: MotTable, points: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    if len(table) == 0:
        return {}
    order = np.lexsort((table.frames, table.ids))
    ids = table.ids[order]
    uniq, starts = np.unique(ids, return_index=True)
    bounds = list(starts[1:]) + [ids.size]
    return {int(u): (table.frames[order[a:b]], points[order[a:b]])
            for u, a, b in zip(uniq, starts, bounds, strict=True)}


def round_significant(values: Any, digits: int = 4) -> list[float | None]:
    """Values as a JSON-ready list of floats rounded to ``digits`` significant digits.

    Keeps ``metrics.json`` small where it holds a value per frame; a non-finite value
    becomes ``None`` (JSON has no NaN or infinity).

    Parameters
    ----------
    values : array_like
        Numbers (any shape; flattened).
    digits : int
        Significant digits kept (default 4: a relative error of at most ``5e-4``).

    Returns
    -------
    list of float or None
    """
    out: list[float | None] = []
    for v in np.asarray(values, dtype=float).reshape(-1):
        out.append(float(f"{v:.{digits}g}") if math.isfinite(v) else None)
    return out


def _key(c: float, p: float) -> str:
    return f"ospa_{float(c):g}_{float(p):g}".replace(".", "p")


def _library_metrics(gt_ids: list[list[int]], gt_boxes: list[np.ndarray],
                     pred_ids: list[list[int]], pred_boxes: list[np.ndarray],
                     iou: float) -> dict[str, Any]:
    """CLEAR, Identity and HOTA from ``motrics`` (TrackEval parity)."""
    import motrics  # imported here: the set distances above do not need it

    res = motrics.evaluate(motrics.Frames(ids=gt_ids, boxes=gt_boxes),
                           motrics.Frames(ids=pred_ids, boxes=pred_boxes),
                           iou_threshold=float(iou), box_format="xyxy")
    clear, ident, hota = res.clear, res.identity, res.hota
    return {
        "mota": float(clear.mota),
        "motp": float(clear.motp),
        "idf1": float(ident.idf1),
        "idp": float(ident.idp),
        "idr": float(ident.idr),
        "hota": float(hota.hota),
        "deta": float(hota.deta),
        "assa": float(hota.assa),
        "loca": float(hota.loca),
        "id_switches": int(clear.num_switches),
        "fragmentations": int(clear.frag),
        "fp": int(clear.num_false_positives),
        "fn": int(clear.num_misses),
        "tp": int(clear.num_matches),
        "mostly_tracked": int(clear.mt),
        "partially_tracked": int(clear.pt),
        "mostly_lost": int(clear.ml),
    }


def evaluate_mot(gt: MotTable, pred: MotTable, *, iou: float = 0.5,
                 ospa_params: Sequence[tuple[float, float]] = ((50, 1), (100, 2)),
                 ospa2_window: int = 10, ospa2_params: tuple[float, float] = (50, 1),
                 num_frames: int | None = None, per_frame: bool = True) -> dict[str, Any]:
    """Score a multi-target tracking result against MOTChallenge-style ground truth.

    Follows ``bench/README.md`` (see the module docstring): flag-0 ground-truth rows are
    ignore regions (:func:`apply_ignore_regions`), and the preprocessed sets feed every
    metric below. Frames ``1 .. num_frames`` are scored.

    Parameters
    ----------
    gt : MotTable
        Ground truth (``load_mot(..., kind='gt')``), flag-0 rows marked in ``ignore``.
    pred : MotTable
        Tracker output (``load_tracks``); one box per identity and frame.
    iou : float
        IoU threshold of CLEAR, Identity and the ignore-region matching (HOTA sweeps its
        own thresholds 0.05 .. 0.95).
    ospa_params : sequence of (c, p)
        OSPA settings; each gives ``ospa_{c}_{p}`` (and its ``_loc`` / ``_card`` parts),
        the mean over all frames of the OSPA between the foot points (bottom-centre, px)
        of the scored ground truth and the kept predictions, frames where both are empty
        counted as 0.
    ospa2_window : int
        OSPA⁽²⁾ window in frames (default 10), see :func:`ospa2`.
    ospa2_params : (c, p)
        OSPA⁽²⁾ cut-off and order on foot points (default ``(50, 1)``).
    num_frames : int, optional
        Sequence length (``seqLength`` of ``seqinfo.ini``); default: the last frame of
        either table.
    per_frame : bool
        Also return the per-frame series (default ``True``; see ``per_frame`` below).

    Returns
    -------
    dict
        JSON-ready values: floats ``mota, motp, idf1, idp, idr, hota, deta, assa, loca,
        ospa_50_1, ospa_100_2`` (one per ``ospa_params``), ``ospa2``,
        ``mean_abs_cardinality_error``, ``error_rate`` (:func:`error_rate`); integer
        counts ``id_switches, fragmentations, fp, fn, tp, num_gt, num_pred, mostly_tracked,
        partially_tracked, mostly_lost,
        num_gt_ignored`` (flag-0 rows), ``num_pred_ignored`` (predictions dropped on
        them), ``num_frames``; and ``ospa2_window``. With ``per_frame``, also
        ``per_frame``: a dict of JSON-ready lists, one entry per frame ``1 .. num_frames``:
        ``frames``; ``ospa_{c}_{p}`` for each ``ospa_params`` setting and ``ospa2`` (px,
        rounded to 4 significant digits by :func:`round_significant`, so their mean
        matches the scalar of the same name to a relative ``5e-4``); ``gt_cardinality``
        and ``pred_cardinality`` (scored ground-truth boxes and kept predictions per
        frame, exact integers, whose mean absolute difference is
        ``mean_abs_cardinality_error``).

    Raises
    ------
    InputError
        A bad threshold or frame count, a frame beyond ``num_frames``, two boxes of one
        identity in a frame, or nothing to score.
    """
    iou = float(iou)
    if not (0.0 < iou <= 1.0):
        raise InputError(f"IoU threshold must be in (0, 1] (got {iou!r})")
    last = max(int(gt.frames.max(initial=0)), int(pred.frames.max(initial=0)))
    if num_frames is None:
        if last == 0:
            raise InputError("nothing to score: ground truth and prediction are both empty")
        n_frames = last
    else:
        if int(num_frames) != num_frames or num_frames < 1:
            raise InputError(f"num_frames must be an integer >= 1 (got {num_frames!r})")
        n_frames = int(num_frames)
        if last > n_frames:
            raise InputError(f"a box in frame {last}, beyond the sequence's {n_frames} frames")
    frames = np.arange(1, n_frames + 1, dtype=np.int64)

    gt_s, pred_s, dropped = apply_ignore_regions(gt, pred, iou)
    _check_unique_ids(gt_s, "ground truth")
    _check_unique_ids(pred_s, "prediction")

    gt_ids, gt_boxes = _per_frame(gt_s, frames)
    pr_ids, pr_boxes = _per_frame(pred_s, frames)
    out: dict[str, Any] = _library_metrics(gt_ids, gt_boxes, pr_ids, pr_boxes, iou)

    g_feet, p_feet = foot_points(gt_s.boxes), foot_points(pred_s.boxes)
    series: dict[str, Any] = {"frames": frames.tolist()}
    for c, p in ospa_params:
        comps = np.array([ospa_components(g_feet[gt_s.rows(int(f))],
                                          p_feet[pred_s.rows(int(f))], c, p)
                          for f in frames])
        key = _key(c, p)
        out[key] = float(comps[:, 0].mean())
        out[key + "_loc"] = float(comps[:, 1].mean())
        out[key + "_card"] = float(comps[:, 2].mean())
        series[key] = round_significant(comps[:, 0])
    c2, p2 = ospa2_params
    o2 = ospa2(_tracks_of(gt_s, g_feet), _tracks_of(pred_s, p_feet), c2, p2, ospa2_window,
               frames=frames)
    out["ospa2"] = o2.mean
    series["ospa2"] = round_significant(o2.values)
    out["ospa2_window"] = int(ospa2_window)
    n_gt = np.bincount(gt_s.frames, minlength=n_frames + 1)[1:]
    n_pr = np.bincount(pred_s.frames, minlength=n_frames + 1)[1:]
    out["mean_abs_cardinality_error"] = cardinality_error(n_gt, n_pr).mean_abs
    out["error_rate"] = error_rate([gt_s.boxes[gt_s.rows(int(f))] for f in frames],
                                   [pred_s.boxes[pred_s.rows(int(f))] for f in frames], iou)
    out["num_gt"] = len(gt_s)
    out["num_pred"] = len(pred_s)
    out["num_gt_ignored"] = int(np.count_nonzero(~gt.scored))
    out["num_pred_ignored"] = dropped
    out["num_frames"] = n_frames
    if per_frame:
        series["gt_cardinality"] = n_gt.tolist()
        series["pred_cardinality"] = n_pr.tolist()
        out["per_frame"] = series
    return out


def error_rate(gt_boxes: Sequence[np.ndarray], pred_boxes: Sequence[np.ndarray],
               iou: float = 0.5) -> float | None:
    """The error rate of Wang, Yin & Man (2008) over per-frame top-left ``(x, y, w, h)``
    boxes: the fraction of frames holding ground truth in which at least one ground-truth
    target is miss-tracked — left without a predicted box of IoU ≥ ``iou`` in the frame's
    optimal one-to-one assignment. ``None`` when no frame holds ground truth. Identities
    are not used (the paper's definition)."""
    from scipy.optimize import linear_sum_assignment

    from pgm.core.boxes import iou_xywh

    bad = total = 0
    for g, p in zip(gt_boxes, pred_boxes, strict=True):
        if len(g) == 0:
            continue
        total += 1
        if len(p) == 0:
            bad += 1
            continue
        m = iou_xywh(np.asarray(g, float)[:, None, :], np.asarray(p, float)[None, :, :])
        r, c = linear_sum_assignment(-m)
        bad += int(np.count_nonzero(m[r, c] >= iou) < len(g))
    return bad / total if total else None


def _seq_length(gt_path: Path) -> int | None:
    """``seqLength`` of the ``seqinfo.ini`` of a ``<seq>/gt/gt.txt`` file, if any."""
    ini = gt_path.resolve().parent.parent / "seqinfo.ini"
    if not ini.is_file():
        return None
    parser = configparser.ConfigParser()
    try:
        parser.read(ini, encoding="utf-8")
        return int(parser["Sequence"]["seqLength"])
    except (configparser.Error, KeyError, ValueError):
        raise InputError(f"{ini}: no integer [Sequence] seqLength") from None


def evaluate_mot_files(gt_path: str | Path, pred_path: str | Path, *,
                       num_frames: int | None = None, **kwargs: Any) -> dict[str, Any]:
    """:func:`evaluate_mot` on a MOTChallenge ``gt.txt`` and a tracker result file.

    ``num_frames`` defaults to ``seqLength`` of ``seqinfo.ini`` beside the ``gt/`` folder
    when there is one, else to the last frame in either file. Other keyword arguments go
    to :func:`evaluate_mot`.
    """
    gt_path = Path(gt_path)
    gt = load_mot(gt_path, kind="gt")
    pred = load_tracks(pred_path)
    if num_frames is None:
        num_frames = _seq_length(gt_path)
    return evaluate_mot(gt, pred, num_frames=num_frames, **kwargs)


# --------------------------------------------------------------------------- table

_COLUMNS = (("MOTA", "mota", "{:.3f}"), ("IDF1", "idf1", "{:.3f}"), ("HOTA", "hota", "{:.3f}"),
            ("ID switches", "id_switches", "{:d}"), ("OSPA(50,1)", "ospa_50_1", "{:.1f}"),
            ("OSPA(100,2)", "ospa_100_2", "{:.1f}"))


def _cell(value: Any, fmt: str) -> str:
    if value is None:
        return "–"
    try:
        if fmt == "{:d}":
            v = float(value)
            if not math.isfinite(v):
                return "–"
            return fmt.format(int(v)) if v == int(v) else f"{v:.1f}"
        v = float(value)
        return "–" if not math.isfinite(v) else fmt.format(v)
    except (TypeError, ValueError):
        return str(value)


def format_mot_table(results: Mapping[Any, Mapping[str, Any]], label: str = "run") -> str:
    """Markdown table of :func:`evaluate_mot` results, columns as in ``bench/README.md``.

    Keys label the rows: a string gives one column headed ``label`` (default ``run``);
    ``(sequence, tracker)`` tuples give two columns, the sequence written only where it
    changes (as in the README). Columns: MOTA, IDF1, HOTA (3 decimals), ID switches,
    OSPA(50,1), OSPA(100,2) (1 decimal, px); a missing value prints as ``–``, a count that
    is not a whole number (a mean over sequences) with one decimal.
    """
    pairs = bool(results) and all(isinstance(k, tuple) and len(k) == 2 for k in results)
    head = ["sequence", "tracker"] if pairs else [label]
    head += [name for name, _, _ in _COLUMNS]
    lines = ["| " + " | ".join(head) + " |", "| " + " | ".join("---" for _ in head) + " |"]
    previous = None
    for key, res in results.items():
        if pairs:
            seq, tracker = (str(k) for k in key)
            label = ["" if seq == previous else seq, tracker]
            previous = seq
        else:
            label = [str(key)]
        cells = [_cell(res.get(field), fmt) for _, field, fmt in _COLUMNS]
        lines.append("| " + " | ".join(label + cells) + " |")
    return "\n".join(lines)
