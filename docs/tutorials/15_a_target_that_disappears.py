"""
Tutorial 15 — a target that disappears: absent frames and the long-term scores
==============================================================================

In long-term footage (drones, surveillance) the target is sometimes not there at all:
fully hidden, or out of view. UAV123's ground truth says so with a row of ``NaN``; the
toolkit reads such a row as **absent** (``SingleTrack.absent``), which is not the same as
"not annotated". A tracker should then say "I do not see it" rather than report a box
somewhere. This tutorial

1. renders a scene in which a person walks behind a tall wall (fully hidden for a stretch)
   and writes its ground truth with ``NaN`` on the frames where nothing of the person shows;
2. runs the default single-object tracker with the lost signal on (``lost_below``: a frame
   whose calibrated confidence is below it is reported absent, no row in ``tracks.txt``);
3. scores it: OTB success over the visible frames, and the long-term measures of Lukežič
   et al. (tracking precision, recall and F-score over the confidence thresholds) and the
   absence signal's precision and recall, which reward saying "absent" when it is;
4. compares a tracker that never says "absent" (its confidence ignored): same OTB score,
   lower long-term precision;
5. plots the confidence against the absent stretch.

Run it as a script::

    python docs/tutorials/15_a_target_that_disappears.py --out tutorial_out
"""

# %%
import argparse
import os
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from pgm.app.runner import track
from pgm.evaluation.single_object import long_term_metrics
from pgm.io.annotations import load_single_gt, write_otb_groundtruth
from pgm.io.video import open_source
from pgm.models import single_object
from pgm.synthetic.scene import ObjectSpec, OccluderSpec, Scene

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(), "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
n = max(args.max_frames or 100, 90)  # the absence needs the scene's whole walk

# %%
# 1. The scene: a 30x80 person walking right at 2.6 px/frame behind a 60 px wide wall that
# is taller than the person (fully hidden while wholly behind it).
person = ObjectSpec(box=(20, 100, 30, 80), colors=((40, 40, 200), (200, 80, 40)),
                    velocity=(2.6, 0.0), name="person")
wall = OccluderSpec(box=(140, 80, 60, 130))
seq = Scene([person], [wall], size=(320, 240), fps=30.0, name="wall").render(
    np.random.default_rng(0), n)
folder = seq.write_otb(out / "scene")
visible = np.array([seq.scene.visibility(0, f) for f in range(1, n + 1)])
boxes = np.array([seq.box(0, f) for f in range(1, n + 1)], dtype=float)
boxes[visible == 0] = np.nan  # UAV123's convention: NaN = absent (fully hidden here)
write_otb_groundtruth(folder / "groundtruth_rect.txt", boxes)
gt = load_single_gt(folder / "groundtruth_rect.txt")
print(f"{len(gt)} frames with a box, {gt.absent.size} annotated absent "
      f"(frames {gt.absent.min()}-{gt.absent.max()})")

# %%
# 2. The default tracker, the lost signal at even odds. Given the frame's size, as ``pgm
# track`` gives it, the default also re-detects while its confidence is low (the region a
# lost object may come back in is the frame).
x, y, w, h = gt.boxes[0]
graph = single_object.build_graph(single_object.Params(init_box=(x + w / 2, y + h / 2, w, h),
                                                       frame_size=seq.scene.size))
source = open_source(folder)
run = track(source, graph, rng=np.random.default_rng(0), gt=gt, progress=False,
            out_dir=out / "run", write_video=False, lost_below=0.5)
m = run.metrics

# %%
# 3. The scores: OTB over the visible frames; long-term over visible and absent ones.
lt, ab = m["long_term"], m["absence"]
print(f"success AUC {m['success_auc']:.3f} over the {m['n_frames']} visible frames")
print(f"long-term: F {lt['f_score']:.3f} (precision {lt['precision']:.3f}, recall "
      f"{lt['recall']:.3f}, at confidence >= {lt['threshold']:.2f})")
print(f"absence signal (confidence < 0.5): precision {ab['precision']}, recall {ab['recall']}"
      f" over {ab['absent']} absent frames")

# %%
# 4. A tracker that never says "absent": the same boxes, every one reported.
always = long_term_metrics(gt, run.frames, run.boxes)
print(f"never absent: F {always['f_score']:.3f} (precision {always['precision']:.3f}, "
      f"recall {always['recall']:.3f}) — its boxes on the absent frames cost precision")

# %%
# 5. The confidence through the absence.
plt.figure(figsize=(6, 2.5))
plt.axvspan(gt.absent.min() - 0.5, gt.absent.max() + 0.5, color="0.85", label="absent")
plt.plot(run.frames, run.scores, label="confidence")
plt.axhline(0.5, color="k", lw=0.8, ls="--")
plt.xlabel("frame")
plt.legend(loc="lower left")
plt.tight_layout()
plt.savefig(out / "confidence_absent.png", dpi=80)
plt.close()
print(f"wrote {out / 'confidence_absent.png'}; tracks in {out / 'run' / 'tracks.txt'} "
      f"({sum(1 for _ in open(out / 'run' / 'tracks.txt'))} frames reported of {len(run.frames)})")
