"""Single-object accuracy and speed of the appearance cues: the ablation table.

Every row is a model config of the one engine (a one-node graph unless it says
"3 nodes"), run over whole sequences with ``--seeds`` seeds; success AUC (OTB, 21
thresholds) and precision at 20 px over the annotated frames, and inference frames per
second (decoding excluded). OpenCV's MIL tracker runs in the same process on the same
frames as the same-run baseline (CSRT and KCF are in the contrib build only; their
figures are quoted from ``../shared/bench/README.md``).

Sequences:

* ``FaceOcc1`` and ``Crossing`` (``../shared/data``), the two single-object sequences;
  the default configuration (``pgm.models.single_object``) was chosen on them;
* ``PETS persons``, a held-out check: the ``--persons`` longest ground-truth tracks of
  ``PETS09-S2L1`` (768x576, people occluding each other and a lamp post), each run as a
  single-object task from its first to its last annotated frame; the AUC is the mean
  over the tracks.

    python benchmarks/appearance_eval.py [--seeds 5] [--persons 6] [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, print_table, single_thread, time_engine  # noqa: E402

single_thread()

import cv2  # noqa: E402

from pgm.app.runner import init_box_from_gt  # noqa: E402
from pgm.evaluation.single_object import single_object_metrics  # noqa: E402
from pgm.inference import Engine  # noqa: E402
from pgm.io.annotations import SingleTrack, load_mot, load_single_gt  # noqa: E402
from pgm.io.video import open_source  # noqa: E402
from pgm.models import part_graph, single_object  # noqa: E402

DEFAULT = single_object.APPEARANCE
SCALE = single_object.SCALE_NOISE
#: (label, part_graph.Params overrides): the ablation
CONFIGS = [
    ("colour PF (Pérez et al. 2002)", dict(appearance="colour")),
    ("part graph, 3 nodes x 10, colour", dict(n_parts=3, num_particles=10, appearance="colour")),
    ("fragments", dict(appearance="fragments")),
    ("gradient", dict(appearance="gradient")),
    ("GMM-KL", dict(appearance="gmm")),
    ("rings (rotation-invariant)", dict(appearance="rings")),
    ("contrast", dict(appearance="contrast")),
    ("template (NCC)", dict(appearance="template")),
    (f"DEFAULT {DEFAULT}, scale {SCALE}", dict(appearance=DEFAULT, scale_noise=SCALE)),
    ("  - scale (fixed size)", dict(appearance=DEFAULT)),
    ("  - template (contrast, scale)", dict(appearance="contrast", scale_noise=SCALE)),
    ("  - contrast (template, scale)", dict(appearance="template", scale_noise=SCALE)),
    ("  + fragments", dict(appearance=DEFAULT + "+fragments", scale_noise=SCALE)),
    ("  + rings", dict(appearance=DEFAULT + "+rings", scale_noise=SCALE)),
    ("  + gradient", dict(appearance=DEFAULT + "+gradient", scale_noise=SCALE)),
    ("fragments+rings+contrast (fixed size)", dict(appearance="fragments+rings+contrast")),
    ("3 nodes x 10, fragments+contrast", dict(n_parts=3, num_particles=10,
                                              appearance="fragments+contrast")),
]
QUICK = {"colour PF (Pérez et al. 2002)", f"DEFAULT {DEFAULT}, scale {SCALE}", "contrast"}
OPENCV = {"FaceOcc1": "CSRT 0.815 / KCF 0.855", "Crossing": "CSRT 0.771 / KCF 0.100"}


def sequences(n_persons: int):
    """``name -> list of tasks (frames, gt, init)``; decoded once."""
    out = {}
    for name in ("FaceOcc1", "Crossing"):
        if (SHARED_DATA / name).is_dir():
            src = open_source(SHARED_DATA / name)
            gt = load_single_gt(src.gt_path)
            out[name] = [(list(src.frames()), gt, init_box_from_gt(gt, 1))]
    pets = SHARED_DATA / "PETS09-S2L1"
    if n_persons > 0 and pets.is_dir():
        table = load_mot(pets / "gt" / "gt.txt", kind="gt")
        keep = ~table.ignore
        ids, counts = np.unique(table.ids[keep], return_counts=True)
        chosen = ids[np.argsort(-counts, kind="stable")[:n_persons]]
        src = open_source(pets)
        tracks = []
        for pid in chosen:
            sel = keep & (table.ids == pid)
            tracks.append(SingleTrack(table.frames[sel], table.boxes[sel]))
        lo = min(int(t.frames[0]) for t in tracks)
        hi = max(int(t.frames[-1]) for t in tracks)
        frames = {n: img for n, img in src.frames() if lo <= n <= hi}
        out["PETS persons"] = [
            ([(n, frames[n]) for n in range(int(t.frames[0]), int(t.frames[-1]) + 1)], t,
             init_box_from_gt(t, int(t.frames[0]))) for t in tracks]
    return out


def run_config(tasks, overrides, seeds):
    """Mean AUC / precision over seeds (and tasks), median frames per second."""
    aucs, precs, fps = [], [], []
    for seed in range(seeds):
        task_auc, task_prec, n_frames, secs = [], [], 0, 0.0
        for frames, gt, init in tasks:
            kw = {"n_parts": 1, "num_particles": 100} | overrides
            graph = part_graph.build_graph(part_graph.Params(init_box=tuple(init), **kw))
            boxes, s, _ = time_engine(Engine(graph, np.random.default_rng(seed)), frames)
            m = single_object_metrics(gt, np.array([n for n, _ in frames]), boxes)
            task_auc.append(m["success_auc"])
            task_prec.append(m["precision_at_20"])
            n_frames += len(frames)
            secs += s
        aucs.append(np.mean(task_auc))
        precs.append(np.mean(task_prec))
        fps.append(n_frames / secs)
    return np.array(aucs), float(np.mean(precs)), float(np.median(fps))


def run_mil(tasks):
    """OpenCV MIL on the same frames: AUC, precision@20, frames per second."""
    aucs, precs, n_frames, secs = [], [], 0, 0.0
    for frames, gt, init in tasks:
        tracker = cv2.TrackerMIL_create()
        c = init
        box = (int(round(c[0] - c[2] / 2)), int(round(c[1] - c[3] / 2)), int(c[2]), int(c[3]))
        tracker.init(frames[0][1], box)
        out = [list(box)]
        t0 = time.perf_counter()
        for _, img in frames[1:]:
            ok, b = tracker.update(img)
            out.append(list(b) if ok else out[-1])
        secs += time.perf_counter() - t0
        n_frames += len(frames) - 1
        m = single_object_metrics(gt, np.array([n for n, _ in frames]), np.array(out, float))
        aucs.append(m["success_auc"])
        precs.append(m["precision_at_20"])
    return float(np.mean(aucs)), float(np.mean(precs)), n_frames / secs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--persons", type=int, default=6,
                    help="PETS09-S2L1 person tracks for the held-out check (0: none)")
    ap.add_argument("--quick", action="store_true", help="three rows only")
    args = ap.parse_args()
    seqs = sequences(args.persons)
    if not seqs:
        sys.exit(f"no sequences under {SHARED_DATA}")
    for name, tasks in seqs.items():
        mil_auc, mil_prec, mil_fps = run_mil(tasks)
        rows = [["OpenCV MIL (same run)", f"{mil_auc:.3f}", "", "", f"{mil_prec:.3f}",
                 mil_fps, 1.0]]
        for label, overrides in CONFIGS:
            if args.quick and label not in QUICK:
                continue
            auc, prec, fps = run_config(tasks, overrides, args.seeds)
            rows.append([label, f"{auc.mean():.3f}", f"{auc.min():.3f}", f"{auc.max():.3f}",
                         f"{prec:.3f}", fps, fps / mil_fps])
        n = sum(len(t[0]) for t in tasks)
        extra = f"; OpenCV (bench README): {OPENCV[name]}" if name in OPENCV else ""
        print_table(["config (100 particles unless stated)", "AUC", "min", "max", "prec@20",
                     "frames/s", "x MIL fps"], rows,
                    title=f"{name}: {len(tasks)} task(s), {n} frames, {args.seeds} seeds{extra}")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
