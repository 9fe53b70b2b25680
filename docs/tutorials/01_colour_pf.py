"""
Tutorial 1 — the colour particle filter as a factor graph
==========================================================

Declare the conventional colour particle filter (Pérez et al. [#perez2002]) as an explicit
graph, draw it, run it on a video with the generic engine, look inside a frame and
score the result. Run it as a script::

    python docs/tutorials/01_colour_pf.py --out tutorial_out
    python docs/tutorials/01_colour_pf.py --source ../shared/data/FaceOcc1 --out faceocc

Without ``--source`` it renders the built-in synthetic scene, so it needs no data.
Without ``--out`` every tutorial writes to ``pgm-tutorials/<its name>`` in the system's
temporary folder (``PGM_TUTORIAL_OUT`` names another parent folder) and prints where.

References
----------
.. [#perez2002] P. Pérez, C. Hue, J. Vermaak and M. Gangnet, "Color-based probabilistic
   tracking", Proc. ECCV 2002, LNCS 2350, 661–675. doi:10.1007/3-540-47969-4_44
"""

# %%
# The model
# ---------
# One variable, the object's box ``X = (cx, cy, w, h)``, and three factors:
#
# * a prior: every particle starts on the initial box, with zero velocity;
# * a second-order transition ``X_t = X_{t-1} + a (X_{t-1} - X_{t-2}) + U_t`` with
#   damping ``a = 0.5`` and position noise only (a colour histogram cannot see scale);
# * a likelihood ``log p(z | X) = -λ (1 - ρ)`` with ``ρ`` the Bhattacharyya coefficient
#   between the box's colour histogram and a template taken in the first frame.

import argparse
import os
import tempfile
from pathlib import Path

import numpy as np

import pgm
from pgm.app.runner import track
from pgm.inference import Engine
from pgm.io.annotations import load_single_gt
from pgm.io.video import open_source
from pgm.models import colour_pf
from pgm.observation.appearance.likelihoods import ColourHistogramLikelihood

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
parser.add_argument("--source", help="a video or sequence folder (default: synthetic scene)")
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(), "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
parser.add_argument("--particles", type=int, default=100)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)

# %%
# A source with ground truth: the synthetic demo scene (a two-colour "person" walking
# behind an occluder) written as an OTB folder, or a real sequence.
if args.source is None:
    from pgm.synthetic import demo_scene

    demo_scene(seed=0, n_frames=args.max_frames or 60).write_otb(out / "scene")
    source = open_source(out / "scene")
else:
    source = open_source(args.source)
gt = load_single_gt(source.gt_path)
x, y, w, h = gt.boxes[0]  # frame 1, top-left corner, 0-based
init_box = (x + w / 2, y + h / 2, w, h)  # the toolkit's (cx, cy, w, h)

# %%
# Declare the graph by hand — this is all a model is.
s = 0.03 * np.sqrt(w * h)
graph = pgm.FactorGraph(
    [pgm.Variable("object", 4, role="part", labels=("cx", "cy", "w", "h"))],
    [pgm.GaussianPrior("object", mean=init_box, cov=0.0),
     pgm.AR2Transition("object", noise_std=[s, s, 0.0, 0.0], damping=0.5),
     ColourHistogramLikelihood("object", lam=20.0, layout="perez")],
    name="colour-pf", meta={"output": "object", "engine": {"num_particles": 100}})

# The ready-made config builds exactly the same graph:
assert graph == colour_pf.build_graph(colour_pf.Params(init_box=init_box))
print(graph)
graph.draw(out / "colour_pf_graph.png")
(out / "colour_pf_graph.dot").write_text(graph.to_dot())

# %%
# Step through a few frames by hand and look inside: the engine derives its schedule
# from the graph, and a hook sees every stage.
engine = Engine(graph, rng=np.random.default_rng(0), num_particles=args.particles)
print(engine.schedule)
ess_log = []
engine.add_hook("weight", lambda eng, stage, frame, rec: ess_log.append(rec.ess["object"]))
for number, image in source.frames(1, 11):
    record = engine.step(pgm.FrameContext(number, image))
cx, cy, bw, bh = record.estimates["object"]
print(f"frame {record.frame}: box centre ({cx:.1f}, {cy:.1f}), ESS per frame "
      f"{np.round(ess_log, 1).tolist()}")

import cv2  # noqa: E402

from pgm.plotting.annotate import annotate  # noqa: E402

belief = record.beliefs["object"]
cv2.imwrite(str(out / "frame_particles.png"),
            annotate(image, boxes=[[cx - bw / 2, cy - bh / 2, bw, bh]],
                     particles={"object": belief.x}, particle_weights={"object": belief.weights},
                     text=f"frame {record.frame}"))

# %%
# Run on the whole sequence with one call: tracks.txt (MOTChallenge rows, written as
# it goes), annotated.mp4 and metrics.json.
result = track(source, graph, rng=np.random.default_rng(0), out_dir=out, gt=gt,
               num_particles=args.particles, max_frames=args.max_frames, progress=False)
m = result.metrics
print(f"{len(result.frames)} frames at {result.fps:.0f} frames/s: success AUC "
      f"{m['success_auc']:.3f}, precision@20px {m['precision_at_20']:.3f}")
print(f"outputs in {out}")
