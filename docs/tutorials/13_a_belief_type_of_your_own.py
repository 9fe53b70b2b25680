"""
Tutorial 13 — a belief type of your own: a grid filter in one file
==================================================================

The engine keeps every variable's belief in a type that rules are keyed on: particles,
Gaussians, intensities, inverse-Gamma noise. This tutorial adds a fifth, a *grid* belief
(the posterior density held on fixed points: a histogram filter), without editing the
toolkit — everything below is this file:

1. the belief: a class that gives the belief protocol (:mod:`pgm.core.protocol`:
   ``dim``, ``mean()``, ``cov()``, ``estimate()``, ``log_mass``);
2. its rules, registered for the toolkit's own factors: a Gaussian prior evaluated on the
   grid, a linear-Gaussian transition as a convolution, a likelihood as a product, an
   estimate, and no resampling. A rule receives a ``RuleContext`` (the beliefs, the
   generator, the settings), never the engine;
3. a name for it (``register_belief_form``), so that a model may ask for it in its saved
   engine settings;
4. the oracle: on a linear-Gaussian random walk the grid filter's mean and variance equal
   the Kalman filter's — to rounding, because a sum over evenly spaced points of a
   Gaussian many points wide is exact far beyond the spacing (the trapezoid rule on a
   smooth, fast-decaying function);
5. the same graph in a plate: the plate keeps the grid beliefs one per replica
   (``Replicated[GridBelief]``) and runs the single-graph rules once per replica; one
   replica equals the single-graph run bit for bit.

Run it as a script::

    python docs/tutorials/13_a_belief_type_of_your_own.py --out tutorial_out
"""

# %%
import argparse
import os
import tempfile
from pathlib import Path

import numpy as np
from scipy.special import logsumexp

import pgm
from pgm.core.protocol import Belief
from pgm.factors import LikelihoodFactor
from pgm.inference import DEFAULT_RULES, Engine, RuleContext, kalman_filter
from pgm.inference.settings import EngineSettings, register_belief_form

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(), "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
T = max(args.max_frames or 40, 10)


# %%
# 1. The belief: log-weights on fixed grid points ``x`` (G, d), total mass 1.
class GridBelief:
    """A density held on grid points: ``x`` (G, d) and normalised ``log_weights`` (G,)."""

    likelihood_reweights = False  # its likelihood rule updates the belief itself
    log_mass = 0.0  # a normalised density

    def __init__(self, x: np.ndarray, log_weights: np.ndarray):
        self.x = np.asarray(x, dtype=float)
        self.log_weights = np.asarray(log_weights, dtype=float) - logsumexp(log_weights)

    @property
    def dim(self) -> int:
        return self.x.shape[1]

    def mean(self) -> np.ndarray:
        return np.exp(self.log_weights) @ self.x

    def cov(self) -> np.ndarray:
        c = self.x - self.mean()
        return (c * np.exp(self.log_weights)[:, None]).T @ c

    def estimate(self) -> np.ndarray:
        return self.mean()


# %%
# 2. Its rules, for the toolkit's factors (keyed by factor class and belief type).
rules = DEFAULT_RULES.copy()
GRID = np.linspace(-20.0, 20.0, 801)[:, None]  # 0.05 apart; the posterior's sd is ~0.6


@rules.register(pgm.GaussianPrior, GridBelief)
def grid_prior(ctx: RuleContext, factor, frame) -> None:
    ctx.beliefs[factor.variables[0]] = GridBelief(GRID, factor.log_prob(GRID))


@rules.register(pgm.LinearGaussianTransition, GridBelief)
def grid_predict(ctx: RuleContext, factor, frame) -> None:
    """p(x') = sum_j w_j p(x' | x_j): the transition density on every pair of points."""
    b = ctx.beliefs[factor.variables[0]]
    g = len(b.x)
    new, old = np.repeat(b.x, g, axis=0), np.tile(b.x, (g, 1))  # (G*G, d): x'_i, x_j
    log_t = factor.log_prob(new, old).reshape(g, g)
    ctx.beliefs[factor.variables[0]] = GridBelief(b.x, logsumexp(log_t + b.log_weights, axis=1))


