"""Tracking-by-detection peers (``trackers`` 2.6.1) on one MOTChallenge sequence's public detections.

Runs INSIDE the peer venv (``bash benchmarks/peers/setup_env.sh``); it does not import
``pgm`` (the toolkit scores the output, see ``benchmarks/_peers.py``)::

    .venv-peers/bin/python benchmarks/peers/mot_peers.py --sequence DIR --out OUTDIR \
        [--last-frame N] [--trackers sort,bytetrack,ocsort | all] [--frames auto|none|PATH]

Trackers (CLI name -> ``trackers`` class; ``all`` = every one of them, all runnable
without downloads, torch or a GPU):

* ``sort`` (``SORTTracker``), ``bytetrack`` (``ByteTrackTracker``), ``ocsort``
  (``OCSORTTracker``), ``cbiou`` (``CBIoUTracker``: ``update(detections)`` only, no CMC):
  detections alone, no frame is passed (the package warns when one is);
* ``botsort`` (``BoTSORTTracker``): default ``enable_cmc=True`` (sparse optical flow,
  ``cmc_downscale=2``), which needs the frame: ``update(detections, frame=BGR image)``;
  without a frame the package silently skips CMC;
* ``mcbyte`` (``McByteTracker``) in its **default** configuration:
  ``enable_mask_manager=False`` (no SAM / Cutie, so no torch and no checkpoint download;
  the clear-match locking and reduced Hungarian assignment still run on IoU alone) and
  ``enable_cmc=True``, so it gets the frame too, in **RGB** order as its ``update``
  documents (the package's own McByte benchmark script converts ``cv2.imread``'s BGR
  with ``COLOR_BGR2RGB``). The mask-conditioned McByte (``enable_mask_manager=True``)
  is not run: it imports torch, ``segment_anything`` and Cutie and downloads their
  checkpoints; the package's ``DummyBoxMaskGenerator`` / ``DummyIdentityMaskPropagator``
  are test doubles (a frozen box-shaped mask per track, no confidence), not a tracker
  worth measuring.

Frames (only for ``botsort`` and ``mcbyte``): ``--frames auto`` (default) reads
``DIR/<imDir>/`` (``imDir`` of ``seqinfo.ini``, else ``img1``; files with ``imExt``,
else any image extension, sorted, frame *n* = the *n*-th file, as the toolkit's
``open_source`` pairs them), else the one video file in ``DIR`` (frame *n* = decoded
frame *n - 1*, e.g. ``PETS09-S2L1-video/vtest.avi``); when neither exists, the trackers
run with ``frame=None`` (CMC off) and ``timing.json`` says ``"images": null``.
``--frames none`` never reads frames (BoT-SORT / McByte without CMC); ``--frames PATH``
names an image folder or a video file. Frames are decoded with ``cv2`` outside the timed
section; a sequence with fewer frames than it tracks is an error for those trackers.

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
  boxes, as ``trackers``' own MOT writer does; for BoT-SORT, C-BIoU and McByte too),
  rows with id -1 (unconfirmed tracks; BoT-SORT / C-BIoU / McByte also return unmatched
  low-score and non-spawning detections with id -1) left out, ids shifted by +1
  (``trackers`` counts from 0; MOTChallenge ids are positive);
  ``OUTDIR/timing.json``: ``{tracker: {"frames", "seconds", "fps", "rows", "images",
  "read_seconds", ...}}``, ``seconds`` the time in ``tracker.update`` only (CMC
  included, it runs inside ``update``; decoding the frames is ``read_seconds``, not
  timed in); a tracker that raises is reported there with an ``"error"`` and the others
  still run.
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
#: CLI name -> (class name in the `trackers` package, the frame its ``update`` takes:
#: None = no frame, "bgr" / "rgb" = the image in that channel order)
TRACKERS: dict[str, tuple[str, str | None]] = {
    "sort": ("SORTTracker", None),
    "bytetrack": ("ByteTrackTracker", None),
    "ocsort": ("OCSORTTracker", None),
    "botsort": ("BoTSORTTracker", "bgr"),  # CMC (enable_cmc=True) reads the frame
    "cbiou": ("CBIoUTracker", None),  # enable_cmc=False; warns when given a frame
    "mcbyte": ("McByteTracker", "rgb"),  # no mask manager (default); CMC reads the frame
}
DEFAULT_TRACKERS = ("sort", "bytetrack", "ocsort")
IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp")
VIDEO_EXTENSIONS = (".avi", ".mp4", ".mkv", ".mov", ".webm", ".mpg", ".mpeg", ".m4v")


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


def find_frames(seq: Path, info: dict[str, str], how: str) -> Path | None:
    """The image folder or video file the frames come from (None: no frames).

    ``how``: ``auto`` (``DIR/<imDir>`` with images, else the one video file in ``DIR``),
    ``none``, or a path to an image folder or a video file."""
    if how == "none":
        return None
    if how != "auto":
        path = Path(how).expanduser().resolve()
        if not path.exists():
            raise FileNotFoundError(f"--frames {how}: no such file or folder")
        return path
    folder = seq / info.get("imdir", "img1")
    if folder.is_dir() and image_files(folder, info):
        return folder
    videos = sorted(p for p in seq.iterdir() if p.is_file()
                    and p.suffix.lower() in VIDEO_EXTENSIONS)
    return videos[0] if len(videos) == 1 else None


def image_files(folder: Path, info: dict[str, str]) -> list[Path]:
    """The folder's images with ``imExt`` (any image extension without one, or when none
    has it), sorted."""
    ext = info.get("imext", "").lower()
    files = [p for p in folder.iterdir() if p.is_file()]
    named = [p for p in files if ext and p.suffix.lower() == ext]
    return sorted(named or [p for p in files if p.suffix.lower() in IMAGE_EXTENSIONS])


def iter_frames(source: Path, info: dict[str, str], n_frames: int):
    """Frames ``1..n_frames`` as BGR ``uint8`` arrays, decoded one at a time with cv2."""
    import cv2

    if source.is_dir():
        files = image_files(source, info)
        if len(files) < n_frames:
            raise ValueError(f"{source} has {len(files)} images, {n_frames} frames tracked")
        for path in files[:n_frames]:
            image = cv2.imread(str(path), cv2.IMREAD_COLOR)
            if image is None:
                raise ValueError(f"cv2 could not read {path}")
            yield image
        return
    cap = cv2.VideoCapture(str(source))
    if not cap.isOpened():
        raise ValueError(f"cv2 could not open the video {source}")
    try:
        for k in range(n_frames):
            ok, image = cap.read()
            if not ok or image is None:
                raise ValueError(f"{source} ends after {k} frames, {n_frames} frames tracked")
            yield image
    finally:
        cap.release()


def map_scores(scores: np.ndarray, how: str) -> tuple[np.ndarray, str]:
    """Scores fed to the trackers and the name of the map applied (see the docstring)."""
    if how == "none" or scores.size == 0 or np.all((scores >= 0) & (scores <= 1)):
        return scores, "none"
    return 1.0 / (1.0 + np.exp(-scores)), "logistic"


def run_tracker(name: str, dets: np.ndarray, scores: np.ndarray, n_frames: int, fps: float,
                out_path: Path, frames: Path | None = None,
                info: dict[str, str] | None = None) -> dict:
    """Run one tracker with its default settings (``frame_rate=fps``) over frames
    ``1..n_frames``; ``frames`` (an image folder or video file) feeds the trackers whose
    ``update`` takes the image (``TRACKERS``), in the channel order it expects."""
    import cv2
    import supervision as sv
    import trackers

    class_name, channels = TRACKERS[name]
    tracker = getattr(trackers, class_name)(frame_rate=fps)
    source = frames if channels is not None else None
    images = iter_frames(source, info or {}, n_frames) if source is not None else None
    by_frame = {int(f): np.flatnonzero(dets[:, 0] == f) for f in np.unique(dets[:, 0])}
    lines, secs, read_secs = [], 0.0, 0.0
    for frame in range(1, n_frames + 1):
        idx = by_frame.get(frame)
        if idx is None or idx.size == 0:
            det = sv.Detections.empty()
        else:
            x, y, w, h = dets[idx, 2], dets[idx, 3], dets[idx, 4], dets[idx, 5]
            det = sv.Detections(xyxy=np.stack([x, y, x + w, y + h], axis=1),
                                confidence=scores[idx].astype(float),
                                class_id=np.zeros(idx.size, dtype=int))
        image = None
        if images is not None:
            t0 = time.perf_counter()
            image = next(images)
            if channels == "rgb":
                image = cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
            read_secs += time.perf_counter() - t0
        t0 = time.perf_counter()
        out = tracker.update(det) if channels is None else tracker.update(det, frame=image)
        secs += time.perf_counter() - t0
        if len(out) == 0 or out.tracker_id is None:
            continue
        conf = out.confidence if out.confidence is not None else np.ones(len(out))
        for (x1, y1, x2, y2), tid, c in zip(out.xyxy, out.tracker_id, conf, strict=True):
            if int(tid) < 0:  # not (yet) a confirmed track, or an unassigned detection
                continue
            lines.append(f"{frame},{int(tid) + 1},{x1:.3f},{y1:.3f},{x2 - x1:.3f},{y2 - y1:.3f},"
                         f"{float(c):.4f},-1,-1,-1\n")
    out_path.write_text("".join(lines))
    result = {"frames": n_frames, "seconds": secs,
              "fps": n_frames / secs if secs > 0 else None, "rows": len(lines)}
    if channels is not None:
        result.update(images=None if source is None else str(source), channels=channels,
                      read_seconds=read_secs,
                      cmc_failed_frames=getattr(getattr(tracker, "cmc", None),
                                                "frames_failed", None))
    return result


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sequence", required=True, type=Path, help="MOTChallenge sequence folder")
    ap.add_argument("--out", required=True, type=Path, help="output folder")
    ap.add_argument("--last-frame", type=int, default=None,
                    help="track frames 1..N (default: seqLength, else the last det frame)")
    ap.add_argument("--trackers", default=",".join(DEFAULT_TRACKERS),
                    help=f"comma-separated, from {', '.join(TRACKERS)}; or 'all'")
    ap.add_argument("--score-map", choices=("auto", "none"), default="auto",
                    help="auto: logistic on all scores when any lies outside [0, 1]")
    ap.add_argument("--fps", type=float, default=None, help="override the frame rate")
    ap.add_argument("--frames", default="auto",
                    help="images for the trackers that take them (botsort, mcbyte): auto "
                         "(DIR/<imDir>, else DIR's video file), none, or a folder / video")
    args = ap.parse_args(argv)

    import cv2

    cv2.setNumThreads(1)
    seq = args.sequence.resolve()
    det_path = seq / "det" / "det.txt"
    if not det_path.is_file():
        print(f"no detections file {det_path}", file=sys.stderr)
        return 2
    names = [n.strip().lower() for n in args.trackers.split(",") if n.strip()]
    if "all" in names:
        names = list(dict.fromkeys([*(n for n in names if n != "all"), *TRACKERS]))
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
    frames = None
    if any(TRACKERS[n][1] is not None for n in names):
        try:
            frames = find_frames(seq, info, args.frames)
        except FileNotFoundError as exc:
            print(exc, file=sys.stderr)
            return 2

    args.out.mkdir(parents=True, exist_ok=True)
    timing: dict[str, dict] = {}
    for name in names:
        try:
            timing[name] = run_tracker(name, dets, scores, n_frames, fps,
                                       args.out / f"{name}.txt", frames=frames, info=info)
        except Exception as exc:  # report and go on with the other trackers
            traceback.print_exc()
            timing[name] = {"error": f"{type(exc).__name__}: {exc}"}
        timing[name].update(frame_rate=fps, frame_rate_from=fps_from, score_map=score_map)
        (args.out / "timing.json").write_text(json.dumps(timing, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
