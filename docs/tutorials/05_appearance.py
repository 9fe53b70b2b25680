"""
Tutorial 5 — appearance: composing cues, and a learned person likelihood
========================================================================

Several likelihood factors on one variable multiply — declaring them is all it takes.
This tutorial composes colour, fragment, oriented-gradient, GMM-KL, rotation-invariant,
colour-contrast and template (NCC) cues on a one-node tracker and compares them on a synthetic
occlusion scene (the ``single-object`` model that ``pgm track`` runs by default uses
another cue, a correlation filter: tutorial 06), then trains the
deep-belief-network person likelihood of the VB-PHD paper [#feng2015] on one synthetic crowd and
uses it as an appearance factor of a PHD filter on another. Run it as a script::

    python docs/tutorials/05_appearance.py --out tutorial_out

References
----------
.. [#feng2015] P. Feng, W. Wang, S. M. Naqvi and J. A. Chambers, "Variational Bayesian PHD
   filter with deep learning network updating for multiple human tracking", Proc. Sensor
   Signal Processing for Defence (SSPD), Edinburgh, 2015 (venue inferred; DOI not confirmed).
"""

# %%
# Cues are factors. Each scores all particles of a frame in one pass
# and sharing per-frame work (colour quantisation, gradient integral images) through
# the frame cache.
import argparse
import os
import tempfile
from pathlib import Path

import numpy as np

import pgm
from pgm.app.runner import track, track_multi
from pgm.io.annotations import load_mot, load_single_gt
from pgm.io.video import open_source
from pgm.models import phd
from pgm.observation.appearance.dbn import DBN, DBNLikelihood, training_set
from pgm.observation.appearance.features import PatchFeatures
from pgm.observation.appearance.likelihoods import (
    ColourContrastLikelihood,
    ColourHistogramLikelihood,
    FragmentsLikelihood,
    GMMKLLikelihood,
    GradientLikelihood,
    RotationInvariantLikelihood,
    TemplateLikelihood,
)
from pgm.observation.detections import PublicDetections
from pgm.synthetic import demo_scene, multi_target_scene

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(), "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
n = max(args.max_frames or 90, 60)

demo_scene(seed=0, n_frames=n).write_otb(out / "scene")
source = open_source(out / "scene")
gt = load_single_gt(source.gt_path)
x, y, w, h = gt.boxes[0]
box = (x + w / 2, y + h / 2, w, h)
s = 0.03 * np.sqrt(w * h)


def tracker(*cues):
    """One box node with the given likelihood factors (they multiply)."""
    return pgm.FactorGraph(
        [pgm.Variable("object", 4, role="part", labels=("cx", "cy", "w", "h"))],
        [pgm.GaussianPrior("object", mean=box), pgm.AR2Transition("object",
                                                                   noise_std=[s, s, 0, 0]),
         *cues],
        name="+".join(type(c).__name__.replace("Likelihood", "") for c in cues),
        meta={"output": "object"})


# %%
# Compare compositions (same seed, same particles).
for graph in (tracker(ColourHistogramLikelihood("object")),
              tracker(FragmentsLikelihood("object")),
              tracker(ColourHistogramLikelihood("object"), GradientLikelihood("object", lam=10)),
              tracker(FragmentsLikelihood("object"), GradientLikelihood("object", lam=10)),
              tracker(GMMKLLikelihood("object")),
              tracker(ColourContrastLikelihood("object")),
              tracker(FragmentsLikelihood("object"), RotationInvariantLikelihood("object"),
                      ColourContrastLikelihood("object")),
              # the previous default single-object model's cues
              tracker(ColourContrastLikelihood("object"), TemplateLikelihood("object"))):
    r = track(source, graph, rng=np.random.default_rng(0), gt=gt, num_particles=100,
              progress=False)
    print(f"{graph.name:45s} success AUC {r.metrics['success_auc']:.3f} "
          f"({r.fps:.0f} frames/s)")
graph.draw(out / "composed_cues.png")

# %%
# A learned likelihood: train the DBN (colour + gradient features of patches, two RBM
# layers pre-trained by contrastive divergence, a logistic unit fine-tuned by
# back-propagation, Platt calibration) on one synthetic crowd ...
multi_target_scene(seed=0, n_frames=n).write_mot(out / "crowd-train", rng=0)
multi_target_scene(seed=1, n_frames=n).write_mot(out / "crowd-test", rng=1)
X, labels = training_set([out / "crowd-train"], np.random.default_rng(0), every=4)
net = DBN(hidden=(32, 16))
net.features_ = PatchFeatures().to_dict()
net.fit(X, labels, np.random.default_rng(1), rbm_epochs=5, finetune_epochs=20)
net.save(out / "dbn.npz")  # .npz, loaded without pickle
Xt, yt = training_set([out / "crowd-test"], np.random.default_rng(2), every=6)
print(f"DBN on held-out patches: accuracy {np.mean((net.predict_proba(Xt) > 0.5) == yt):.3f} "
      f"(base rate {max(yt.mean(), 1 - yt.mean()):.3f})")

# %%
# ... and use it on the other crowd as an appearance factor of a PHD filter: declared on
# the set variable, it multiplies the detection terms by ℓ(x)^γ.
test = open_source(out / "crowd-test")
W, H = test.size
base = phd.build_graph(phd.Params(area=W * H, sigma=3.0, q=0.3, birth_velocity_std=3.0))
with_dbn = base.with_factors(DBNLikelihood("targets", model=str(out / "dbn.npz"),
                                           name="appearance:dbn"), name="phd+dbn")
gt_crowd = load_mot(test.gt_path, kind="gt")
for graph in (base, with_dbn):
    r = track_multi(test, graph, PublicDetections(test.det_path),
                    rng=np.random.default_rng(0), gt=gt_crowd, write_video=False,
                    progress=False, max_frames=args.max_frames)
    print(f"{graph.name:8s}: MOTA {r.metrics['mota']:.3f} IDF1 {r.metrics['idf1']:.3f} "
          f"over {r.n_frames} frames")
print(f"outputs in {out}")
