"""OpenCV single-object trackers (CSRT, KCF, MIL) on one image sequence.

Runs INSIDE the peer venv (``bash benchmarks/peers/setup_env.sh``: CSRT and KCF are in the
``opencv-contrib-python-headless`` build only); it does not import ``pgm``::

    .venv-peers/bin/python benchmarks/peers/sot_peers.py --task TASK.json --out RESULT.json \
        [--trackers csrt,kcf,mil] [--seed 0]

``TASK.json``: ``{"frames": ["/abs/img1.png", ...], "init": [x, y, w, h]}``, the first
frame's box, top-left ``x, y`` and size in pixel coordinates with the origin at the
image's top-left pixel (the toolkit's 0-based coordinates, which are OpenCV's).

``RESULT.json``: ``{tracker: {"boxes": [[x, y, w, h], ...], "ok": [bool, ...], "fps": f,
"failed_frames": k, "frames": T, "seconds": s}}``, one box and ``update``'s flag per
frame; the first is ``init`` as given. Each tracker is initialised on the first frame
with the box rounded to integers (what OpenCV's ``Tracker.init`` takes); when ``update``
reports failure (``ok`` False) the previous box is kept and the frame counted in
``failed_frames``. ``fps`` is frames 2..T
over the time in ``update`` only (decoding and ``init`` excluded), as the toolkit's own
MIL baseline in ``benchmarks/appearance_eval.py``. Images are decoded as 3-channel BGR
(``cv2.IMREAD_COLOR``; greyscale files become three equal channels, as the toolkit's frame
sources deliver them). A tracker that raises gets ``{"error": "..."}`` and the others
still run.

MIL draws its training samples from OpenCV's global RNG, so its result depends on what
ran before it in the process; ``cv2.setRNGSeed(seed)`` is called before each tracker's
``init`` (``--seed``, default 0), which makes every tracker's output reproducible and
independent of the order. CSRT and KCF are deterministic, but very sensitive to the
integer init box: on FaceOcc1 moving CSRT's init by one pixel moves its AUC by up to 0.3.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread per library, as the reference figures

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import traceback  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402

CREATE = {"csrt": "TrackerCSRT_create", "kcf": "TrackerKCF_create", "mil": "TrackerMIL_create"}


def read(path: str):
    image = cv2.imread(path, cv2.IMREAD_COLOR)
    if image is None:
        raise OSError(f"cannot read image {path}")
    return image


def run_tracker(name: str, frames: list[str], init: list[float], seed: int = 0) -> dict:
    cv2.setRNGSeed(int(seed))
    tracker = getattr(cv2, CREATE[name])()
    x, y, w, h = (float(v) for v in init)
    box0 = (int(round(x)), int(round(y)), max(1, int(round(w))), max(1, int(round(h))))
    tracker.init(read(frames[0]), box0)
    boxes = [[x, y, w, h]]
    oks = [True]
    failed, secs = 0, 0.0
    for path in frames[1:]:
        image = read(path)
        t0 = time.perf_counter()
        ok, b = tracker.update(image)
        secs += time.perf_counter() - t0
        oks.append(bool(ok))
        if ok:
            boxes.append([float(v) for v in b])
        else:
            failed += 1
            boxes.append(list(boxes[-1]))
    n = len(frames) - 1
    return {"boxes": boxes, "ok": oks, "fps": n / secs if secs > 0 else None,
            "failed_frames": failed, "frames": len(frames), "seconds": secs}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--task", required=True, type=Path, help="task JSON (frames, init)")
    ap.add_argument("--out", required=True, type=Path, help="result JSON")
    ap.add_argument("--trackers", default="csrt,kcf,mil",
                    help=f"comma-separated, from {', '.join(CREATE)}")
    ap.add_argument("--seed", type=int, default=0, help="cv2.setRNGSeed before each tracker")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    task = json.loads(args.task.read_text())
    frames, init = [str(f) for f in task["frames"]], task["init"]
    if not frames or len(init) != 4:
        print("task needs a non-empty 'frames' list and 'init' = [x, y, w, h]", file=sys.stderr)
        return 2
    names = [n.strip().lower() for n in args.trackers.split(",") if n.strip()]
    unknown = [n for n in names if n not in CREATE]
    if unknown:
        print(f"unknown tracker(s) {unknown}; choose from {list(CREATE)}", file=sys.stderr)
        return 2
    result: dict[str, dict] = {}
    for name in names:
        try:
            result[name] = run_tracker(name, frames, init, args.seed)
        except Exception as exc:  # report and go on with the other trackers
            traceback.print_exc()
            result[name] = {"error": f"{type(exc).__name__}: {exc}"}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
