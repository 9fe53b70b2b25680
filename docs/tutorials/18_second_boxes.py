"""
Tutorial 18 — A detector's second box on a person: births a track explains
=========================================================================

Many detectors give some people a second, weaker box — larger, or on the upper body —
that non-maximum suppression let through because it overlaps the first by less than its
own threshold (on MOT16-11's DPM detections a quarter of the boxes overlap a
higher-scored one by more than 0.2, and nine in ten of those are on no person). A
tracker that starts a track on every unmatched detection, as the classic SORT family
does, turns each recurring second box into a second identity: a false track.

The multi-target default (``ocsort-colour``) treats a track's predicted box as the
explanation of every detection the association could have given it:

* ``birth_iou`` — no track is born on a detection that overlaps a track's predicted box
  by more than the association's own IoU gate (0.3);
* ``explain_tentative="prediction"`` — the same rule on every match of a track not yet
  confirmed, a birth in progress: one born beside a person that drifts onto their
  second box is removed before it gets an identity.

The tutorial

1. draws a synthetic scene's detections and gives three of its six people a second
   box, 1.3 times as tall, raised by 0.5 to 0.8 of its height, scoring lower (IoU 0.28
   to 0.53 with the first: a few are born beside the person, then match boxes on them);
2. tracks them with the default's association (without its colour models, to run on the
   detections alone) three ways: births everywhere
   (``birth_iou=1``, the classic cores), births a track explains refused, and tentative
   tracks too;
3. prints MOTA, IDF1, false positives and identities against the scene's true count,
   and plots how many tracks each reports per frame.

Run it as a script::

    python docs/tutorials/18_second_boxes.py --out tutorial_out
"""

# %%
import argparse
import os
import tempfile
from dataclasses import replace
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pgm.core.frame import FrameContext  # noqa: E402
from pgm.core.readout import readout  # noqa: E402
from pgm.evaluation.mot import evaluate_mot  # noqa: E402
from pgm.inference import Engine  # noqa: E402
from pgm.io.annotations import MotTable, load_mot  # noqa: E402
from pgm.models import ocsort_colour  # noqa: E402
from pgm.observation.detections import Detections  # noqa: E402
from pgm.synthetic.scenes import multi_target_scene  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(),
                                                              "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
T = min(150, args.max_frames or 150)

# %%
# 1. Detections of a synthetic scene, every other person's with a second, weaker box.
scene = multi_target_scene(seed=1, n_frames=T, occluder=False)
folder = scene.write_mot(out / "scene", rng=0, sigma=2.0, clutter_rate=0.5)
gt = load_mot(folder / "gt" / "gt.txt", kind="gt").until(T)
drawn = scene.detections(0, sigma=2.0, clutter_rate=0.5)  # frame, x, y, w, h, score, id
rng = np.random.default_rng(0)
seconds = drawn[(drawn[:, 6] >= 0) & (drawn[:, 6] % 2 == 1)].copy()
# raised by 0.5 to 0.8 of the height, 1.3 times as tall: IoU 0.28 to 0.53 with the first
seconds[:, 2] -= rng.uniform(0.5, 0.8, len(seconds)) * seconds[:, 4]
seconds[:, 4] *= 1.3
seconds[:, 5] = drawn[:, 5].min() + (seconds[:, 5] - 0.5) * rng.uniform(0.3, 0.6,
                                                                        len(seconds))
rows = np.concatenate([drawn, seconds])
rows = rows[np.argsort(rows[:, 0], kind="stable")]
print(f"{len(drawn)} detections drawn, {len(seconds)} second boxes added")


def detections(t: int) -> Detections:
    r = rows[rows[:, 0] == t]
    return Detections(r[:, 1:5], r[:, 5])


def track(params) -> tuple[dict, np.ndarray, int]:
    """The default's association with ``params``: metrics, tracks per frame, identities."""
    engine = Engine(ocsort_colour.build_graph(params), 0)
    out_rows, per_frame = [], []
    for t in range(1, T + 1):
        targets = readout(engine.graph, engine.step(FrameContext(t, detections=detections(t))))
        f, i, b, _ = targets.rows(t)  # this frame's rows, and a gap filled now
        out_rows += [(fr, k, *box) for fr, k, box in zip(f, i, b, strict=True)]
        per_frame.append(len(targets))
    a = np.array(out_rows, dtype=float).reshape(-1, 6)
    table = MotTable(a[:, 0].astype(np.int64), a[:, 1].astype(np.int64), a[:, 2:],
                     np.ones(len(a)))
    return (evaluate_mot(gt, table, num_frames=T), np.array(per_frame),
            len(np.unique(table.ids)))


# %%
# 2. Three ways to start tracks, on the same detections.
base = replace(ocsort_colour.Params(), appearance=None, fps=scene.fps)
runs = {
    "births everywhere (birth_iou=1)": replace(base, birth_iou=1.0, explain_tentative="none"),
    "births a track explains refused": replace(base, explain_tentative="none"),
    "... and tentative tracks (default)": base,
}
true_count = np.array([int(np.sum(gt.frames == t)) for t in range(1, T + 1)])
lines = [f"{'births':<36} {'MOTA':>6} {'IDF1':>6} {'FP':>5} {'identities':>10}"]
fig, ax = plt.subplots(figsize=(6, 3.5))
ax.plot(np.arange(1, T + 1), true_count, "k-", lw=2, label="true count")
for name, params in runs.items():
    m, per_frame, n_ids = track(params)
    lines.append(f"{name:<36} {m['mota']:>6.3f} {m['idf1']:>6.3f} {int(m['fp']):>5d} "
                 f"{n_ids:>10d}")
    ax.plot(np.arange(1, T + 1), per_frame, label=name)
lines.append(f"{'(the scene)':<36} {'':>6} {'':>6} {'':>5} {len(np.unique(gt.ids)):>10d}")
print("\n".join(lines))
(out / "second_boxes.txt").write_text("\n".join(lines) + "\n")

# %%
# 3. Tracks reported per frame against the true count.
ax.set_xlabel("frame")
ax.set_ylabel("tracks reported")
ax.legend(loc="upper left", fontsize=7)
fig.tight_layout()
fig.savefig(out / "second_boxes.png", dpi=100)
print(f"{T} frames; wrote {out / 'second_boxes.txt'} and {out / 'second_boxes.png'}")
