"""Detection quality on PETS09-S2L1: MOG2 settings and public detections vs ground truth.

Streams ``PETS09-S2L1-video/vtest.avi`` (768x576) and scores each detection source
against the flag-1 rows of ``gt/gt.txt`` (flag-0 boxes are ignore regions: a detection
on one is neither a hit nor a false positive), frame by frame, with
:func:`pgm.observation.detections.match_detections`:

* ``P/R iou``: precision / recall pooled over the first N frames, one-to-one matching
  at IoU >= 0.3; ``mean R``: the mean over frames of each frame's recall;
* ``P/R foot``: the same with foot points (bottom-centre) within 20 px;
* ``det/fr``: detections per frame; ``merged``: share of detections that are one box
  over a group of two or more people; ``in grp``: share of people inside such a box;
* ``ms/fr``: detector time per frame (decoding excluded, one thread), over all frames run.

MOG2 settings (everything else at the :class:`pgm.observation.detections.MOG2Detector` defaults):
``default``; ``opencv-tb`` OpenCV's background ratio 0.9 and a larger (7x15) closing;
``var25`` var_threshold 25; ``no-close`` no closing; ``tb0.5`` background ratio 0.5.

    python benchmarks/detections.py [--frames 60 200] [--sequence PATH]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, print_table, single_thread  # noqa: E402

single_thread()

from pgm.io.annotations import load_mot  # noqa: E402
from pgm.io.video import open_source  # noqa: E402
from pgm.observation.detections import (  # noqa: E402
    DetectionSource,
    MatchCounts,
    MOG2Detector,
    PublicDetections,
    match_detections,
)

MOG2_SETTINGS: dict[str, dict] = {
    "default": {},
    "opencv-tb": dict(background_ratio=0.9, close_size=(7, 15)),
    "var25": dict(var_threshold=25),
    "no-close": dict(close_size=0),
    "tb0.5": dict(background_ratio=0.5),
}
PUBLIC_THRESHOLDS = (None, 10, 20, 30, 40, 50, 60)


def run(det: DetectionSource, frames, gt) -> tuple[list[MatchCounts], list[MatchCounts], float]:
    """Per-frame IoU and foot-point counts, and the detector's mean ms per frame."""
    per_iou, per_foot, spent = [], [], 0.0
    for k, image in frames():
        t0 = time.perf_counter()
        d = det(k, image)
        spent += time.perf_counter() - t0
        rows = gt.rows(k)
        boxes, scored, ignore = gt.boxes[rows], gt.scored[rows], gt.ignore[rows]
        per_iou.append(match_detections(d, boxes[scored], boxes[ignore], criterion="iou"))
        per_foot.append(match_detections(d, boxes[scored], boxes[ignore], criterion="foot"))
    return per_iou, per_foot, 1000.0 * spent / max(len(per_iou), 1)


def row(source: str, setting: str, n: int, per_iou, per_foot, ms: float) -> list:
    ci = sum(per_iou[:n], MatchCounts())
    cf = sum(per_foot[:n], MatchCounts())
    frame_recall = [c.recall for c in per_iou[:n] if c.n_gt]
    return [source, setting, n, round(ci.precision, 3), round(ci.recall, 3),
            round(float(np.mean(frame_recall)), 3), round(cf.precision, 3),
            round(cf.recall, 3), round(ci.n_det / n, 2),
            f"{100 * ci.merged / max(ci.n_det, 1):.1f}%",
            f"{100 * ci.people_in_merged / max(ci.n_gt, 1):.1f}%", round(ms, 3)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, nargs="+", default=[60, 200],
                    help="prefix lengths N to score (default: 60 200; 795 = all)")
    ap.add_argument("--sequence", type=Path, default=SHARED_DATA / "PETS09-S2L1-video")
    args = ap.parse_args()
    source = open_source(args.sequence)
    gt = load_mot(source.gt_path, kind="gt")
    n_max = min(max(args.frames), len(source))
    lengths = sorted({min(n, n_max) for n in args.frames})

    t0 = time.perf_counter()
    n_decoded = sum(1 for _ in source.frames(1, n_max + 1))
    decode_ms = 1000 * (time.perf_counter() - t0) / max(n_decoded, 1)

    def frames():
        return source.frames(1, n_max + 1)

    header = ["source", "setting", "N", "P iou", "R iou", "mean R", "P foot", "R foot",
              "det/fr", "merged", "in grp", "ms/fr"]
    rows = []
    for setting, kwargs in MOG2_SETTINGS.items():
        per_iou, per_foot, ms = run(MOG2Detector(**kwargs), frames, gt)
        rows += [row("mog2", setting, n, per_iou, per_foot, ms) for n in lengths]
    for th in PUBLIC_THRESHOLDS:
        det = PublicDetections(source.det_path, min_score=th)
        per_iou, per_foot, ms = run(det, frames, gt)
        rows += [row("public", "all" if th is None else f">= {th}", n, per_iou, per_foot, ms)
                 for n in lengths]
    rows.sort(key=lambda r: (r[2], r[0] != "mog2"))
    print_table(header, rows, title=f"{source.name} ({args.sequence.name}), frames 1..N;"
                f" decoding {decode_ms:.1f} ms/frame (not included)")


if __name__ == "__main__":
    main()
