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

``--hog`` adds OpenCV's HOG people detector (:class:`~pgm.observation.hog.
HOGPeopleDetector`), which needs an OpenCV with ``cv2.HOGDescriptor``: the contrib build
of the peers' venv, with the toolkit's pure-Python dependencies added (``.venv-peers/bin/pip
install networkx scikit-learn 'motrics>=0.3,<0.4'``), run as ``PYTHONPATH=. .venv-peers/
bin/python benchmarks/detectors.py --hog``. Its detections are computed once per sequence;
Platt's calibration of the SVM margin (``pgm.observation.hog.PLATT``) is fitted on the
detections matched one to one to a ground-truth person (IoU >= 0.5; ignored regions left
out), held out one sequence at a time (the table: each fold's ``a, b`` and the held-out
sequence's expected calibration error over ten bins), then on all of them (the constants
shipped). The default reads the scores by their quantile among the video's, so its tracks
do not depend on the calibration.

    python benchmarks/detectors.py [--sequences PETS09-S2L1,TUD-Campus] [--all] [--hog]
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


def hog_detections(seq: str) -> tuple[list, float]:
    """HOG's boxes and margins on every frame of ``seq`` (frame, boxes, margins) and the
    detector's seconds."""
    import time

    from pgm.observation.hog import HOGPeopleDetector

    det = HOGPeopleDetector()
    out, secs = [], 0.0
    for number, image in open_source(SHARED_DATA / seq).frames():
        t0 = time.perf_counter()
        boxes, margins = det.margins(image)
        secs += time.perf_counter() - t0
        out.append((number, boxes, margins))
    return out, secs


def hog_labels(frames: list, gt) -> tuple[np.ndarray, np.ndarray]:
    """Each HOG detection's margin and whether it is matched one to one to a scored
    ground-truth person (IoU >= 0.5); detections on ignored regions left out."""
    from scipy.optimize import linear_sum_assignment

    from pgm.core.boxes import iou_xywh

    margins, labels = [], []
    for number, boxes, m in frames:
        if not len(boxes):
            continue
        rows = gt.rows(number)
        truth = gt.boxes[rows][gt.scored[rows]]
        ignore = gt.boxes[rows][gt.ignore[rows]]
        hit = np.zeros(len(boxes), dtype=bool)
        if len(truth):
            iou = iou_xywh(boxes[:, None, :], truth[None, :, :])
            r, c = linear_sum_assignment(-iou)
            hit[r[iou[r, c] >= 0.5]] = True
        on_ignored = (np.zeros(len(boxes), dtype=bool) if not len(ignore) else
                      (iou_xywh(boxes[:, None, :], ignore[None, :, :]) >= 0.5).any(axis=1))
        keep = hit | ~on_ignored
        margins.append(m[keep])
        labels.append(hit[keep])
    return np.concatenate(margins), np.concatenate(labels)


def platt(margins: np.ndarray, labels: np.ndarray) -> dict[str, float]:
    """Platt's ``a, b`` (a logistic regression of the label on the margin)."""
    from sklearn.linear_model import LogisticRegression

    fit = LogisticRegression(C=1e6).fit(margins[:, None], labels.astype(int))
    return {"a": float(fit.coef_[0, 0]), "b": float(fit.intercept_[0])}


def ece(p: np.ndarray, y: np.ndarray, bins: int = 10) -> float:
    """Expected calibration error over ``bins`` equal-width bins of ``p``."""
    k = np.minimum((p * bins).astype(int), bins - 1)
    return float(sum(abs(p[k == b].mean() - y[k == b].mean()) * np.mean(k == b)
                     for b in range(bins) if np.any(k == b)))


def hog_rows(seqs: list[str]) -> list[list]:
    """Calibrate HOG leave one sequence out, then track with it on each sequence."""
    import tempfile

    from pgm.io.annotations import MotWriter
    from pgm.observation.hog import HOGPeopleDetector

    found = {}
    for seq in seqs:
        src = open_source(SHARED_DATA / seq)
        gt = load_mot(src.gt_path, kind="gt")
        frames, secs = hog_detections(seq)
        found[seq] = (frames, secs, gt, *hog_labels(frames, gt))
    cal = []
    for seq in seqs:
        m = np.concatenate([found[s][3] for s in seqs if s != seq])
        y = np.concatenate([found[s][4] for s in seqs if s != seq])
        fold = platt(m, y)
        det = HOGPeopleDetector(platt=fold)
        held = ece(det.probability(found[seq][3]), found[seq][4].astype(float))
        cal.append([seq, f"{fold['a']:.3f}", f"{fold['b']:.3f}", len(found[seq][3]),
                    f"{found[seq][4].mean():.3f}", f"{held:.3f}"])
    every = platt(np.concatenate([found[s][3] for s in seqs]),
                  np.concatenate([found[s][4] for s in seqs]))
    print_table(["held out", "a", "b", "detections", "share matched", "held-out ECE"], cal,
                title=f"HOG's margin calibrated leave one sequence out; on all: "
                      f"a = {every['a']:.3f}, b = {every['b']:.3f}")
    rows = []
    for seq in seqs:
        frames, secs, gt = found[seq][:3]
        det = HOGPeopleDetector(platt=every)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "det.txt"
            with MotWriter(path) as w:
                for number, boxes, m in frames:
                    if len(boxes):
                        w.write_rows(np.full(len(boxes), number), np.full(len(boxes), -1),
                                     boxes, det.probability(m))
            res = run(seq, lambda path=path: PublicDetections(path), gt)
        m = res.metrics
        rows.append([seq, "hog", m["mota"], m["idf1"], m["hota"], "", "",
                     f"{len(frames) / secs:.1f}", f"{res.fps:.0f}"])
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sequences", default=",".join(SEQUENCES))
    ap.add_argument("--all", action="store_true", help="MOG2 on moving cameras too")
    ap.add_argument("--hog", action="store_true",
                    help="OpenCV's HOG people detector too (an OpenCV with HOGDescriptor)")
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
    if args.hog:
        rows += hog_rows([q for q in args.sequences.split(",") if (SHARED_DATA / q).is_dir()])
    print_table(["sequence", "detector", "MOTA", "IDF1", "HOTA", "ΔMOTA", "ΔIDF1",
                 "detector fps", "tracker fps"], rows,
                title=f"The default ({DEFAULT_MULTI_TARGET}) with each detector; "
                      f"{machine_note()}")


if __name__ == "__main__":
    main()
