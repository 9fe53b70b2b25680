"""
Tutorial 7 — a discriminative likelihood, fast motion, and a confidence you can trust
===================================================================================

The default single-object tracker (``pgm.models.single_object``) is one node with one
likelihood factor: a correlation filter learned online
(:class:`~pgm.observation.appearance.correlation.CorrelationFilterLikelihood`). This
tutorial

1. looks inside the factor: its response map over a search window, which every particle
   reads at its own centre and scale;
2. builds the tracker by hand from the factor, a heavy-tailed AR(2) transition and a
   declared confidence, and checks it equals the model config;
3. reads the calibrated confidence per frame: the probability that the box overlaps the
   truth by at least half, and its reliability on this scene;
4. assesses it over several scenes, each weighted equally (what the confidence means on
   a scene drawn at random), as ``pgm report`` draws it for a folder of runs.

Run it as a script::

    python docs/tutorials/07_correlation_filter_confidence.py --out tutorial_out
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

import pgm
from pgm.app.report import write_report
from pgm.app.runner import track
from pgm.core.frame import FrameContext
from pgm.evaluation.calibration import confidence_outcomes, reliability, video_weights
from pgm.io.annotations import load_single_gt
from pgm.io.video import open_source
from pgm.models import single_object
from pgm.observation.appearance.correlation import CorrelationFilterLikelihood
from pgm.synthetic import demo_scene

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(), "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
n = max(args.max_frames or 90, 40)

demo_scene(seed=0, n_frames=n).write_otb(out / "scene")
source = open_source(out / "scene")
gt = load_single_gt(source.gt_path)
frames = list(source.frames())
x, y, w, h = gt.boxes[0]
box = np.array([x + w / 2, y + h / 2, w, h])

# %%
# 1. The factor alone: learn on frame 1, score a grid of candidate centres on frame 10.
cf = CorrelationFilterLikelihood("object")
cf.initialize(FrameContext(frames[0][0], frames[0][1]), box)
shifts = np.arange(-30, 31, 2.0)
grid = np.array([[box[0] + dx, box[1] + dy, w, h] for dy in shifts for dx in shifts])
ll = cf.log_likelihood(grid, FrameContext(frames[9][0], frames[9][1]))
best = grid[np.argmax(ll)]
tx, ty, tw, th = gt.boxes[9] if len(gt.boxes) > 9 else gt.boxes[-1]
print(f"frame 10: best candidate centre ({best[0]:.0f}, {best[1]:.0f}), truth "
      f"({tx + tw / 2:.0f}, {ty + th / 2:.0f}); peak log-likelihood {ll.max():.1f} "
      f"(lam = {cf.lam:g} times the response over the filter's peak on its training frame)")
plt.figure(figsize=(4, 3.5))
plt.imshow(ll.reshape(len(shifts), len(shifts)), extent=[shifts[0], shifts[-1], shifts[-1],
                                                         shifts[0]])
plt.colorbar(label="log-likelihood")
plt.xlabel("dx (px)")
plt.ylabel("dy (px)")
plt.title("correlation-filter likelihood, frame 10")
plt.tight_layout()
plt.savefig(out / "cf_response.png", dpi=80)
plt.close()

# %%
# 2. The tracker by hand: the same graph as the model config.
s = 0.03 * np.sqrt(w * h)
graph = pgm.FactorGraph(
    [pgm.Variable("object", 4, role="part", labels=("cx", "cy", "w", "h"))],
    [pgm.GaussianPrior("object", mean=box),
     pgm.AR2Transition("object", noise_std=[s, s, 0, 0], scale_noise=single_object.SCALE_NOISE,
                       reference_size=box[2:], jump_prob=single_object.JUMP_PROB,
                       jump_scale=10.0),
     CorrelationFilterLikelihood("object", name="cf")],
    name="by-hand", meta={"output": "object",
                          "confidence": {"factor": "cf", **single_object.CONFIDENCE}})
config = single_object.build_graph(single_object.Params(init_box=tuple(box)))
runs = {}
for g in (graph, config):
    runs[g.name] = track(source, g, rng=np.random.default_rng(0), gt=gt, num_particles=100,
                         progress=False, max_frames=args.max_frames)
    print(f"{g.name:14s} success AUC {runs[g.name].metrics['success_auc']:.3f} "
          f"({runs[g.name].fps:.0f} frames/s)")

# %%
# 3. The confidence: per frame, and how well it is calibrated on this scene.
r = runs["single-object"]
cal = r.metrics["confidence"]["calibration"]
print(f"confidence: mean {r.scores.mean():.2f}, min {r.scores.min():.2f} (frame "
      f"{r.frames[np.argmin(r.scores)]}); on the {cal['n']} scored frames the box overlapped "
      f"the truth by half {cal['hit_rate']:.0%} of the time against a mean confidence of "
      f"{cal['mean_confidence']:.0%} (ECE {cal['ece']:.3f})")
ious = dict(zip(r.metrics["frames"], r.metrics["ious"], strict=True))
plt.figure(figsize=(6, 2.5))
plt.plot(r.frames, r.scores, label="confidence")
plt.plot(list(ious), list(ious.values()), label="IoU with the truth")
plt.xlabel("frame")
plt.legend()
plt.tight_layout()
plt.savefig(out / "confidence.png", dpi=80)
plt.close()

# %%
# 4. Over several scenes. A confidence is calibrated with respect to a population: here a
# frame of a scene drawn at random, every scene weighted equally (a long scene must not
# decide alone). Each run writes its folder (``runs/<scene>/<model>/<seed>``, as an
# experiment does); ``pgm report`` draws the same diagram.
cs, hits, scene_of = [], [], []
for seed in (1, 2, 3):
    demo_scene(seed=seed, n_frames=n).write_otb(out / f"scenes/s{seed}")
    src = open_source(out / f"scenes/s{seed}")
    sgt = load_single_gt(src.gt_path)
    bx, by, bw, bh = sgt.boxes[0]
    g = single_object.build_graph(single_object.Params(init_box=(bx + bw / 2, by + bh / 2,
                                                                 bw, bh)))
    res = track(src, g, rng=np.random.default_rng(0), gt=sgt, progress=False,
                max_frames=args.max_frames, out_dir=out / f"runs/s{seed}/single-object/0",
                write_video=False)
    c, hit = confidence_outcomes(res.frames, res.scores, res.metrics["frames"],
                                 res.metrics["ious"])  # at the scored frames
    cs.append(c)
    hits.append(hit)
    scene_of += [seed] * len(c)
pooled = reliability(np.concatenate(cs), np.concatenate(hits),
                     weights=video_weights(scene_of))
print(f"over 3 scenes ({len(scene_of)} frames), scenes weighted equally: hit rate "
      f"{pooled['hit_rate']:.0%}, mean confidence {pooled['mean_confidence']:.0%}, "
      f"ECE {pooled['ece']:.3f}")
print(f"report with the reliability diagram: {write_report(out / 'runs')}")
