"""How the public detections err against the ground truth, per shared MOT sequence.

For the choice of a multi-target measurement model: which reference point of a box
(foot point or centre) and which size variable to measure, and whether their errors
are independent, as a diagonal measurement noise assumes. Each scored ground-truth box
is matched one-to-one to the frame's public detections (IoU >= 0.5; the most
pairs, then the largest total IoU, as ``match_detections`` scores a detector); per
sequence the script prints, in units of the ground-truth box's height ``h``:

* the detections' height range (10 % / 50 % / 90 % quantiles, px) — how far the people
  are spread in depth;
* the robust standard deviation (1.4826 × MAD) of the errors of the foot point's x and
  y, the centre's y and the log-height;
* the Spearman correlation of the foot-y error and of the centre-y error with the
  log-height error. A box that is too tall reaches further down: its foot-y and
  log-height errors move together, and a model that treats them as independent counts
  that one error twice.

A second table asks what a detection's score says, by the decile of its quantile among
the sequence's scores: the share of the detections that overlap a scored ground-truth box
by IoU >= 0.5 (a true positive as the MOT metrics count one), and the share that the
persistence model (:class:`pgm.factors.persistence.PersistenceScoreModel`, its buffer and gate)
labels found again in the next frame — what the score gate of the multi-target default
reads instead of the truth.

The ground truth is read here for diagnosis only; no tracker setting is taken from it.

    python benchmarks/detection_errors.py [--sequences A,B]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, print_table  # noqa: E402
from scipy.stats import spearmanr  # noqa: E402

from pgm.core.boxes import iou_xywh  # noqa: E402
from pgm.io.annotations import load_mot  # noqa: E402
from pgm.io.video import open_source  # noqa: E402
from pgm.observation.detections import make_detector, pair_boxes  # noqa: E402

SEQUENCES = ("PETS09-S2L1", "TUD-Campus", "TUD-Stadtmitte", "MOT16-11", "PETS09-S2L1-video")


def errors(seq_dir: Path) -> dict[str, np.ndarray]:
    """Matched (detection, truth) pairs' errors in units of the truth's height, and the
    heights of all detections (px)."""
    src = open_source(seq_dir)
    gt = load_mot(src.gt_path, kind="gt")
    gt = gt.subset(gt.scored)
    det = make_detector("public", src).table
    out = {k: [] for k in ("foot_x", "foot_y", "centre_y", "log_h")}
    for n in gt.frame_numbers():
        g = gt.boxes[gt.rows(n)]
        d = det.boxes[det.rows(n)]
        if len(g) == 0 or len(d) == 0:
            continue
        iou = iou_xywh(g[:, None, :], d[None, :, :])  # (truths, detections)
        r, c = pair_boxes(iou >= 0.5, iou)  # the most pairs, then the best total IoU
        g, d = g[r], d[c]
        h = g[:, 3]
        out["foot_x"].append((d[:, 0] + d[:, 2] / 2 - g[:, 0] - g[:, 2] / 2) / h)
        out["foot_y"].append((d[:, 1] + d[:, 3] - g[:, 1] - g[:, 3]) / h)
        out["centre_y"].append((d[:, 1] + d[:, 3] / 2 - g[:, 1] - g[:, 3] / 2) / h)
        out["log_h"].append(np.log(d[:, 3] / h))
    res = {k: np.concatenate(v) if v else np.zeros(0) for k, v in out.items()}
    res["heights"] = np.asarray(det.boxes[:, 3], dtype=float)
    return res


def score_deciles(seq_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """Per decile of the detections' score quantile ``(10,)``: the share that overlap a
    scored truth by IoU >= 0.5, and the share the persistence model labels found again
    (the model itself run over every frame, as a tracker runs it)."""
    from pgm.core.boxes import xywh_to_cxcywh
    from pgm.factors.scores import PersistenceScoreModel, mid_ranks

    src = open_source(seq_dir)
    gt = load_mot(src.gt_path, kind="gt")
    gt = gt.subset(gt.scored)
    det = make_detector("public", src).table  # rows sorted by frame
    scores = np.asarray(det.conf, dtype=float)
    true = np.zeros(scores.size, dtype=bool)
    model, labels = PersistenceScoreModel(), []
    for n in range(1, int(det.frames.max()) + 1):
        rows = det.rows(n)
        d, g = det.boxes[rows], gt.boxes[gt.rows(n)]
        if len(d) and len(g):
            true[rows] = iou_xywh(d[:, None, :], g[None, :, :]).max(axis=1) >= 0.5
        model.observe(xywh_to_cxcywh(d), scores[rows])
        labels.append(model.last_labelled[1])
    # the model labels each frame's detections when the next frame comes: all but the
    # last frame's, in row order
    decile = np.minimum((mid_ranks(np.sort(scores), scores) * 10).astype(int), 9)
    found = np.concatenate(labels)
    labelled = decile[:found.size]
    return (np.array([true[decile == k].mean() for k in range(10)]),
            np.array([found[labelled == k].mean() for k in range(10)]))


def robust_sd(v: np.ndarray) -> float:
    return float(1.4826 * np.median(np.abs(v - np.median(v)))) if len(v) else float("nan")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sequences", default=",".join(SEQUENCES),
                    help="comma-separated sequences under ../shared/data")
    args = ap.parse_args()
    rows = []
    for name in args.sequences.split(","):
        d = SHARED_DATA / name
        if not d.is_dir():
            print(f"{name}: not under {SHARED_DATA}, skipped", file=sys.stderr)
            continue
        e = errors(d)
        q = np.quantile(e["heights"], [0.1, 0.5, 0.9]) if len(e["heights"]) else [np.nan] * 3
        rho_foot = spearmanr(e["foot_y"], e["log_h"])[0] if len(e["log_h"]) > 2 else np.nan
        rho_centre = spearmanr(e["centre_y"], e["log_h"])[0] if len(e["log_h"]) > 2 else np.nan
        rows.append([name, len(e["log_h"]), " / ".join(f"{v:.0f}" for v in q),
                     f"{robust_sd(e['foot_x']):.3f}", f"{robust_sd(e['foot_y']):.3f}",
                     f"{robust_sd(e['centre_y']):.3f}", f"{robust_sd(e['log_h']):.3f}",
                     f"{rho_foot:+.2f}", f"{rho_centre:+.2f}"])
    print_table(["sequence", "matched", "det. height 10/50/90 % px", "sd foot x", "sd foot y",
                 "sd centre y", "sd log h", "ρ(foot y, log h)", "ρ(centre y, log h)"], rows,
                title="Public detections against the ground truth (IoU >= 0.5, one-to-one); "
                      "errors in units of the true height, robust sd = 1.4826 MAD")
    rows = []
    for name in args.sequences.split(","):
        if (SHARED_DATA / name).is_dir():
            true, found = score_deciles(SHARED_DATA / name)
            rows.append([name, "on a person"] + [f"{v:.2f}" for v in true])
            rows.append(["", "found again"] + [f"{v:.2f}" for v in found])
    print_table(["sequence", "share"] + [f"{10 * k}-{10 * k + 10} %" for k in range(10)], rows,
                title="By the decile of the score's quantile: the share on a person (IoU >= 0.5 "
                      "with a scored truth) and the share the persistence model labels found "
                      "again in the next frame")


if __name__ == "__main__":
    main()
