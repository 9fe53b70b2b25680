"""
Tutorial 14 — a researcher's tasks, done the documented way
===========================================================

Four tasks a researcher new to the toolkit brings, each with the public API only (no
internals, no global rule table edited):

A. a constant-acceleration box (the motion library, in seconds) with a likelihood of
   one's own — a normalised cross-correlation (NCC) template — and its own inference
   rule declared with the factor class; the run is saved as ``model.json`` and the
   reloaded model reproduces it exactly (the rule travels by name);
B. a head/torso/legs part graph from the toolkit's factors, stepped through stage by
   stage (``engine.stages``) on a frame where the legs are hidden behind a wall;
D. an unknown measurement noise on model A: an inverse-Gamma noise node joined to a
   linear-Gaussian measurement of the box centre, updated by mean-field VB on the
   particles — no VB rule written by hand (the likelihood's ``noise_residuals`` is the
   conjugate contract).

C. SORT plus one idea of one's own: a Mahalanobis gate on the Kalman filter's predicted
   covariance, added to SORT's association as a gate (the association's extension
   points) — not by post-filtering its output with the toolkit's internals;

Run it as a script::

    python docs/tutorials/14_a_researchers_tasks.py --out tutorial_out
"""

# %%
import argparse
import json
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import pgm
from pgm.core.expfam import Gaussian
from pgm.core.learned import LearnedState
from pgm.factors import LikelihoodFactor, LinearGaussianLikelihood
from pgm.factors.motion import constant_acceleration
from pgm.factors.multitarget import InverseGammaPrior, NoiseForgetting, VBNoise
from pgm.inference import Engine, RuleContext
from pgm.inference.rules import declare
from pgm.models import part_graph
from pgm.synthetic import demo_scene

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(), "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
T = min(max(args.max_frames or 60, 55), 90)

scene = demo_scene(seed=0, n_frames=T)  # a person walking behind a low wall (frames 48-69)
x0, y0, w0, h0 = scene.box(0, 1)
FPS = scene.fps


def truth_centre(f: int) -> np.ndarray:
    x, y, w, h = scene.box(0, f)
    return np.array([x + w / 2, y + h / 2])


# %%
# A. A likelihood of one's own: NCC of a grid of grey levels against a template learned
#    on the first frame — vectorised over particles (no loop over them). What it learns is
#    declared as its State: the engine keeps one per learner (each replica of a plate
#    its own), the factor's parameters are shared.
@dataclass
class NCCState(LearnedState):
    template: np.ndarray | None = None  # (grid², ) learned on the first frame


class NCCTemplate(LikelihoodFactor):
    """``lam * NCC(template, patch at the particle's box)`` on a ``grid x grid`` sample."""

    State = NCCState

    def __init__(self, variable, *, lam=20.0, grid=12, name=None):
        super().__init__(variable, name=name)
        self.lam, self.grid = float(lam), int(grid)

    def params(self):
        return {"lam": self.lam, "grid": self.grid}

    def _patches(self, boxes: np.ndarray, image: np.ndarray) -> np.ndarray:
        grey = image.mean(axis=2)
        u = (np.arange(self.grid) + 0.5) / self.grid - 0.5  # box-relative sample points
        xs = boxes[:, :1] + boxes[:, 2:3] * u[None, :]  # (N, g)
        ys = boxes[:, 1:2] + boxes[:, 3:4] * u[None, :]
        xi = np.clip(np.rint(xs).astype(int), 0, grey.shape[1] - 1)
        yi = np.clip(np.rint(ys).astype(int), 0, grey.shape[0] - 1)
        p = grey[yi[:, :, None], xi[:, None, :]].reshape(len(boxes), -1)  # (N, g*g)
        p = p - p.mean(axis=1, keepdims=True)
        return p / (np.linalg.norm(p, axis=1, keepdims=True) + 1e-9)

    def initialize(self, ctx, value):
        self.template = self._patches(np.asarray(value, float)[None, :4], ctx.image)[0]

    def ncc(self, x, ctx):
        return self._patches(x[:, :4], ctx.image) @ self.template  # (N,) in [-1, 1]

    def log_likelihood(self, x, ctx):
        return self.lam * self.ncc(x, ctx)


