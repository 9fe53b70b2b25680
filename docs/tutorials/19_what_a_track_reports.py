"""
Tutorial 19 — What a track reports, and when: recovery, filled gaps and births
==============================================================================

A tracker decides each frame which tracks to report. Report too early and a single
false detection near a lost track brings it back in the wrong place; report too late
and every frame of waiting is a missed box. The multi-target default (``ocsort-colour``)
asks for evidence first and reports what it then knows about the frames it waited:

* ``recover_hits=3`` — a lost track found again is reported after three matches in a
  row (at 30 frames/s; the evidence a new track needs);
* ``fill_gaps=0.5`` — once it is, the frames it was missed or waited (up to half a
  second) are reported too, boxes interpolated between the two it reported, in the world
  the camera sees: both ends are taken through the camera's motion over the gap;
* ``fill_births=True`` — a new track, once confirmed, reports the frames it was
  tentative in.

These rows belong to earlier frames and are written when they are known (in a track
file, after the rows of the frame that decided them; ``Targets.rows(frame)`` gives both).

The tutorial

1. draws a synthetic scene's detections, drops a quarter of them, and pans the camera
   unevenly (the boxes and the truth move with it, the engine is told the motion);
2. tracks them four ways: a lost track reported at once (SORT's rule), reported after
   three matches, then with its gaps filled, then with births' frames too (the default);
3. prints MOTA, IDF1, false positives, misses and the rows written late, and plots one
   object's x-position: the truth, the rows reported live and those filled later.

Run it as a script::

    python docs/tutorials/19_what_a_track_reports.py --out tutorial_out
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
# 1. A scene, a quarter of its detections dropped, and an uneven pan of the camera.
scene = multi_target_scene(seed=1, n_frames=T, occluder=False)
folder = scene.write_mot(out / "scene", rng=0, sigma=2.0, clutter_rate=0.5)
gt = load_mot(folder / "gt" / "gt.txt", kind="gt").until(T)
drawn = scene.detections(0, sigma=2.0, clutter_rate=0.5)  # frame, x, y, w, h, score, id
rng = np.random.default_rng(0)
rows = drawn[rng.random(len(drawn)) >= 0.25]
# the image moves right by pan[t] px at frame t: a still object moves with it
pan = 60.0 * np.sin(2 * np.pi * np.arange(T + 1) / 50.0)
rows[:, 1] += pan[rows[:, 0].astype(int)]
gt = replace(gt, boxes=gt.boxes + np.c_[pan[gt.frames], np.zeros((len(gt.frames), 3))])
print(f"{len(drawn)} detections drawn, {len(rows)} kept; the camera pans by up to "
      f"{np.abs(np.diff(pan)).max():.1f} px a frame")


def frame_of(t: int) -> FrameContext:
    r = rows[rows[:, 0] == t]
    motion = np.array([[1.0, 0.0, pan[t] - pan[t - 1]], [0.0, 1.0, 0.0]]) if t > 1 else None
    return FrameContext(t, detections=Detections(r[:, 1:5], r[:, 5]), camera_motion=motion)


def track(params) -> tuple[dict, MotTable, np.ndarray]:
    """The default's association with ``params``: metrics, the track file's rows, and
    which of them were written after their frame."""
    engine = Engine(ocsort_colour.build_graph(params), 0)
    f_, i_, b_, late = [], [], [], []
    for t in range(1, T + 1):
        f, i, b, _ = readout(engine.graph, engine.step(frame_of(t))).rows(t)
        f_ += f.tolist()
        i_ += i.tolist()
        b_ += b.tolist()
        late += (f < t).tolist()
    table = MotTable(np.asarray(f_, dtype=np.int64), np.asarray(i_, dtype=np.int64),
                     np.asarray(b_, dtype=float).reshape(-1, 4), np.ones(len(f_)))
    return evaluate_mot(gt, table, num_frames=T), table, np.asarray(late, dtype=bool)


# %%
# 2. Four ways to report, on the same detections (no colour models: no images here).
base = replace(ocsort_colour.Params(), appearance=None, fps=scene.fps)
runs = {
    "a found track reported at once": replace(base, recover_hits=1, fill_gaps=0.0,
                                              fill_births=False),
    "after 3 matches in a row": replace(base, fill_gaps=0.0, fill_births=False),
    "... and its gaps filled": replace(base, fill_births=False),
    "... and births' frames (default)": base,
}
lines = [f"{'what is reported':<34} {'MOTA':>6} {'IDF1':>6} {'FP':>5} {'FN':>5} "
         f"{'late rows':>9}"]
for name, params in runs.items():
    m, table, late = track(params)
    lines.append(f"{name:<34} {m['mota']:>6.3f} {m['idf1']:>6.3f} {int(m['fp']):>5d} "
                 f"{int(m['fn']):>5d} {int(late.sum()):>9d}")
print("\n".join(lines))
(out / "what_a_track_reports.txt").write_text("\n".join(lines) + "\n")

# %%
# 3. One object's x-position: the truth, what the default reported live, what it filled.
obj = int(np.bincount(gt.ids).argmax())  # the object seen longest
truth = gt.frames[gt.ids == obj], gt.boxes[gt.ids == obj, 0]
# (table and late: the last run's, the default)
t0 = truth[0][0]
# the track that covers the object's first frame best
at = (table.frames == t0)
dist = [abs(table.boxes[k, 0] - truth[1][0]) for k in np.flatnonzero(at)]
fig, ax = plt.subplots(figsize=(6, 3.5))
ax.plot(*truth, "k-", lw=2, label=f"object {obj}, true x")
if dist:
    tid = table.ids[np.flatnonzero(at)[int(np.argmin(dist))]]
    mine = table.ids == tid
    filled = late[mine]
    ax.plot(table.frames[mine][~filled], table.boxes[mine][~filled, 0], "b.", ms=4,
            label=f"track {tid}, reported live")
    ax.plot(table.frames[mine][filled], table.boxes[mine][filled, 0], "r.", ms=6,
            label="filled later (gaps, births)")
ax.set_xlabel("frame")
ax.set_ylabel("box x (px; the camera pans)")
ax.legend(loc="best", fontsize=7)
fig.tight_layout()
fig.savefig(out / "what_a_track_reports.png", dpi=100)
print(f"{T} frames; wrote {out / 'what_a_track_reports.txt'} and "
      f"{out / 'what_a_track_reports.png'}")
