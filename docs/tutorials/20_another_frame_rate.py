"""
Tutorial 20 — The same scene at another frame rate: constants per second, noise per detection
=============================================================================================

A tracker's per-frame constants were chosen on videos at some frame rate; a drone camera at
10 frames/s, or a dashcam at 7, sees the same people move three or four times as far
between frames. The SORT family reads its constants as at a reference rate
(``reference_fps=30``) and converts them to the video's (``pgm.models.sort_time.
at_frame_rate``, ``τ = 30 / fps`` reference frames per video frame):

* windows of frames — the matches a new track needs, OC-SORT's momentum window — become
  windows of time;
* the Kalman process noise either grows as a random walk in time (``noise_per="second"``:
  a coordinate's variance per frame ``τ`` times, a rate's ``τ³``), or stays one step per
  detection with only its rates put in the video's units (``noise_per="detection"``, the
  default: a rate's variance ``τ²`` times). What that noise models on a detector's boxes is
  their irregularity from one detection to the next, which does not grow with the time
  between them.

The tutorial

1. draws a synthetic scene's detections at 30 frames/s and keeps every third frame (10
   frames/s), each of the three shares of the frames in turn
   (``pgm.evaluation.perturb.keep_frames``);
2. tracks every share with the default and with the noise as a random walk, and prints
   MOTA, IDF1, HOTA (the mean over the shares) and the rates' process variance against
   30 frames/s;
3. plots one object's horizontal speed at 10 frames/s: the truth and the two filters'
   estimates.

Run it as a script::

    python docs/tutorials/20_another_frame_rate.py --out tutorial_out
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
from pgm.evaluation.perturb import keep_frames  # noqa: E402
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
STEP = 3

# %%
# 1. A scene at 30 frames/s, its detections drawn once; every third frame kept, from the
#    first, the second and the third frame on (frames renumbered).
scene = multi_target_scene(seed=0, n_frames=T, occluder=False)
folder = scene.write_mot(out / "scene", rng=0, sigma=2.0, clutter_rate=0.5)
gt_all = np.loadtxt(folder / "gt" / "gt.txt", delimiter=",", ndmin=2)
det_all = np.loadtxt(folder / "det" / "det.txt", delimiter=",", ndmin=2)
fps = scene.fps / STEP
print(f"{T} frames at {scene.fps:g} frames/s; kept every {STEP}rd: {fps:g} frames/s")


def track(params, det_rows: np.ndarray, n: int) -> tuple[MotTable, dict]:
    """The default's association with ``params`` on MOT detection rows: the track file's
    rows and, per track id, its Kalman state means frame by frame."""
    engine = Engine(ocsort_colour.build_graph(params), 0)
    f_, i_, b_, states = [], [], [], {}
    for t in range(1, n + 1):
        r = det_rows[det_rows[:, 0] == t]
        record = engine.step(FrameContext(t, detections=Detections(r[:, 2:6], r[:, 6])))
        f, i, b, _ = readout(engine.graph, record).rows(t)
        f_ += f.tolist()
        i_ += i.tolist()
        b_ += b.tolist()
        for track_, mean in zip(engine.replicas.tracks, engine.replicas.est["box"],
                                strict=True):
            if track_.track_id is not None and track_.matched:
                states.setdefault(track_.track_id, []).append((t, np.array(mean)))
    table = MotTable(np.asarray(f_, dtype=np.int64), np.asarray(i_, dtype=np.int64),
                     np.asarray(b_, dtype=float).reshape(-1, 4), np.ones(len(f_)))
    return table, states


# %%
# 2. Each share tracked with the noise per detection (the default) and as a random walk.
base = replace(ocsort_colour.Params(), appearance=None, fps=fps)  # no images here
runs = {"noise per detection (default)": base,
        "noise as a random walk in time": replace(base, noise_per="second")}
scores = {name: [] for name in runs}
kept = {}
for phase in range(STEP):
    det = keep_frames(det_all, STEP, T, phase)
    gt_rows = keep_frames(gt_all, STEP, T, phase)
    n = int(gt_rows[:, 0].max())
    np.savetxt(out / "gt.txt", gt_rows, delimiter=",", fmt="%g")
    gt = load_mot(out / "gt.txt", kind="gt")
    for name, params in runs.items():
        table, states = track(params, det, n)
        m = evaluate_mot(gt, table, num_frames=n)
        scores[name].append([m["mota"], m["idf1"], m["hota"]])
        if phase == 0:
            kept[name] = (table, states, gt)
reference = np.diag(ocsort_colour.build_graph(replace(base, fps=scene.fps))
                    .factors["transition:box"].Q)
lines = [f"{'at ' + format(fps, 'g') + ' frames/s, the mean over the shares':<40} "
         f"{'MOTA':>6} {'IDF1':>6} {'HOTA':>6} {'rate variance':>14}"]
for name, params in runs.items():
    q = np.diag(ocsort_colour.build_graph(params).factors["transition:box"].Q)
    mota, idf1, hota = np.mean(scores[name], axis=0)
    lines.append(f"{name:<40} {mota:>6.3f} {idf1:>6.3f} {hota:>6.3f} "
                 f"{q[-1] / reference[-1]:>10.0f} x 30/s")
print("\n".join(lines))
(out / "another_frame_rate.txt").write_text("\n".join(lines) + "\n")

# %%
# 3. One object's horizontal speed (px per second) at 10 frames/s on the first share: the
#    truth from its ground-truth boxes, each filter's from the track that starts on it.
table, _, gt = kept["noise per detection (default)"]
obj = int(np.bincount(gt.ids).argmax())  # the object seen longest
mine = gt.ids == obj
t_true, x_true = gt.frames[mine], gt.boxes[mine, 0] + gt.boxes[mine, 2] / 2
fig, ax = plt.subplots(figsize=(6, 3.5))
ax.plot(t_true[1:], np.diff(x_true) * fps, "k-", lw=2, label=f"object {obj}, true")
for (name, (table, states, _)), colour in zip(kept.items(), ("b", "r"), strict=True):
    first = np.flatnonzero(table.frames == t_true[0])
    if not len(first):
        continue
    near = first[np.argmin(np.abs(table.boxes[first, 0] + table.boxes[first, 2] / 2
                                  - x_true[0]))]
    tid = int(table.ids[near])
    if tid not in states:
        continue
    t, m = zip(*states[tid], strict=True)
    labels = ocsort_colour.build_graph(base).variables["box"].labels
    # the state's horizontal rate is per video frame: times the frame rate, per second
    speed = np.asarray(m)[:, labels.index("vcx")] * fps
    ax.plot(t, speed, colour + ".-", ms=3, lw=0.8, label=name)
ax.set_xlabel("frame (10 frames/s)")
ax.set_ylabel("horizontal speed (px/s)")
ax.legend(loc="best", fontsize=7)
fig.tight_layout()
fig.savefig(out / "another_frame_rate.png", dpi=100)
print(f"wrote {out / 'another_frame_rate.txt'} and {out / 'another_frame_rate.png'}")
