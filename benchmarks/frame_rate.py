"""The same synthetic scene at 30, 15 and 10 frames per second: does a model's behaviour
per second hold?

    python benchmarks/frame_rate.py [--model NAME] [--draws 4] [--frames 150]

The toolkit's multi-target synthetic scene (six people with births, deaths and crossings,
640x480 at 30 frames/s; ``pgm.synthetic.scenes.multi_target_scene``) with ``--draws``
draws of its detections (2 px noise, a miss in ten, one clutter box a frame), each
written as a MOTChallenge folder and then every second and third frame kept
(``pgm.evaluation.perturb``: frames renumbered, ``frameRate`` divided). The model runs as
``pgm track`` runs it (no camera motion: the scene's camera is still) and is scored on
the frames it saw. A model whose settings are stated per second, in box units, would
score about the same at the three rates; the table shows how far each is from that.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine_note, print_table, single_thread  # noqa: E402

single_thread()

KINDS = ("none", "fps/2", "fps/3")


def run(model: str, folder: Path) -> tuple[float, float, float]:
    from pgm.app.runner import track_multi
    from pgm.evaluation.mot import evaluate_mot
    from pgm.io.annotations import load_mot
    from pgm.io.video import open_source
    from pgm.models import get_config
    from pgm.models.config import VideoInfo
    from pgm.observation.detections import PublicDetections

    src = open_source(folder)
    det = PublicDetections(folder / "det" / "det.txt")
    gt = load_mot(folder / "gt" / "gt.txt", kind="gt")
    graph = get_config(model).graph_for({}, VideoInfo(
        *src.size, fps=src.fps, score_range=det.score_range,
        typical_height=float(np.median(det.table.boxes[:, 3]))))
    r = track_multi(src, graph, det, rng=0, write_video=False, progress=False,
                    camera_motion="off")
    m = evaluate_mot(gt.until(len(src)), r.table, num_frames=len(src))
    return float(m["mota"]), float(m["idf1"]), float(m["hota"])


def main(argv: list[str] | None = None) -> int:
    from pgm.evaluation.perturb import perturb_sequence
    from pgm.models import DEFAULT_MULTI_TARGET
    from pgm.synthetic.scenes import multi_target_scene

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--model", default=DEFAULT_MULTI_TARGET)
    ap.add_argument("--draws", type=int, default=4)
    ap.add_argument("--frames", type=int, default=150)
    args = ap.parse_args(argv)
    print(machine_note())
    scores = np.zeros((args.draws, len(KINDS), 3))
    with tempfile.TemporaryDirectory() as tmp:
        scene = multi_target_scene(seed=0, n_frames=args.frames, occluder=False)
        for d in range(args.draws):
            base = scene.write_mot(Path(tmp) / f"draw{d}", rng=d, sigma=2.0, clutter_rate=1.0)
            for k, kind in enumerate(KINDS):
                folder = perturb_sequence(base, Path(tmp) / f"draw{d}-{k}", kind)
                scores[d, k] = run(args.model, folder)
    rows = []
    for k in range(len(KINDS)):
        mean, sd = scores[:, k].mean(axis=0), scores[:, k].std(axis=0, ddof=1)
        rows.append([f"{30 / (k + 1):g} frames/s"] + [
            f"{m:.3f} ± {s / np.sqrt(args.draws):.3f}" for m, s in zip(mean, sd, strict=True)])
    print_table(["rate", "MOTA", "IDF1", "HOTA"], rows,
                title=f"{args.model}: mean over {args.draws} draws ± its standard error")
    return 0


if __name__ == "__main__":
    sys.exit(main())
