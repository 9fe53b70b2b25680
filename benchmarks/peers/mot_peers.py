"""Tracking-by-detection peers (``trackers`` 2.6.1) on one MOTChallenge sequence's public detections.

Runs INSIDE the peer venv (``bash benchmarks/peers/setup_env.sh``); it does not import
``pgm`` (the toolkit scores the output, see ``benchmarks/_peers.py``)::

    .venv-peers/bin/python benchmarks/peers/mot_peers.py --sequence DIR --out OUTDIR \
        [--last-frame N] [--trackers sort,bytetrack,ocsort]

Protocol (``../shared/bench/README.md``, "Tracking-by-detection peers"):

* detections: every row of ``DIR/det/det.txt`` (``frame,-1,x,y,w,h,score,...``, 1-based
  top-left boxes), fed frame by frame (frames ``1..N``; a frame without detections gets
  an empty set) to each tracker with its **default settings**, except ``frame_rate``;
* frame rate: ``frameRate`` of ``DIR/seqinfo.ini``; without one, a ``frameRate=`` or
  ``<n> fps`` statement in ``DIR/SOURCE.md``; else 25 fps (MOTChallenge's usual rate,
  also what the toolkit's ``open_source`` assumes);
* scores: the ``trackers`` thresholds (activation 0.25 / 0.7, high-confidence 0.6) assume
  confidences in [0, 1], but MOT15's public scores run ~0..140 and MOT16's DPM scores are
  margins around 0 (negative allowed). When *any* score of the sequence lies outside
  [0, 1], *every* score is mapped through the standard logistic ``1 / (1 + exp(-s))``
  (one monotone map per sequence, so the detections keep their order; mapping only the
  out-of-range rows would put a score of 0.9 below one of 1.1 -> 0.75). Sequences whose
  scores are all in [0, 1] are fed unchanged. ``--score-map none`` turns this off. With
  this map, ``trackers``' own TrackEval-parity scorer (MOT15 flag-0 rows given to it as a
  distractor class) reproduces every MOTA / IDF1 / HOTA / ID-switch figure of the bench
  README (to rounding: four values sit on a half, e.g. IDF1 0.4495 printed 0.450); without
  it OC-SORT is far off (PETS09-S2L1: MOTA 0.617, IDF1 0.429 against 0.657, 0.489);
* output: ``OUTDIR/<tracker>.txt`` in MOT format ``frame,id,x,y,w,h,score,-1,-1,-1``
  (1-based frames, top-left ``x,y`` in the same 1-based pixel coordinates as
  ``det.txt``, ``w,h``): the tracker's confirmed output boxes (the associated detection
  boxes, as ``trackers``' own MOT writer does), unconfirmed ones (id -1) left out, ids
  shifted by +1 (``trackers`` counts from 0; MOTChallenge ids are positive);
  ``OUTDIR/timing.json``: ``{tracker: {"frames", "seconds", "fps", ...}}``, the time in
  ``tracker.update`` only; a tracker that raises is reported there with an ``"error"``
  and the others still run.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread per library, as the reference figures

import argparse  # noqa: E402
import configparser  # noqa: E402
import json  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

DEFAULT_FPS = 25.0
TRACKERS = {  # CLI name -> class name in the `trackers` package
    "sort": "SORTTracker",
    "bytetrack": "ByteTrackTracker",
    "ocsort": "OCSORTTracker",
    "botsort": "BoTSORTTracker",
    "cbiou": "CBIoUTracker",
}


def read_seqinfo(seq: Path) -> dict[str, str]:
    """``[Sequence]`` of ``seqinfo.ini`` with lower-cased keys ({} when absent)."""
    ini = seq / "seqinfo.ini"
    if not ini.is_file():
        return {}
    parser = configparser.ConfigParser(interpolation=None)
    parser.read_string(ini.read_text(encoding="utf-8-sig", errors="replace"))
    return {k.lower(): v for k, v in parser["Sequence"].items()} if "Sequence" in parser else {}


def frame_rate(seq: Path, info: dict[str, str]) -> tuple[float, str]:
    """Frame rate and where it came from (seqinfo.ini, SOURCE.md or the default)."""
    if "framerate" in info:
        return float(info["framerate"]), "seqinfo.ini"
    src = seq / "SOURCE.md"
    if src.is_file():
        text = src.read_text(encoding="utf-8", errors="replace")
        m = (re.search(r"frameRate\s*=\s*(\d+(?:\.\d+)?)", text)
             or re.search(r"(\d+(?:\.\d+)?)\s*fps\b", text, flags=re.IGNORECASE))
        if m:
            return float(m.group(1)), "SOURCE.md"
    return DEFAULT_FPS, "default"


def load_detections(path: Path) -> np.ndarray:
    """``det.txt`` as a float array ``(n, >=7)``: frame, id, x, y, w, h, score, ..."""
    rows = [line.replace(" ", "").split(",") for line in
            path.read_text(encoding="utf-8-sig").splitlines() if line.strip()]
    if not rows:
        return np.zeros((0, 7))
    width = max(len(r) for r in rows)
    out = np.full((len(rows), max(width, 7)), np.nan)
    for i, r in enumerate(rows):
        out[i, :len(r)] = [float(v) for v in r]
    out[np.isnan(out[:, 6]), 6] = 1.0
    return out


def map_scores(scores: np.ndarray, how: str) -> tuple[np.ndarray, str]:
    """Scores fed to the trackers and the name of the map applied (see the docstring)."""
    if how == "none" or scores.size == 0 or np.all((scores >= 0) & (scores <= 1)):
        return scores, "none"
    return 1.0 / (1.0 + np.exp(-scores)), "logistic"


def run_tracker(name: str, dets: np.ndarray, scores: np.ndarray, n_frames: int, fps: float,
                out_path: Path) -> dict:
    import supervision as sv
    import trackers

    tracker = getattr(trackers, TRACKERS[name])(frame_rate=fps)
    by_frame = {int(f): np.flatnonzero(dets[:, 0] == f) for f in np.unique(dets[:, 0])}
    lines, secs = [], 0.0
    for frame in range(1, n_frames + 1):
        idx = by_frame.get(frame)
        if idx is None or idx.size == 0:
            det = sv.Detections.empty()
        else:
            x, y, w, h = dets[idx, 2], dets[idx, 3], dets[idx, 4], dets[idx, 5]
            det = sv.Detections(xyxy=np.stack([x, y, x + w, y + h], axis=1),
                                confidence=scores[idx].astype(float),
                                class_id=np.zeros(idx.size, dtype=int))
        t0 = time.perf_counter()
        out = tracker.update(det)
        secs += time.perf_counter() - t0
        if len(out) == 0 or out.tracker_id is None:
            continue
        conf = out.confidence if out.confidence is not None else np.ones(len(out))
        for (x1, y1, x2, y2), tid, c in zip(out.xyxy, out.tracker_id, conf, strict=True):
            if int(tid) < 0:  # not (yet) a confirmed track
                continue
            lines.append(f"{frame},{int(tid) + 1},{x1:.3f},{y1:.3f},{x2 - x1:.3f},{y2 - y1:.3f},"
                         f"{float(c):.4f},-1,-1,-1\n")
    out_path.write_text("".join(lines))
    return {"frames": n_frames, "seconds": secs, "fps": n_frames / secs if secs > 0 else None,
            "rows": len(lines)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sequence", required=True, type=Path, help="MOTChallenge sequence folder")
    ap.add_argument("--out", required=True, type=Path, help="output folder")
    ap.add_argument("--last-frame", type=int, default=None,
                    help="track frames 1..N (default: seqLength, else the last det frame)")
    ap.add_argument("--trackers", default="sort,bytetrack,ocsort",
                    help=f"comma-separated, from {', '.join(TRACKERS)}")
    ap.add_argument("--score-map", choices=("auto", "none"), default="auto",
                    help="auto: logistic on all scores when any lies outside [0, 1]")
    ap.add_argument("--fps", type=float, default=None, help="override the frame rate")
    args = ap.parse_args(argv)

    import cv2

    cv2.setNumThreads(1)
    seq = args.sequence.resolve()
    det_path = seq / "det" / "det.txt"
    if not det_path.is_file():
        print(f"no detections file {det_path}", file=sys.stderr)
        return 2
    names = [n.strip().lower() for n in args.trackers.split(",") if n.strip()]
    unknown = [n for n in names if n not in TRACKERS]
    if unknown:
        print(f"unknown tracker(s) {unknown}; choose from {list(TRACKERS)}", file=sys.stderr)
        return 2
    info = read_seqinfo(seq)
    fps, fps_from = frame_rate(seq, info)
    if args.fps is not None:
        fps, fps_from = float(args.fps), "--fps"
    dets = load_detections(det_path)
    if args.last_frame is not None:
        n_frames = int(args.last_frame)
    elif "seqlength" in info:
        n_frames = int(info["seqlength"])
    else:
        n_frames = int(dets[:, 0].max()) if len(dets) else 0
    dets = dets[dets[:, 0] <= n_frames]
    scores, score_map = map_scores(dets[:, 6], args.score_map)

    args.out.mkdir(parents=True, exist_ok=True)
    timing: dict[str, dict] = {}
    for name in names:
        try:
            timing[name] = run_tracker(name, dets, scores, n_frames, fps,
                                       args.out / f"{name}.txt")
        except Exception as exc:  # report and go on with the other trackers
            traceback.print_exc()
            timing[name] = {"error": f"{type(exc).__name__}: {exc}"}
        timing[name].update(frame_rate=fps, frame_rate_from=fps_from, score_map=score_map)
        (args.out / "timing.json").write_text(json.dumps(timing, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