@declare(NCCTemplate, pgm.Particles)
def ncc_rule(ctx: RuleContext, factor: NCCTemplate, frame) -> np.ndarray:
    """Its own rule: the NCC likelihood, floored at zero correlation (a particle on the
    background scores no worse than an uncorrelated patch)."""
    x = ctx.beliefs[factor.variables[0]].x
    return factor.lam * np.maximum(factor.ncc(x, frame), 0.0)


LABELS = ("cx", "cy", "w", "h", "vx", "vy", "ax", "ay")
start = np.array([x0 + w0 / 2, y0 + h0 / 2, w0, h0, 0, 0, 0, 0])
model_a = pgm.FactorGraph(
    [pgm.Variable("box", 8, role="state", labels=LABELS)],
    [pgm.GaussianPrior("box", mean=start, cov=np.diag([4, 4, 1, 1, 400, 400, 100, 100.0])),
     constant_acceleration("box", labels=LABELS, axes=[("cx", "vx", "ax"), ("cy", "vy", "ay")],
                           q=2000.0, fps=FPS, q_static=4.0),  # px²/s⁵ jerk; px²/s size walk
     NCCTemplate("box", name="ncc")],
    name="ca-ncc", meta={"output": ["box"]})


def run(graph, frames, seed=1, particles=300):
    engine = Engine(graph, seed, num_particles=particles)
    est = np.array([engine.step(pgm.FrameContext(f, image)).estimates["box"]
                    for f, image in frames])
    return engine, est


frames = [(f, scene.frames[f - 1]) for f in range(1, T + 1)]
engine_a, est_a = run(model_a, frames)
err_a = np.linalg.norm(est_a[:, :2] - np.array([truth_centre(f) for f, _ in frames]), axis=1)
print(f"A: constant acceleration + NCC: centre error median {np.median(err_a):.1f} px over "
      f"{T} frames; rule serving 'ncc': {engine_a.graph.meta['rules']['ncc']}")
(out / "model.json").write_text(json.dumps(engine_a.graph.to_dict()))
reloaded = pgm.FactorGraph.from_dict(json.loads((out / "model.json").read_text()))
_, est_again = run(reloaded, frames)
assert np.array_equal(est_again, est_a), "the reloaded model must reproduce the run"
print("A: model.json reloaded and re-run: the same estimates, bit for bit")

# %%
# B. Head, torso and legs from the toolkit's factors, stepped through on a frame where
#    the legs are hidden (48-69): the legs' particles lean on the torso's messages.
graph_b = part_graph.build_graph(part_graph.Params(
    init_box=(x0 + w0 / 2, y0 + h0 / 2, w0, h0), n_parts=3, num_particles=60))
parts = list(graph_b.variables)
engine_b = Engine(graph_b, 0)
hidden = min(55, T)
for f, image in frames[:hidden - 1]:
    engine_b.step(pgm.FrameContext(f, image))
print(f"B: parts {parts}; frame {hidden}, legs hidden, stage by stage:")
for stage, record in engine_b.stages(pgm.FrameContext(hidden, scene.frames[hidden - 1])):
    if stage in ("weight", "inframe", "fuse", "estimate"):
        ess = {v: round(float(e), 1) for v, e in record.ess.items()}
        msgs = sorted(f"{s}->{d}" for s, d in record.messages)
        print(f"   after {stage:8s} ESS {ess}  messages {msgs}")
legs = record.estimates[parts[-1]]
print(f"B: the legs' estimate at frame {hidden}: centre ({legs[0]:.0f}, {legs[1]:.0f}); "
      f"truth's bottom band centre x {truth_centre(hidden)[0]:.0f}")

