"""
Tutorial 3 — your own factors and your own model, in your own file
===================================================================

Nothing here touches the toolkit: a new coupling factor and a new likelihood factor
are ordinary subclasses, a new tracker is a function that returns a
:class:`pgm.FactorGraph`, and the generic engine runs it — particle BP included.
Run it as a script::

    python docs/tutorials/03_your_own_model.py --out tutorial_out
"""

# %%
# A coupling: "``a`` sits on top of ``b``", with a heavy-tailed (Laplace) potential on
# the vertical offset — robust to a part that is briefly mislocated. A coupling needs
# ``map`` (the deterministic image of particles at the other end), ``log_prob`` (the
# potential, broadcasting over leading axes: product fusion evaluates an N x M matrix)
# and, if message particles should be jittered, ``propagate``.
import argparse
import os
import tempfile
from pathlib import Path

import cv2
import numpy as np

import pgm
from pgm.app.runner import track
from pgm.io.annotations import load_single_gt
from pgm.io.video import open_source
from pgm.observation.appearance.likelihoods import ColourHistogramLikelihood


class StackedParts(pgm.CouplingFactor):
    """``a`` above ``b``: ``cx_a = cx_b``, ``cy_a = cy_b - gap``; Laplace potential."""

    def __init__(self, a, b, *, gap, scale=2.0, jitter=1.0, name=None):
        super().__init__(a, b, name=name)
        self.gap, self.scale, self.jitter = float(gap), float(scale), float(jitter)

    def params(self):  # what a saved model stores
        return {"gap": self.gap, "scale": self.scale, "jitter": self.jitter}

    def map(self, x_src, src):
        shift = np.array([0.0, self.gap, 0.0, 0.0])
        return x_src - shift if src == self.variables[1] else x_src + shift

    def propagate(self, rng, x_src, src):
        out = self.map(x_src, src)
        out[:, :2] += self.jitter * rng.standard_normal((len(out), 2))
        return out

    def log_prob(self, x_a, x_b):
        d = np.abs(x_a[..., :2] - x_b[..., :2] - [0.0, -self.gap]).sum(-1)
        return -d / self.scale - 2 * np.log(2 * self.scale)


# %%
# A likelihood: the mean brightness inside the box should stay what it was in frame 1.
# All particles are scored at once from an integral image, computed once per frame and
# cached on the frame (any other factor asking for it gets the same array).
class BrightnessLikelihood(pgm.LikelihoodFactor):
    """``log p(z | x) = -|mean brightness(box) - template| / tau``."""

    def __init__(self, variable, *, tau=4.0, template=None, name=None):
        super().__init__(variable, name=name)
        self.tau = float(tau)
        self.template = None if template is None else float(template)

    def params(self):
        p = {"tau": self.tau}
        if self.template is not None:
            p["template"] = self.template
        return p

    def _mean(self, x, ctx):
        ii = ctx.cached("grey-integral", lambda: cv2.integral(
            cv2.cvtColor(ctx.image, cv2.COLOR_BGR2GRAY)).astype(float))
        H, W = ctx.shape
        x0 = np.clip(np.round(x[:, 0] - x[:, 2] / 2), 0, W).astype(int)
        x1 = np.clip(np.round(x[:, 0] + x[:, 2] / 2), 0, W).astype(int)
        y0 = np.clip(np.round(x[:, 1] - x[:, 3] / 2), 0, H).astype(int)
        y1 = np.clip(np.round(x[:, 1] + x[:, 3] / 2), 0, H).astype(int)
        area = np.maximum((x1 - x0) * (y1 - y0), 1)
        return (ii[y1, x1] - ii[y0, x1] - ii[y1, x0] + ii[y0, x0]) / area

    def initialize(self, ctx, value):
        if self.template is None:
            self.template = float(self._mean(np.asarray(value)[None], ctx)[0])

    def log_likelihood(self, x, ctx):
        return -np.abs(self._mean(x, ctx) - self.template) / self.tau


# %%
# The model: a function that returns a graph. Two parts — head and body — each with a
# prior, an AR(2) transition and a likelihood (brightness for the head, colour for the
# body), and the new coupling between them.
def head_and_body(box, particles=20):
    cx, cy, w, h = box
    head = np.array([cx, cy - h / 4, w, h / 2])
    body = np.array([cx, cy + h / 4, w, h / 2])
    s = 0.03 * np.sqrt(w * h)
    labels = ("cx", "cy", "w", "h")
    factors = []
    for name, b in (("head", head), ("body", body)):
        factors += [pgm.GaussianPrior(name, mean=b, cov=0.0),
                    pgm.AR2Transition(name, noise_std=[s, s, 0, 0], damping=0.5)]
    factors += [BrightnessLikelihood("head"), ColourHistogramLikelihood("body"),
                StackedParts("head", "body", gap=h / 2)]
    return pgm.FactorGraph(
        [pgm.Variable("head", 4, role="part", labels=labels),
         pgm.Variable("body", 4, role="part", labels=labels)],
        factors, name="head-and-body",
        meta={"output": ["head", "body"], "engine": {"num_particles": particles},
              "part_offsets": {"head": (np.asarray(box) - head).tolist(),
                               "body": (np.asarray(box) - body).tolist()}})


# %%
# Use it like any built-in model: draw it, save and reload it (plain JSON: your
# classes are found by name once this module has defined them), track, score.
parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(), "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)

from pgm.synthetic import demo_scene  # noqa: E402

demo_scene(seed=1, n_frames=args.max_frames or 60).write_otb(out / "scene")
source = open_source(out / "scene")
gt = load_single_gt(source.gt_path)
x, y, w, h = gt.boxes[0]
graph = head_and_body((x + w / 2, y + h / 2, w, h))
graph.draw(out / "head_and_body.png")
graph.save(out / "head_and_body.json")
assert pgm.FactorGraph.load(out / "head_and_body.json") == graph
for fusion in ("mixture", "product"):
    result = track(source, graph, rng=np.random.default_rng(0), out_dir=out / fusion, gt=gt,
                   engine_kwargs={"fusion": fusion}, progress=False)
    print(f"{fusion:8s}: {len(result.frames)} frames at {result.fps:.0f} frames/s, success AUC "
          f"{result.metrics['success_auc']:.3f}")
print(f"outputs in {out}")
