"""Copy me: a new factor, its own inference rule, and the conformance check it must pass.

Copy this file next to your model, rename the classes, keep the structure:

1. **The factor** subclasses a kind base (here :class:`pgm.LikelihoodFactor`), takes
   its scope's variable names first and its parameters as keywords, and returns those
   keywords from ``params()`` so a saved graph rebuilds it (registration by class name
   is automatic: loading a ``model.json`` never runs code).
2. **The rule** (optional: the default rule for likelihoods already scores every
   particle with ``log_likelihood``) is registered for *(factor class, belief type)*
   in a copy of the rule table. On particles, a likelihood rule **returns** its
   log-likelihood increment, shape ``(N,)``, and never moves, reorders or resamples
   particles: the engine applies the increment and keeps it as the local evidence
   that particle-BP messages read.
3. **The check**: run your model with ``rules=checked(your_table)``; every rule call
   is then checked against its contract and a broken promise raises
   :class:`pgm.core.errors.RuleContractError` naming the rule.

Run: ``python docs/skeletons/new_factor_and_rule.py`` (a few seconds; ``--out`` is
accepted and ignored, so the docs test can run every script the same way).
"""

# %%
from __future__ import annotations

import argparse
from collections import Counter

import numpy as np

import pgm
from pgm.inference import DEFAULT_RULES, Engine, RuleContext
from pgm.inference.conformance import checked

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--out", default=None, help="unused (uniform tutorial interface)")
parser.add_argument("--max-frames", type=int, default=30)
args = parser.parse_args()


# %%
# 1. The factor: a Student-t point measurement of the first two state components —
#    heavy tails, so one outlier measurement does not drag the estimate.
class StudentTPoint(pgm.LikelihoodFactor):
    """``z ~ t_nu(x[:2], scale²)`` with ``z`` from ``frame.measurements``."""

    def __init__(self, variable: str, *, scale: float = 1.0, nu: float = 3.0,
                 name: str | None = None):
        super().__init__(variable, name=name)
        if not (np.isfinite(scale) and scale > 0 and np.isfinite(nu) and nu > 0):
            raise ValueError(f"factor {self.name!r}: scale and nu must be positive, got "
                             f"{scale!r}, {nu!r}")
        self.scale, self.nu = float(scale), float(nu)

    def params(self) -> dict:
        return {"scale": self.scale, "nu": self.nu}

    def log_likelihood(self, x: np.ndarray, ctx: pgm.FrameContext) -> np.ndarray:
        z = np.asarray(ctx.measurements, dtype=float)
        r2 = (((x[:, :2] - z) / self.scale) ** 2).sum(axis=1)  # (N,), vectorised
        return -0.5 * (self.nu + 2.0) * np.log1p(r2 / self.nu)


# %%
# 2. Its own rule: tempered by a factor ``beta`` (e.g. for annealing). It returns the
#    increment and touches no belief.
rules = DEFAULT_RULES.copy()
BETA = 0.8


@rules.register(StudentTPoint, pgm.Particles)
def tempered_student_t(ctx: RuleContext, factor: StudentTPoint, frame) -> np.ndarray:
    x = ctx.beliefs[factor.variables[0]].x  # a rule sees a RuleContext, not the engine
    return BETA * factor.log_likelihood(x, frame)


# %%
# A model using it: a 2-D constant-position walker observed through the new factor.
graph = pgm.FactorGraph(
    [pgm.Variable("p", 2, role="state", labels=("x", "y"))],
    [pgm.GaussianPrior("p", mean=[0.0, 0.0], cov=4.0),
     pgm.LinearGaussianTransition("p", F=np.eye(2), Q=0.25 * np.eye(2)),
     StudentTPoint("p", scale=1.0, nu=3.0)],
    name="student-t-walker")
assert pgm.FactorGraph.from_dict(graph.to_dict()) == graph  # saves and loads as data

# %%
# 3. Run it with every rule call checked against its contract.
rng = np.random.default_rng(0)
truth = np.cumsum(rng.normal(0.0, 0.5, (args.max_frames, 2)), axis=0)
z = truth + rng.standard_t(3.0, truth.shape)
calls: Counter = Counter()
engine = Engine(graph, np.random.default_rng(1), rules=checked(rules, calls), num_particles=500)
est = np.array([engine.step(pgm.FrameContext(t + 1, measurements=z[t])).estimates["p"]
                for t in range(args.max_frames)])
err = np.sqrt(((est - truth) ** 2).sum(axis=1)).mean()
raw = np.sqrt(((z - truth) ** 2).sum(axis=1)).mean()
assert calls[(StudentTPoint, pgm.Particles)] == args.max_frames  # our rule ran each frame
print(f"{args.max_frames} frames: mean error {err:.2f} (measurements alone {raw:.2f}); "
      f"rule calls checked: {sum(calls.values())}")