# %%
# C. SORT with a gate of one's own: the detector glitches for two frames (its box jumps
#    8 px, IoU 0.58); the IoU gate lets the jump through, the Mahalanobis gate on the predicted
#    covariance refuses it and the track coasts through on its prediction.
from pgm.factors.association import DetectionAssociation  # noqa: E402
from pgm.inference.association_terms import mahalanobis_gate  # noqa: E402
from pgm.models import sort  # noqa: E402
from pgm.observation.detections import Detections  # noqa: E402

sort_graph = sort.build_graph(sort.Params())
old = sort_graph.factors_by_kind("association")[0]
gated = pgm.FactorGraph(
    list(sort_graph.variables.values()),
    [f for f in sort_graph.factors.values() if f is not old]
    + [DetectionAssociation(old.variables[0], **old.params(), name=old.name,
                            gates=[{"fn": mahalanobis_gate, "args": {"quantile": 0.99}}])],
    name="sort+mahalanobis", meta=sort_graph.meta, plates=sort_graph.plates)
glitch = (30, 31)
worst_of = {}
for label, graph in (("SORT", sort_graph), ("SORT + Mahalanobis gate", gated)):
    engine_c = Engine(graph, 0)
    worst = 0.0
    for f in range(1, 41):
        x, y, w, h = scene.box(0, f)
        box = np.array([x + (8.0 if f in glitch else 0.0), y, w, h])
        rec = engine_c.step(pgm.FrameContext(f, detections=Detections(box[None], np.ones(1))))
        if f in glitch:
            info = rec.plate
            first = int(np.flatnonzero(info["ids"] == 1)[0])  # the first track
            worst = max(worst, abs(info["boxes"][first][0] - (x + w / 2)))
    worst_of[label] = worst
    print(f"C: {label}: the first track's centre during the glitch is {worst:.1f} px off "
          f"the truth; {engine_c.num_targets} track(s) at the end")
assert worst_of["SORT + Mahalanobis gate"] < worst_of["SORT"] / 2, worst_of

# %%
# D. The unknown noise of a centre measurement (say, a detector's) on model A's motion,
#    learned by VB on the particles — and, for reference, by the closed-form VB adaptive
#    Kalman filter on the same graph (a Gaussian belief: ``belief_types``). The noise
#    node's prior says 2 px; the measurements have 6 px.
rng = np.random.default_rng(5)
H = np.zeros((2, 8))
H[0, 0] = H[1, 1] = 1.0
motion = constant_acceleration("box", labels=LABELS, axes=[("cx", "vx", "ax"), ("cy", "vy", "ay")],
                               q=20000.0, fps=FPS, q_static=4.0)
model_d = pgm.FactorGraph(
    [*model_a.variables.values(), pgm.Variable("noise", 2, role="noise")],
    [model_a.factors_of("box", "prior")[0], motion,
     LinearGaussianLikelihood("box", H=H, R=np.eye(2), name="centre"),
     InverseGammaPrior("noise", sigma=[2.0, 2.0], alpha=3.0),
     NoiseForgetting("noise", rho=0.95, alpha_min=2.0),
     VBNoise("noise", "box", likelihood="centre", tol=1e-6, max_iter=20, name="vb")],
    name="ca-vb", meta=model_a.meta)
measurements = [truth_centre(f) + rng.normal(0, 6.0, 2) for f, _ in frames]
learned = {}
for kind, engine_d in (("particles", Engine(model_d, 1, num_particles=500)),
                       ("Gaussian", Engine(model_d, 1, belief_types={"box": Gaussian}))):
    r_hat = []
    for (f, image), z in zip(frames, measurements, strict=True):
        engine_d.step(pgm.FrameContext(f, image, measurements=z))
        r_hat.append(np.sqrt(engine_d.beliefs["noise"].r_hat()))
    learned[kind] = np.mean(r_hat[-20:], axis=0)
    print(f"D: noise sd learned by VB, {kind} belief: {learned[kind].round(1)} px (truth 6, "
          f"prior 2); rule: {engine_d.graph.meta['rules']['vb']}")
assert np.all(learned["particles"] > 3.0), learned  # moved from the prior, towards the truth
