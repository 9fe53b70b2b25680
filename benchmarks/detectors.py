"""The multi-target default with each detector, on the shared MOT sequences.

For each sequence (its own frames, its ground truth), the default multi-target model
(``pgm.models.DEFAULT_MULTI_TARGET``) runs on the detections of

* ``public``: the sequence's ``det/det.txt`` (the baseline of the table);
* ``mog2``: OpenCV MOG2 background subtraction (:class:`~pgm.observation.detections.
  MOG2Detector`; a still camera's detector: MOT16-11's camera walks, so it is left out
  there unless ``--all``);
* ``yours``: a detector of one's own through :class:`~pgm.observation.detections.
  CallableDetector` — here MOG2 again, wrapped as a user's function, to measure what the
  wrapping costs (identical tracks, the same frames per second).

Printed per sequence and detector: MOTA, IDF1, HOTA, their differences from ``public``,
the detector's frames per second (its calls alone, decoding excluded) and the tracker's
(inference alone). Memory is not traced (tracemalloc would slow the detector several
times; ``benchmarks/mot_speed.py`` measures the default's).

    python benchmarks/detectors.py [--sequences PETS09-S2L1,TUD-Campus] [--all]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numpy as np  # noqa: E402
from _common import SHARED_DATA, machine_note, print_table, single_thread  # noqa: E402

single_thread()

from pgm.app.runner import track_multi  # noqa: E402
from pgm.io.annotations import load_mot  # noqa: E402
from pgm.io.video import open_source  # noqa: E402
from pgm.models import DEFAULT_MULTI_TARGET, get_config  # noqa: E402
from pgm.models.config import VideoInfo  # noqa: E402
from pgm.observation.detections import (  # noqa: E402
    CallableDetector,
    MOG2Detector,
    PublicDetections,
)

SEQUENCES = ("PETS09-S2L1", "TUD-Campus", "TUD-Stadtmitte", "MOT16-11")
#: sequences filmed by a moving camera: background subtraction has nothing to hold on to
MOVING = {"MOT16-11"}


def detectors(src, everything: bool):
    """``name -> a fresh detector`` for one sequence."""
    out = {"public": lambda: PublicDetections(src.det_path)}
    if everything or src.name not in MOVING:
        out["mog2"] = MOG2Detector

        def yours():
            inner, seen = MOG2Detector(), [0]

            def detect(image):  # a user's function: frame -> boxes, scores
                seen[0] += 1
                d = inner(seen[0], image)
                return d.boxes, d.scores
            detect.score_range = None  # fill fractions, no confidence: as MOG2 says
            return CallableDetector(detect, name="yours (mog2 in a function)")
        out["yours"] = yours
    return out


def run(seq: str, make, gt):
    src = open_source(SHARED_DATA / seq)
    det = make()
    width, height = src.size
    table = getattr(det, "table", None)
    graph = get_config(DEFAULT_MULTI_TARGET).graph_for({}, VideoInfo(
        width=width, height=height, fps=float(src.fps), fps_declared=src.fps_declared,
        typical_height=(float(np.median(table.boxes[:, 3])) if table is not None else None),
        score_range=getattr(det, "score_range", None)))
    return track_multi(src, graph, det, rng=0, gt=gt, write_video=False, progress=False)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sequences", default=",".join(SEQUENCES))
    ap.add_argument("--all", action="store_true", help="MOG2 on moving cameras too")
    args = ap.parse_args()
    rows = []
    for seq in args.sequences.split(","):
        folder = SHARED_DATA / seq
        if not folder.is_dir():
            print(f"{seq}: not in {SHARED_DATA}, skipped")
            continue
        src = open_source(folder)
        gt = load_mot(src.gt_path, kind="gt")
        base = None
        for name, make in detectors(src, args.all).items():
            res = run(seq, make, gt)
            m = res.metrics
            if base is None:
                base = m
            det_fps = res.n_frames / res.detector_seconds if res.detector_seconds else float("nan")
            rows.append([seq, name, m["mota"], m["idf1"], m["hota"],
                         f"{m['mota'] - base['mota']:+.3f}", f"{m['idf1'] - base['idf1']:+.3f}",
                         f"{det_fps:.0f}", f"{res.fps:.0f}"])
    print_table(["sequence", "detector", "MOTA", "IDF1", "HOTA", "ΔMOTA", "ΔIDF1",
                 "detector fps", "tracker fps"], rows,
                title=f"The default ({DEFAULT_MULTI_TARGET}) with each detector; "
                      f"{machine_note()}")


if __name__ == "__main__":
    main()
