"""
Tutorial 17 — Where a run's time goes, and appearance at the resolution it needs
================================================================================

A tracker that follows people on a 1080p video does not need 1080p pixels to tell them
apart: a few thousand samples of a person's colours describe them as well as their
twenty thousand pixels do. The multi-target default reads each detection's colour
histogram from between 1 024 and 4 096 of its pixels (``pgm.core.resolution``: a box is
read on the lattice of every ``2**k``-th pixel, ``k`` the largest level that leaves it 1 024
pixels), all the frame's detections at once, and scores every track against every
detection in one matrix product. The camera's motion is estimated on a frame halved to at
most 640 pixels wide, and the frames are decoded on a thread of their own.

The tutorial

1. writes the synthetic street at three times its size (1920x1440: people 200-270 px
   tall), with noisy detections;
2. shows at which level each of frame 1's detections is read, and from how many pixels;
3. runs the default reading every pixel (``appearance_pixels=0``) and as it does by
   default, and prints the tracks' MOTA / IDF1 and the time of each;
4. prints where one run's time goes: decoding the frames alone, inference (the engine's
   steps and the camera's motion), end to end.

Run it as a script::

    python docs/tutorials/17_where_the_time_goes.py --out tutorial_out
"""

# %%
import argparse
import os
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from pgm.app.runner import track_multi
from pgm.core.resolution import BOX_PIXELS, box_levels
from pgm.io.annotations import load_mot
from pgm.io.video import open_source
from pgm.models import DEFAULT_MULTI_TARGET, get_config
from pgm.models.config import VideoInfo
from pgm.observation.detections import PublicDetections
from pgm.synthetic import multi_target_scene

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(),
                                                              "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
n = max(args.max_frames or 100, 30)
ZOOM = 3

# %%
# 1. The street, three times its size: frames enlarged, boxes scaled with them.
seq = multi_target_scene(seed=0, n_frames=n).write_mot(out / "street", rng=0, sigma=3.0,
                                                        clutter_rate=1.0)
for png in sorted((seq / "img1").glob("*.png")):
    img = cv2.imread(str(png))
    cv2.imwrite(str(png.with_suffix(".jpg")),
                cv2.resize(img, None, fx=ZOOM, fy=ZOOM, interpolation=cv2.INTER_CUBIC))
    png.unlink()
for table in (seq / "det" / "det.txt", seq / "gt" / "gt.txt"):
    rows = np.loadtxt(table, delimiter=",", ndmin=2)
    rows[:, 2:6] *= ZOOM
    np.savetxt(table, rows, delimiter=",", fmt="%.6g")
ini = seq / "seqinfo.ini"
ini.write_text(ini.read_text().replace("imExt=.png", "imExt=.jpg")
               .replace("imWidth=640", f"imWidth={640 * ZOOM}")
               .replace("imHeight=480", f"imHeight={480 * ZOOM}"))
source = open_source(seq)
detections = PublicDetections(seq / "det" / "det.txt")
gt = load_mot(seq / "gt" / "gt.txt", kind="gt")
print(f"the street at {source.size[0]}x{source.size[1]}, {len(source)} frames")

# %%
# 2. Each detection's level: the frame shrunk 2**level times a side for that box.
first = detections(1, None).boxes                   # (x, y, w, h) of frame 1's detections
levels = box_levels(first)                          # boxes (cx, cy, w, h): only w, h matter
print(f"\nframe 1: each box read from between {BOX_PIXELS} and {4 * BOX_PIXELS} of its "
      f"pixels")
print("   box w x h   pixels  level  pixels read")
for (_, _, w, h), k in zip(first, levels, strict=True):
    print(f"  {w:5.0f} x {h:4.0f}  {w * h:7.0f}  {k:5d}  {w * h / 4 ** k:11.0f}")

# %%
# 3. Every pixel, and the default's pixels: the tracks, and the time.
width, height = source.size
graph = get_config(DEFAULT_MULTI_TARGET).graph_for({}, VideoInfo(
    width=width, height=height, fps=source.fps, score_range=detections.score_range))
runs = {}
for label, pixels in (("every pixel", 0.0), (f"{BOX_PIXELS} per box (default)", BOX_PIXELS)):
    graph.factors["association"].appearance_pixels = pixels
    r = track_multi(source, graph, detections, rng=0, gt=gt, out_dir=out / f"run-{int(pixels)}",
                    write_video=False, progress=False)
    runs[label] = r
print(f"\n{'appearance read from':24s}  MOTA   IDF1   inference frames/s  end to end frames/s")
for label, r in runs.items():
    print(f"{label:24s}  {r.metrics['mota']:.3f}  {r.metrics['idf1']:.3f}  "
          f"{r.fps:18.1f}  {r.end_to_end_fps:19.1f}")

# %%
# 4. Where one run's time goes.
t0 = time.perf_counter()
for _ in source.frames():
    pass
decode = time.perf_counter() - t0
r = runs[f"{BOX_PIXELS} per box (default)"]
print(f"\ndecoding {r.n_frames} frames alone (read ahead on a thread): {decode:.2f} s; "
      f"the default's run: inference {r.inference_seconds:.2f} s (camera motion included), "
      f"end to end {r.wall_seconds:.2f} s (first frame read to last row written)")
