"""
Tutorial 16 — your own detector: tracking a video that has no detections
========================================================================

Multi-target models track *detections*. A MOTChallenge folder brings its own
(``det/det.txt``); a video of your own does not, and the detector you trust (YOLO, RT-DETR,
a model of your lab) lives in your code. The toolkit takes it as it is: any function from
a frame to boxes and scores. This tutorial

1. renders a synthetic street (coloured people on a grey, textured background) as a
   MOTChallenge folder and writes a detector of "your own" into a file: a saturation
   threshold, connected components, and the share of saturated pixels in each box as its
   score — a stand-in for your network;
2. tracks from the command line with ``--detector FILE.py:detect`` (a module on your path
   works too: ``--detector my_package.detectors:detect``);
3. does the same from Python with :class:`~pgm.observation.detections.CallableDetector`;
4. compares MOTA and IDF1 with the folder's own (noisy) detections and with background
   subtraction (``--detector mog2``), and the detector's own frames per second.

Your function gets each frame as OpenCV reads it (``H x W x 3`` BGR ``uint8``) and returns
``(boxes, scores)``: top-left ``x, y, w, h`` in pixels ``(M, 4)`` and ``(M,)`` scores on any
scale (the multi-target default reads them by their quantile among the video's scores).
A bad box or an exception in your code stops the run with one line naming the detector
and the frame.

Run it as a script::

    python docs/tutorials/16_your_own_detector.py --out tutorial_out
"""

# %%
import argparse
import importlib.util
import json
import os
import tempfile
import textwrap
import time
from pathlib import Path

from pgm.app.cli import main
from pgm.app.runner import track_multi
from pgm.io.annotations import load_mot
from pgm.io.video import open_source
from pgm.models import DEFAULT_MULTI_TARGET, get_config
from pgm.models.config import VideoInfo
from pgm.observation.detections import CallableDetector
from pgm.synthetic import multi_target_scene

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(), "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
n = max(args.max_frames or 100, 40)

# %%
# 1. The scene, and "your" detector in a file of its own.
seq = multi_target_scene(seed=0, n_frames=n).write_mot(out / "street", rng=0, sigma=3.0,
                                                        clutter_rate=1.0)
detector_file = out / "my_detector.py"
detector_file.write_text(textwrap.dedent('''
    """A detector of one's own: saturated blobs (the synthetic people wear colours, the
    street is grey). Any function frame -> (boxes x, y, w, h; scores) will do."""
    import cv2
    import numpy as np


    def detect(image):
        hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
        mask = (hsv[:, :, 1] > 80).astype(np.uint8)
        mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((9, 5), np.uint8))
        n, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        boxes = stats[1:, :4].astype(float)  # x, y, w, h of each blob (label 0: background)
        area = stats[1:, 4].astype(float)
        keep = (boxes[:, 3] >= 20) & (boxes[:, 2] >= 8)
        score = area / (boxes[:, 2] * boxes[:, 3])  # how much of the box is the blob
        return boxes[keep], score[keep]
    '''))

# %%
# 2. From the command line: the detector is named by file (or module) and function.
runs = {}
for name, detector in (("yours (FILE.py:detect)", f"{detector_file}:detect"),
                       ("the folder's det.txt", "public"), ("background subtraction", "mog2")):
    run = out / "runs" / detector.split(":")[-1].replace(".", "_")
    code = main(["track", str(seq), "--detector", detector, "--out", str(run), "--no-video",
                 "--quiet"])
    assert code == 0, f"pgm track --detector {detector} failed"
    runs[name] = json.loads((run / "metrics.json").read_text())

# %%
# 3. From Python: wrap the function, and time it on its own.
spec = importlib.util.spec_from_file_location("my_detector", detector_file)
my_detector = importlib.util.module_from_spec(spec)  # in your code: import my_detector
spec.loader.exec_module(my_detector)
mine = CallableDetector(my_detector.detect, name="mine")
source = open_source(seq)
t0 = time.perf_counter()
for number, image in source.frames():
    mine(number, image)
det_fps = len(source) / (time.perf_counter() - t0)
mine = CallableDetector(my_detector.detect, name="mine")  # a fresh one for the run
width, height = source.size
graph = get_config(DEFAULT_MULTI_TARGET).graph_for(
    {}, VideoInfo(width=width, height=height, fps=source.fps, score_range=mine.score_range))
result = track_multi(source, graph, mine, rng=0, out_dir=out / "api", write_video=False,
                     progress=False, gt=load_mot(seq / "gt" / "gt.txt", kind="gt"))
assert result.metrics["mota"] == runs["yours (FILE.py:detect)"]["mota"]  # the same run

# %%
# 4. The table.
print(f"{'detections':26s} MOTA   IDF1   HOTA")
for name, m in runs.items():
    print(f"{name:26s} {m['mota']:.3f}  {m['idf1']:.3f}  {m['hota']:.3f}")
print(f"your detector alone: {det_fps:.0f} frames/s on {width}x{height}; "
      f"tracked {result.n_frames} frames")