@rules.register(LikelihoodFactor, GridBelief)
def grid_update(ctx: RuleContext, factor, frame) -> None:
    b = ctx.beliefs[factor.variables[0]]
    ctx.beliefs[factor.variables[0]] = GridBelief(
        b.x, b.log_weights + factor.log_likelihood(b.x, frame))


@rules.register("estimate", GridBelief)
def grid_estimate(ctx: RuleContext, variable: str, frame) -> np.ndarray:
    return ctx.beliefs[variable].estimate()


@rules.register("resample", GridBelief)
def grid_keeps_its_points(ctx: RuleContext, variable: str, frame) -> None:
    return None


# %%
# 3. A name, so that a saved model can ask for it.
register_belief_form("grid", GridBelief)
assert isinstance(GridBelief(GRID, np.zeros(len(GRID))), Belief)

q, r, m0, p0 = 0.3, 0.8, 0.0, 4.0
graph = pgm.FactorGraph(
    [pgm.Variable("x", 1, role="state", labels=("x",))],
    [pgm.GaussianPrior("x", mean=[m0], cov=p0),
     pgm.LinearGaussianTransition("x", F=[[1.0]], Q=[[q]]),
     pgm.LinearGaussianLikelihood("x", H=[[1.0]], R=[[r]])],
    name="grid-walker",
    meta={"engine": EngineSettings(beliefs={"x": "grid"}).to_dict()})

# %%
# 4. The oracle: the Kalman filter of the same model.
rng = np.random.default_rng(0)
truth = np.cumsum(rng.normal(0.0, np.sqrt(q), T))
ys = truth + rng.normal(0.0, np.sqrt(r), T)
frames = [pgm.FrameContext(t + 1, measurements=ys[t:t + 1]) for t in range(T)]
engine = Engine(graph, rng=1, rules=rules)
means, variances = [], []
for frame in frames:
    engine.step(frame)
    b = engine.beliefs["x"]
    means.append(b.mean()[0])
    variances.append(b.cov()[0, 0])
kf = kalman_filter([m0], [[p0]], [[1.0]], [[q]], [[1.0]], [[r]], ys[:, None])
err_mean = np.abs(np.array(means) - kf.filtered_means[:, 0]).max()
err_var = np.abs(np.array(variances) - kf.filtered_covs[:, 0, 0]).max()
print(f"{T} frames, {len(GRID)} grid points: largest difference from the Kalman filter "
      f"{err_mean:.1e} in the mean, {err_var:.1e} in the variance "
      f"(the Kalman variance settles at {kf.filtered_covs[-1, 0, 0]:.3f})")
assert err_mean < 1e-9 and err_var < 1e-9, (err_mean, err_var)

# %%
# 5. The same model in a plate: one replica is the single-graph run, bit for bit.
plated = pgm.FactorGraph(list(graph.variables.values()), list(graph.factors.values()),
                         name="grid-walkers", meta=graph.meta,
                         plates=[pgm.Plate("target", ("x",))])
plate = Engine(plated, rng=1, rules=rules)
plate.add(None, frames[0], count=1)
single = Engine(graph, rng=1, rules=rules)
single.step(frames[0])
for frame in frames[1:]:
    plate.step(frame, lifecycle=False)
    single.step(frame)
row = plate.beliefs["x"].row(0)
print(f"in a plate: {type(plate.beliefs['x']).__name__}, K = {plate.num_targets}; "
      f"replica 0 equals the single graph: "
      f"{np.array_equal(row.log_weights, single.beliefs['x'].log_weights)}")
assert np.array_equal(row.log_weights, single.beliefs["x"].log_weights)
(out / "grid_vs_kalman.csv").write_text(
    "frame,grid_mean,kalman_mean,grid_var,kalman_var\n" + "".join(
        f"{t + 1},{m:.6f},{km:.6f},{v:.6f},{kv:.6f}\n" for t, (m, km, v, kv) in enumerate(
            zip(means, kf.filtered_means[:, 0], variances, kf.filtered_covs[:, 0, 0],
                strict=True))))
print(f"wrote {out / 'grid_vs_kalman.csv'}")
