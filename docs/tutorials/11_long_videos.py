"""
Tutorial 11 — long videos: a size that does not drift, a context that moves
============================================================================

Three things go wrong for an online-learned tracker over a long video; appearance
factors address each. The first two are options of the single-object tracker, not its
default: on the shared development videos they cost accuracy (``docs/results.md``, "A
long video").

1. **The size drifts.** The correlation filter reads the size from three window scales;
   its response falls off faster when the window grows than when it shrinks, so the
   estimate comes out a little small, the filter learns at that size, and the next frame
   starts from there. :class:`pgm.observation.appearance.scale_filter.ScaleFilterLikelihood`
   (cue ``scale``, DSST's filter over scale) is *trained* to peak at its estimate's
   size, so it has no such bias: ``cf(scales=1)+scale`` lets it decide the size.
2. **The context is the desk.** The filter learns a window three times the object's
   size. When the background there is static and textured, it is the steadiest thing
   the filter sees, and the tracker stays on it while the object moves away. With
   ``cf(context_rate=...)`` each cell of the window learns from the object's motion
   whether it moves with the object (the object, or context carried along) or stays
   (the desk), and the filter is weighted by that probability. A tracker already held
   by the desk does not move; the filter's box cells alone then say where the object
   went.
3. **The camera moves.** "Did this cell stay where it was?" separates the desk from the
   object only while the camera is still. The filter checks the frames for camera
   motion and, once the camera is found moving, drops its context: every cell counts
   again.

Run it as a script::

    python docs/tutorials/11_long_videos.py --out tutorial_out
"""

# %%
import argparse
import os
import tempfile
from pathlib import Path

import cv2
import numpy as np

import pgm
from pgm.core.boxes import cxcywh_to_xywh
from pgm.evaluation.single_object import single_object_metrics
from pgm.inference import Engine
from pgm.io.annotations import SingleTrack
from pgm.models import single_object
from pgm.observation.appearance.correlation import CorrelationFilterLikelihood
from pgm.synthetic.scenes import desk_scene

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(),
                                                              "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
T = args.max_frames or 600


def run(frames, init_box, appearance, seed=0):
    """Track ``frames`` (BGR images) from ``init_box`` (cx, cy, w, h): the boxes and the
    engine (its graph holds the learned factors)."""
    params = single_object.Params(init_box=tuple(init_box), appearance=appearance)
    engine = Engine(single_object.build_graph(params), np.random.default_rng(seed))
    boxes = [engine.step(pgm.FrameContext(k + 1, img)).estimates["object"]
             for k, img in enumerate(frames)]
    return np.array(boxes), engine


# %%
# 1. A constant-size textured object (40 x 48 px) circling over a textured background.
rng = np.random.default_rng(0)
background = cv2.GaussianBlur(rng.normal(0, 1, (240, 320)).astype(np.float32), (0, 0), 6)
background = 120 + 22 * background / background.std()
texture = cv2.GaussianBlur(rng.normal(0, 1, (48, 40)).astype(np.float32), (0, 0), 2)
texture = np.clip(128 + 40 * texture / texture.std(), 0, 255)
frames = []
for t in range(T):
    cx, cy = 160 + 60 * np.sin(2 * np.pi * t / 150), 120 + 30 * np.sin(2 * np.pi * t / 97)
    img = background.copy()
    x0, y0 = int(round(cx - 20)), int(round(cy - 24))
    img[y0:y0 + 48, x0:x0 + 40] = texture
    img = np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)
    frames.append(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))
lines = [f"constant-size object, {T} frames: estimated size / true size (sqrt of the area)",
         f"{'appearance':<22} {'first 10 %':>10} {'last 10 %':>10}"]
for app in ("cf", "cf(scales=1)+scale"):
    boxes, _ = run(frames, (160, 120, 40, 48), app)
    size = np.sqrt(boxes[:, 2] * boxes[:, 3] / (40 * 48))
    tenth = max(1, T // 10)
    lines.append(f"{app:<22} {size[:tenth].mean():>10.3f} {size[-tenth:].mean():>10.3f}")
print("\n".join(lines))
(out / "size.txt").write_text("\n".join(lines) + "\n")

# %%
# 2. A cube turned by hand over a textured desk (``background=1``: the desk's texture as
# strong as the cube's; :func:`pgm.synthetic.scenes.desk_scene`).
n = min(T, 400)
seq = desk_scene(1, n, background=1.0)
gt = SingleTrack(np.arange(1, n + 1), seq.boxes)
x, y, w, h = seq.boxes[0]
lines = [f"desk scene, {n} frames: success AUC"]
engines = {}
CONTEXT = "cf(context_rate=0.05)"
for app in ("cf", CONTEXT):
    boxes, engines[app] = run(seq.frames, (x + w / 2, y + h / 2, w, h), app)
    auc = single_object_metrics(gt, gt.frames, cxcywh_to_xywh(boxes))["success_auc"]
    lines.append(f"{app:<22} success AUC {auc:.3f}")
print("\n".join(lines))
(out / "desk.txt").write_text("\n".join(lines) + "\n")

# %%
# What the filter learned of its window: the probability that each cell moves with the
# object (the box's own cells are the object's by definition), over the last frame.
import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def the_filter(engine):
    return next(f for f in engine.graph.factors.values()
                if isinstance(f, CorrelationFilterLikelihood))


cf = the_filter(engines[CONTEXT])
fig, ax = plt.subplots(1, 2, figsize=(8, 3.2))
ax[0].imshow(cv2.cvtColor(seq.frames[-1], cv2.COLOR_BGR2RGB))
ax[0].set_title(f"frame {n}")
im = ax[1].imshow(cf.context, vmin=0, vmax=1, cmap="viridis")
ax[1].set_title("P(cell moves with the object)")
fig.colorbar(im, ax=ax[1])
for a in ax:
    a.set_axis_off()
fig.tight_layout()
fig.savefig(out / "context.png", dpi=100)

# %%
# 3. The same object on a camera that pans with it: the object stays put in the image
# and the background slides by 3 px a frame. The filter checks each of the first 20
# frames on its own (later, 16 of the last 20 frames must move), finds the camera
# moving and drops the context.
wide = cv2.resize(background, (640, 240))
pan = []
for t in range(min(T, 60)):
    img = wide[:, 3 * t:3 * t + 320].copy()
    img[96:144, 140:180] = texture
    img = np.clip(img + rng.normal(0, 4, img.shape), 0, 255).astype(np.uint8)
    pan.append(cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))
_, engine = run(pan, (160, 120, 40, 48), CONTEXT)
panned = the_filter(engine)
line = (f"panning camera, {len(pan)} frames: context dropped at frame "
        f"{panned.camera_moved_at}" if panned.context is None
        else f"panning camera, {len(pan)} frames: too few to find the camera moving")
print(line)
(out / "camera.txt").write_text(line + "\n")
print(f"wrote {out / 'size.txt'}, {out / 'desk.txt'}, {out / 'context.png'} and "
      f"{out / 'camera.txt'}")
