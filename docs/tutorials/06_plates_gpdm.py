"""
Tutorial 6 — plates: one sub-graph per target, and a learned GPDM as its dynamics
================================================================================

A *plate* is a sub-graph replicated once per tracked target, drawn as a box labelled
``K``. You declare the model of **one** person — here a box variable with a prior, a
transition, a colour likelihood and a detection likelihood — mark it as a plate, and the
engine (:class:`pgm.inference.Engine`) runs ``K`` replicas of it, all
stepped together in one batched pass, adding a replica when a detection starts a track
and removing it when the track ends. A factor *between* replicas (mutual exclusion)
stops two of them from settling on one person.

Then the same plate with Wang et al.'s (2008) dynamics: a Gaussian-process dynamical model (GPDM)
learned from trajectories (``pgm learn gpdm``) drives each person's latent chain, and
is compared with constant velocity averaged over three frames, also across frames
withheld from the tracker. Run it as a script::

    python docs/tutorials/06_plates_gpdm.py --out tutorial_out
"""

# %%
# A synthetic scene with births, deaths and crossings, and its noisy detections.
import argparse
import os
import tempfile
from pathlib import Path

import numpy as np

import pgm
from pgm.evaluation.mot import evaluate_mot
from pgm.inference import Engine
from pgm.io.annotations import MotTable, load_mot
from pgm.io.video import open_source
from pgm.observation.appearance.likelihoods import ColourHistogramLikelihood
from pgm.observation.detections import Detections
from pgm.synthetic import multi_target_scene

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(), "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
n_frames = max(args.max_frames or 100, 40)
seq = multi_target_scene(seed=0, n_frames=n_frames)
seq.write_mot(out / "scene", rng=0, sigma=1.0, clutter_rate=0.5)
source = open_source(out / "scene")
gt = load_mot(source.gt_path, kind="gt")
dets = load_mot(source.det_path, kind="det")

# %%
# The model of one person, declared in this file: nothing in the toolkit is edited.
# Noise is in units of each box's own height, so one setting serves every person.
person = pgm.Variable("person", 4, role="part", labels=("cx", "cy", "w", "h"))
factors = [
    pgm.GaussianPrior("person", mean=[100, 100, 40, 100], cov=0.0),  # re-centred at birth
    pgm.AR2Transition("person", noise_std=[0.03, 0.03, 0, 0], damping=0.5, relative=True),
    ColourHistogramLikelihood("person", lam=20.0),  # a template learned per person
    pgm.DetectionLikelihood("person", pos_std=0.05, size_std=0.1, strength=2000.0),
    pgm.MutualExclusion("person", strength=10.0),  # between replicas
]
plate = pgm.Plate("person", ["person"], lifecycle=pgm.Lifecycle(confirm_hits=3, max_coast=2))
graph = pgm.FactorGraph([person], factors, name="my-multi-pf", plates=[plate],
                        meta={"output": "person", "readout": "plate",
                              "engine": {"num_particles": 60}})
print(graph)
graph.draw(out / "plate_graph.png")  # the plate is the box labelled K
graph.save(out / "my_model.json")  # plain JSON; `pgm track SEQ --model my_model.json` runs it


# %%
# Run it frame by frame: the engine reports, per frame, every replica's box, identity
# and existence score; the "plate" readout keeps the confirmed ones.
def run(graph, drop=()):
    eng = Engine(graph, np.random.default_rng(0))
    rows, counts = [], []
    for number, image in source.frames():
        if number in drop:  # a missing frame: no image, no detections; predicted through
            ctx = pgm.FrameContext(number)
        else:
            _, boxes, scores = dets.at(number)
            ctx = pgm.FrameContext(number, image, detections=Detections(boxes, scores))
        rec = eng.step(ctx)
        targets = pgm.core.readout.readout(eng.graph, rec)
        counts.append(eng.num_targets)
        rows += [(number, i, *b) for i, b in zip(targets.ids, targets.boxes, strict=True)]
    r = np.array(rows, dtype=float).reshape(-1, 6)
    table = MotTable(r[:, 0].astype(int), r[:, 1].astype(int), r[:, 2:], np.ones(len(r)))
    return evaluate_mot(gt, table, num_frames=len(counts)), counts


m, counts = run(graph)
print(f"my-multi-pf: MOTA {m['mota']:.3f}  IDF1 {m['idf1']:.3f}  error rate "
      f"{m['error_rate']:.2f}  (replicas per frame: {min(counts)}..{max(counts)})")

# %%
# Learn a GPDM from ground-truth trajectories (here the scene's own, to keep the
# tutorial small: on real data train on other sequences, as `pgm learn gpdm` does),
# draw its latent space, and use it as the plate's dynamics.
from pgm.dynamics.gpdm import GPDMSettings, gt_trajectories, learn_gpdm  # noqa: E402
from pgm.models import gpdm  # noqa: E402
from pgm.plotting.gpdm import plot_latent_space  # noqa: E402

trajs = gt_trajectories(gt, fps=source.fps, min_length=10, source="scene")
model = learn_gpdm(trajs, GPDMSettings(max_iter=30, max_points=200), np.random.default_rng(0))
model.save(out / "gpdm.npz")
plot_latent_space(model, out / "gpdm_latent.png")
print(f"GPDM: {len(trajs)} trajectories, latent dimension {model.latent_dim}")

drop = {f for f in range(1, len(source) + 1) if f % 20 >= 12}  # 8 of every 20 withheld
for motion in ("gpdm", "cv3"):
    kw = {"model": str(out / "gpdm.npz")} if motion == "gpdm" else {}
    g = gpdm.build_graph(gpdm.Params(motion=motion, fps=source.fps, num_particles=20,
                                     detection_strength=2000.0, **kw))
    full, _ = run(g)
    gap, _ = run(g, drop)
    print(f"gpdm --motion {motion:4s}: MOTA {full['mota']:.3f}  IDF1 {full['idf1']:.3f};  "
          f"with {len(drop)} frames withheld: MOTA {gap['mota']:.3f}  IDF1 {gap['idf1']:.3f}")
print(f"{len(counts)} frames; outputs in {out}")
