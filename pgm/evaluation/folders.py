"""Score a folder of tracker results against a folder of ground truth (``pgm eval
--gt-dir GT --pred-dir PRED``), in MOTChallenge's layout.

Layout
------
* Ground truth ``GT``: one sequence per ``GT/<SEQ>/gt/gt.txt`` (the sequence folders of
  MOTChallenge, as in ``../shared/data``; a ``seqinfo.ini`` beside ``gt/`` gives the
  sequence length) or per ``GT/<SEQ>.txt`` file. Where both exist for one name, the
  folder is used. Folders without ``gt/gt.txt`` (an OTB sequence, say) are passed over.
* Predictions ``PRED``: one ``PRED/<SEQ>.txt`` per sequence (MOTChallenge result rows,
  as ``pgm track`` writes to ``tracks.txt``).

The sequences with a prediction file are scored; a ground-truth sequence with none is
listed under ``missing`` and left out of every row (a user who ran two of five
sequences sees the two, not a COMBINED row dragged down by three it never ran). With
``all_sequences=True`` (``pgm eval --all-sequences``) every ground-truth sequence is
scored and one without a prediction file is **scored as an empty prediction** (every
target missed: MOTA 0, OSPA at its cut-off), as a benchmark server scores a submission
that leaves a sequence out. Prediction files with no ground truth are listed under
``unmatched`` and not scored. A prediction folder that matches no sequence at all is an
error (most likely the wrong folder).

Summary rows
------------
``combined``
    All sequences scored as **one**: their frames laid end to end and identities made
    distinct per sequence, then :func:`pgm.evaluation.mot.evaluate_mot`. Counts (FP, FN,
    ID switches, ...) are the sums over sequences; MOTA, MOTP, IDF1 and HOTA are those of
    the pooled counts, as TrackEval's ``COMBINED_SEQ`` row (HOTA's association scores
    never mix sequences, since identities are distinct); OSPA, the cardinality error and
    the error rate are means over all frames of all sequences. OSPA⁽²⁾ is the
    frame-weighted mean of the per-sequence values (its sliding window must not span two
    sequences).
``mean``
    The unweighted mean over sequences of each per-sequence value (a short sequence
    counts as much as a long one).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pgm.core.errors import InputError, one_line
from pgm.evaluation.mot import _seq_length, evaluate_mot
from pgm.io.annotations import MotTable, load_mot, load_tracks

__all__ = ["gt_sequences", "pred_sequences", "evaluate_mot_folders", "concatenate_tables"]


def _folder(path: str | Path, flag: str) -> Path:
    p = Path(path)
    if not p.exists():
        raise InputError(f"{flag} {p}: no such folder")
    if not p.is_dir():
        raise InputError(f"{flag} {p} is not a folder")
    return p


def gt_sequences(gt_dir: str | Path) -> dict[str, Path]:
    """Ground-truth files of a folder, by sequence name (sorted).

    Parameters
    ----------
    gt_dir : path
        Holding ``<SEQ>/gt/gt.txt`` folders and/or ``<SEQ>.txt`` files.

    Returns
    -------
    dict
        ``name -> path of the ground-truth file``.

    Raises
    ------
    InputError
        ``gt_dir`` missing, not a folder, or holding no ground truth.
    """
    root = _folder(gt_dir, "--gt-dir")
    found: dict[str, Path] = {}
    for p in sorted(root.iterdir()):
        if p.name.startswith("."):
            continue
        if p.is_file() and p.suffix.lower() == ".txt":
            found.setdefault(p.stem, p)
        elif p.is_dir() and (p / "gt" / "gt.txt").is_file():
            found[p.name] = p / "gt" / "gt.txt"
    if not found:
        raise InputError(f"--gt-dir {root} holds no ground truth (<SEQ>/gt/gt.txt folders "
                         f"or <SEQ>.txt files)")
    return dict(sorted(found.items()))


def pred_sequences(pred_dir: str | Path) -> dict[str, Path]:
    """Result files ``<SEQ>.txt`` of a folder, by sequence name (sorted).

    Raises
    ------
    InputError
        ``pred_dir`` missing or not a folder.
    """
    root = _folder(pred_dir, "--pred-dir")
    return {p.stem: p for p in sorted(root.iterdir())
            if p.is_file() and p.suffix.lower() == ".txt" and not p.name.startswith(".")}


def concatenate_tables(tables: list[MotTable], lengths: list[int]) -> MotTable:
    """Tables of consecutive sequences as one: the frames of table ``i`` shifted by the
    lengths of the tables before it, its identities by the identities used before it
    (so no two sequences share one).

    Parameters
    ----------
    tables : list of MotTable
    lengths : list of int
        Frames of each sequence (every frame of table ``i`` is at most ``lengths[i]``).

    Returns
    -------
    MotTable
    """
    cols: dict[str, list[np.ndarray]] = {k: [] for k in ("frames", "ids", "boxes", "conf",
                                                         "ignore", "scored", "classes",
                                                         "visibility")}
    frame0 = 0
    id0 = 0
    for table, n in zip(tables, lengths, strict=True):
        if len(table):
            ids = table.ids - int(table.ids.min())
            cols["frames"].append(table.frames + frame0)
            cols["ids"].append(ids + id0)
            id0 += int(ids.max()) + 1
            for k in ("boxes", "conf", "ignore", "scored", "classes", "visibility"):
                cols[k].append(getattr(table, k))
        frame0 += int(n)
    if not cols["frames"]:
        return MotTable(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 4)),
                        np.zeros(0))
    fmt = "mot16" if any(t.fmt == "mot16" for t in tables) else "mot15"
    return MotTable(**{k: np.concatenate(v) for k, v in cols.items()}, fmt=fmt)


def _scored(name: str, gt: MotTable, pred: MotTable, n_frames: int,
            kwargs: dict[str, Any]) -> dict[str, Any]:
    try:
        return evaluate_mot(gt, pred, num_frames=n_frames, per_frame=False, **kwargs)
    except InputError as exc:
        raise InputError(f"sequence {name}: {one_line(exc)}") from None


def _mean(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Unweighted mean of every numeric value present in all rows (None where any row
    has None)."""
    out: dict[str, Any] = {}
    for key in rows[0]:
        values = [r.get(key) for r in rows]
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            out[key] = float(np.mean(values))
        elif all(v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))
                 for v in values):
            out[key] = None
    return out


