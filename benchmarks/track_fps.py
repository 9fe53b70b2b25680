"""Colour particle filter: frames per second of inference (decoding excluded).

Frames are decoded into memory first; then each run times only ``engine.step``.
Prints, per sequence and particle count: ms per frame, frames per second, peak
traced memory during tracking, success AUC where ground truth exists, and the ratio
of frames per second to the 30-particle run of the same sequence (the baseline).

    python benchmarks/track_fps.py [--particles 30,90,210,1000] [--frames 200]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, print_table, single_thread, time_engine  # noqa: E402

single_thread()

from pgm.app.runner import init_box_from_gt  # noqa: E402
from pgm.evaluation.single_object import single_object_metrics  # noqa: E402
from pgm.inference import Engine  # noqa: E402
from pgm.io.annotations import load_mot, load_single_gt  # noqa: E402
from pgm.io.video import open_source  # noqa: E402
from pgm.models import colour_pf  # noqa: E402


def sequences(n_frames: int):
    """(name, frames, gt, init box) for FaceOcc1 and PETS09-S2L1 (one person)."""
    face = SHARED_DATA / "FaceOcc1"
    if face.is_dir():
        src = open_source(face)
        gt = load_single_gt(src.gt_path)
        frames = list(src.frames(1, n_frames + 1))
        yield "FaceOcc1", frames, gt, init_box_from_gt(gt, 1)
    pets = SHARED_DATA / "PETS09-S2L1"
    if pets.is_dir():
        src = open_source(pets)
        table = load_mot(src.gt_path, kind="gt")
        ids, boxes, _ = table.at(1)
        x, y, w, h = boxes[0]
        frames = list(src.frames(1, n_frames + 1))
        yield f"PETS09-S2L1 (id {ids[0]})", frames, None, np.array([x + w / 2, y + h / 2, w, h])


def run(frames, init_box, n_particles, seed=0, trace_memory=False):
    """Track ``frames``; return boxes, seconds in ``engine.step`` and peak traced MiB.

    tracemalloc slows Python down several times, so timing runs leave it off and the
    peak memory comes from a separate run with ``trace_memory=True``.
    """
    graph = colour_pf.build_graph(colour_pf.Params(init_box=tuple(init_box)))
    engine = Engine(graph, np.random.default_rng(seed), num_particles=n_particles)
    return time_engine(engine, frames, trace_memory)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    ap.add_argument("--particles", default="30,90,210,1000")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    counts = [int(c) for c in args.particles.split(",")]
    rows = []
    found = False
    for name, frames, gt, init in sequences(args.frames):
        found = True
        base_fps = None
        for n in counts:
            best, aucs = None, []
            for r in range(args.repeats):
                boxes, secs, _ = run(frames, init, n, seed=r)
                best = secs if best is None else min(best, secs)
                if gt is not None:
                    fr = np.array([f for f, _ in frames])
                    aucs.append(single_object_metrics(gt.until(fr[-1]), fr, boxes)["success_auc"])
            peak = run(frames, init, n, trace_memory=True)[2]
            fps = len(frames) / best
            base_fps = base_fps or fps
            auc = f"{np.mean(aucs):.3f}" if aucs else "-"
            rows.append([name, len(frames), n, 1e3 * best / len(frames), fps, peak, auc,
                         f"{fps / base_fps:.2f}"])
    if not found:
        sys.exit(f"no data found under {SHARED_DATA}")
    print_table(["sequence", "frames", "particles", "ms/frame", "frames/s", "peak MiB",
                 "AUC (mean of seeds)", "fps / fps@first"], rows,
                title="colour PF, inference only (decoding excluded), best of repeats")


if __name__ == "__main__":
    main()
