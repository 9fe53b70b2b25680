"""
Tutorial 9 — a proposal of your own
===================================

The bootstrap particle filter draws each particle from the transition and lets the
likelihood weigh it. When the measurement is more informative than the motion model,
most particles land where the likelihood is small and a few carry all the weight. A
*proposal* ``q(x_t | x_{t-1}, z_t)`` that looks at the measurement puts them where the
posterior is; the engine corrects each weight by ``p(x_t | x_{t-1}) / q`` (mixed with the
transition for a share ``1 - fraction``), so the answer stays the same posterior.

Here a user-written proposal (a :class:`pgm.factors.ProposalFactor` subclass, a dozen
lines) moves each particle most of the way towards the measured position. It is checked against the
Kalman filter, the exact answer of this model, and compared with the bootstrap filter and
with the toolkit's locally optimal :class:`pgm.factors.LinearGaussianProposal`. A
proposal pays only as far as it matches the posterior; the table says by how much. Run it as
a script::

    python docs/tutorials/09_proposals.py --out tutorial_out

The second half does the same on images: the single-object tracker's re-detection
proposal (:class:`pgm.observation.appearance.redetection.RedetectionProposal`) draws
particles near the peaks of the correlation filter's response around the last estimate
(``scan_side`` object sizes; the 320x240 scene's whole frame) while the
tracker's confidence is low, so a target that jumped across the frame while hidden is
found again — and the weights stay those of the model, because its transition gives
such a jump a (small) probability.
"""

# %%
import argparse
import os
import tempfile
from pathlib import Path

import numpy as np

import pgm
from pgm.factors import LinearGaussianProposal, ProposalFactor
from pgm.inference import Engine, kalman_filter, linear_gaussian_matrices
from pgm.models import linear_gaussian as lg

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(),
                                                              "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
T = min(args.max_frames or 40, 40)


# %%
# The proposal: the transition's mean moved most of the way (``gain``) to the measured
# position — the velocity following as the transition's noise correlates it with the
# position — with the transition's noise. ``sample`` draws, ``log_prob`` scores what was drawn — any
# proposal that covers the posterior is valid; the better it matches, the less the weights
# vary.
class TowardsTheMeasurement(ProposalFactor):
    """``N(F x + gain (y − H F x) (Q Hᵀ / H Q Hᵀ)ᵀ, Q)``: towards the measurement."""

    def __init__(self, variable, *, F, Q, H, gain=0.8, fraction=1.0, name=None):
        super().__init__(variable, fraction=fraction, name=name)
        self.F, self.Q, self.H = (np.atleast_2d(np.asarray(a, float)) for a in (F, Q, H))
        self.gain = float(gain)
        self._chol = np.linalg.cholesky(self.Q)

    def params(self):
        return {"F": self.F, "Q": self.Q, "H": self.H, "gain": self.gain,
                "fraction": self.fraction}

    def _mean(self, ctx, x_prev):
        m = x_prev @ self.F.T
        # along Q Hᵀ: the measured component moves and the others follow as they covary
        along = (self.Q @ self.H.T / (self.H @ self.Q @ self.H.T)).T
        return m + self.gain * (np.asarray(ctx.measurements, float) - m @ self.H.T) @ along

    def sample(self, rng, ctx, *past):
        m = self._mean(ctx, past[0])
        return m + rng.standard_normal(m.shape) @ self._chol.T

    def log_prob(self, x, ctx, *past):
        u = np.linalg.solve(self._chol, (x - self._mean(ctx, past[0])).T)
        return (-0.5 * np.sum(u * u, axis=0) - np.log(np.diag(self._chol)).sum()
                - 0.5 * len(self.F) * np.log(2 * np.pi))


# %%
# The model: a constant-velocity target whose position is measured precisely (R = 0.02),
# where the bootstrap filter's weights degenerate.
p = lg.Params(R=np.array([[0.02]]))
graph = lg.build_graph(p)
_, ys = lg.simulate(np.random.default_rng(1), p, T)
kf = kalman_filter(**linear_gaussian_matrices(graph, "x"), ys=ys)
frames = [pgm.FrameContext(t + 1, measurements=ys[t]) for t in range(T)]
variants = {
    "bootstrap (the transition)": graph,
    "user proposal (gain 0.8)": graph.with_factors(
        TowardsTheMeasurement("x", F=p.F, Q=p.Q, H=p.H)),
    "locally optimal proposal": graph.with_factors(
        LinearGaussianProposal("x", F=p.F, Q=p.Q, H=p.H, R=p.R)),
}

# %%
# Twelve independent runs of 100 particles each: the mean error against the Kalman
# filter's means, and the spread of the marginal log-likelihood estimate.
rows = []
for label, g in variants.items():
    err, loglik = [], []
    for stream in np.random.default_rng(5).spawn(12):
        recs = list(Engine(g, stream, num_particles=100).run(frames))
        err.append(np.mean([np.abs(r.estimates["x"][0] - m[0])
                            for r, m in zip(recs, kf.filtered_means, strict=True)]))
        loglik.append(sum(r.log_evidence["x"] for r in recs))
    rows.append((label, float(np.mean(err)), float(np.mean(loglik)),
                 float(np.std(loglik, ddof=1))))
lines = [f"{'proposal':<28} {'|pos - KF| mean':>15} {'log-lik mean':>13} {'log-lik sd':>11}"]
lines += [f"{a:<28} {b:>15.4f} {c:>13.2f} {d:>11.2f}" for a, b, c, d in rows]
lines.append(f"{'Kalman filter (exact)':<28} {0.0:>15.4f} "
             f"{kf.marginal_log_likelihood:>13.2f} {0.0:>11.2f}")
print("\n".join(lines))
(out / "proposals.txt").write_text("\n".join(lines) + "\n")
print(f"{T} frames; wrote {out / 'proposals.txt'}")


# %%
# Re-detection. A textured object vanishes behind a page (frames 36-55) and comes back
# 180 px away (:func:`pgm.synthetic.scenes.jump_scene`). The default single-object
# tracker stays where it vanished; with ``redetect=0.5`` (``pgm track ... --redetect
# 0.5``) half the particles come from the filter's scan in the frames where the
# calibrated confidence is below one half.
from pgm.core.boxes import cxcywh_to_xywh, iou_xywh  # noqa: E402
from pgm.models import single_object  # noqa: E402
from pgm.synthetic.scenes import jump_scene  # noqa: E402

seq = jump_scene(0)  # 90 frames, whatever --max-frames says: the jump is at 56
x, y, w, h = seq.boxes[0]
lines = [f"{'single-object tracker':<26} {'IoU >= 0.5 before':>18} {'after the jump':>15}"]
for label, share in (("default", 0.0), ("with re-detection", 0.5)):
    params = single_object.Params(init_box=(x + w / 2, y + h / 2, w, h), redetect=share,
                                  frame_size=(320, 240))
    engine = Engine(single_object.build_graph(params), np.random.default_rng(0))
    hit = np.array([iou_xywh(cxcywh_to_xywh(engine.step(pgm.FrameContext(k + 1, img))
                                           .estimates["object"]), seq.boxes[k]) >= 0.5
                    for k, img in enumerate(seq.frames)])
    after = hit[55:].mean()
    lines.append(f"{label:<26} {hit[:35].mean():>18.2f} {after:>15.2f}")
print("\n".join(lines))
(out / "redetection.txt").write_text("\n".join(lines) + "\n")