def evaluate_mot_folders(gt_dir: str | Path, pred_dir: str | Path, *,
                         all_sequences: bool = False, **kwargs: Any) -> dict[str, Any]:
    """Score every ground-truth sequence of ``gt_dir`` against ``pred_dir/<SEQ>.txt``.

    See the module docstring for the layout, missing predictions and the summary rows.

    Parameters
    ----------
    gt_dir, pred_dir : path
        The two folders.
    all_sequences : bool
        Score every ground-truth sequence, one without a prediction file as an empty
        prediction (False, the default: only those with a prediction file).
    **kwargs
        Passed to :func:`pgm.evaluation.mot.evaluate_mot` (``iou``, ``ospa_params``, ...).

    Returns
    -------
    dict
        JSON-ready: ``sequences`` (name → the scalar metrics of
        :func:`~pgm.evaluation.mot.evaluate_mot`), ``combined`` and ``mean`` (the summary
        rows), ``missing`` (sequences without a prediction file: not scored, or scored
        as empty with ``all_sequences``), ``all_sequences``,
        ``unmatched`` (prediction files without ground truth, not scored) and
        ``combined_method`` (one sentence saying how ``combined`` is computed).

    Raises
    ------
    InputError
        A missing folder, no ground truth, no prediction file for any sequence, or a
        malformed file (named).
    """
    gts = gt_sequences(gt_dir)
    preds = pred_sequences(pred_dir)
    common = [s for s in gts if s in preds]
    if not common:
        listed = ", ".join(list(gts)[:5]) + (", ..." if len(gts) > 5 else "")
        raise InputError(f"--pred-dir {pred_dir} holds no <SEQ>.txt for any ground-truth "
                         f"sequence of --gt-dir {gt_dir} ({listed})")
    empty = MotTable(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 4)),
                     np.zeros(0))
    per_seq: dict[str, dict[str, Any]] = {}
    gt_tables, pred_tables, lengths = [], [], []
    for name, gt_path in gts.items():
        if name not in preds and not all_sequences:
            continue
        gt = load_mot(gt_path, kind="gt")
        pred = load_tracks(preds[name]) if name in preds else empty
        n = _seq_length(gt_path) if gt_path.name == "gt.txt" else None
        if n is None:
            n = max(int(gt.frames.max(initial=0)), int(pred.frames.max(initial=0)))
        if n < 1:
            raise InputError(f"sequence {name}: {gt_path} holds no rows and there is no "
                             f"seqinfo.ini giving its length")
        per_seq[name] = _scored(name, gt, pred, n, kwargs)
        gt_tables.append(gt)
        pred_tables.append(pred)
        lengths.append(per_seq[name]["num_frames"])
    combined = _scored("combined", concatenate_tables(gt_tables, lengths),
                       concatenate_tables(pred_tables, lengths), int(sum(lengths)), kwargs)
    weights = np.asarray(lengths, dtype=float)
    combined["ospa2"] = float(np.dot(weights, [per_seq[s]["ospa2"] for s in per_seq])
                              / weights.sum())
    return {"sequences": per_seq, "combined": combined, "mean": _mean(list(per_seq.values())),
            "missing": [s for s in gts if s not in preds], "all_sequences": bool(all_sequences),
            "unmatched": [s for s in preds if s not in gts],
            "combined_method": "all sequences scored as one (frames end to end, identities "
                               "distinct per sequence): counts summed, MOTA/IDF1/HOTA of the "
                               "pooled counts, OSPA averaged over all frames, OSPA2 "
                               "frame-weighted; mean: unweighted mean over sequences"}
