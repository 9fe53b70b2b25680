"""
Tutorial 21 — Particles that collapse, and a kernel that spreads them again
==========================================================================

A particle filter resamples: the particles the likelihood favoured are copied, the others
dropped. The transition's noise is what spreads the copies apart again. When that noise
is small against the posterior's spread (a walker's velocity changes little from one frame
to the next), the cloud shrinks onto a few distinct points after a few frames: *sample
impoverishment*. The estimates then lag behind the target and depend on which points
survived.

A regularised particle filter draws each resampled particle from a kernel around its
ancestor instead (Musso, Oudjane & Le Gland). On a PHD intensity the toolkit's kernel is
per target: a measurement's share of the particles is that target's posterior, and
Liu & West's shrinkage keeps its mean and covariance (``PHDLikelihood(regularise=True)``,
``pgm.inference.phd_regularise``).

The tutorial

1. draws three walkers with little process noise, detections with p_D 0.95 and clutter;
2. runs the PHD filter with 40 particles per target, plain and regularised, and prints the
   mean distance of the extracted positions to the truth and how many distinct positions
   one target's cloud keeps after resampling;
3. plots one target's particles at a late frame, plain and regularised, over the truth.

Run it as a script::

    python docs/tutorials/21_particles_that_collapse.py --out tutorial_out
"""

# %%
import argparse
import os
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from pgm.core.frame import FrameContext  # noqa: E402
from pgm.inference import Engine  # noqa: E402
from pgm.models import phd  # noqa: E402

parser = argparse.ArgumentParser(description=__doc__.split("\n")[1])
OUT_ROOT = os.environ.get("PGM_TUTORIAL_OUT") or os.path.join(tempfile.gettempdir(),
                                                              "pgm-tutorials")
parser.add_argument("--out", default=os.path.join(OUT_ROOT, Path(__file__).stem),
                    help="output folder (default: %(default)s; $PGM_TUTORIAL_OUT sets its parent)")
parser.add_argument("--max-frames", type=int, default=None)
args = parser.parse_args()
out = Path(args.out)
out.mkdir(parents=True, exist_ok=True)
T = min(40, args.max_frames or 40)

# %%
# 1. Three walkers at constant velocity in a 200 x 200 area; detections (σ 3) with
#    p_D 0.95 and about 4 clutter points a frame.
rng = np.random.default_rng(7)
starts = np.array([[20.0, 1.0, 20.0, 0.6], [150.0, -0.8, 60.0, 0.5],
                   [80.0, 0.3, 160.0, -1.0]])
truth, meas = [], []
for t in range(T):
    pos = starts[:, [0, 2]] + t * starts[:, [1, 3]]
    truth.append(pos)
    z = [p + 3.0 * rng.standard_normal(2) for p in pos if rng.random() < 0.95]
    z += list(rng.uniform(0, 200, size=(rng.poisson(4), 2)))
    meas.append(np.array(z).reshape(-1, 2))
print(f"{T} frames: 3 walkers, {sum(len(z) for z in meas)} measurements")

# %%
# 2. The same filter, plain and regularised: little process noise (q 0.01), 40 particles
#    per target. The error is the distance of each extracted position to the nearest
#    walker (those within 15 of one); "distinct" counts one walker's different particle
#    positions after the last resampling.
clouds, errors = {}, {}
for reg in (False, True):
    params = phd.Params(area=200.0**2, sigma=3.0, q=0.01, clutter_rate=4.0, p_detect=0.95,
                        birth_velocity_std=1.0, n_birth=20, particles_per_target=40,
                        min_particles=40, regularise=reg)
    eng = Engine(phd.build_graph(params), np.random.default_rng(0))
    err = []
    for t, z in enumerate(meas):
        est = eng.step(FrameContext(t + 1, measurements=z)).estimates["targets"]
        got = est["extracted"][:, [0, 2]]
        if t >= 5 and len(got):
            d = np.linalg.norm(got[:, None] - truth[t][None], axis=2).min(axis=1)
            err.extend(d[d < 15.0])
    x = eng.beliefs["targets"].x
    near = np.linalg.norm(x[:, [0, 2]] - truth[-1][0], axis=1) < 15.0  # the first walker
    clouds[reg], errors[reg] = x[near], np.array(err)
    distinct = len(np.unique(np.round(x[near], 6), axis=0))
    print(f"{'regularised' if reg else 'plain      '}: mean error {np.mean(err):.2f} "
          f"({len(err)} estimates); the first walker's cloud: {near.sum()} particles, "
          f"{distinct} distinct")

# %%
# 3. The first walker's particles at the last frame (position), plain and regularised.
fig, axes = plt.subplots(1, 2, figsize=(9, 4), sharex=True, sharey=True)
for ax, reg in zip(axes, (False, True), strict=True):
    c = clouds[reg]
    ax.scatter(c[:, 0], c[:, 2], s=8, alpha=0.5, label="particles")
    ax.plot(*truth[-1][0], "r+", ms=14, mew=2, label="truth")
    ax.set_title(f"{'regularised' if reg else 'plain'}: mean error "
                 f"{errors[reg].mean():.2f}")
    ax.set_xlabel("x")
axes[0].set_ylabel("y")
axes[0].legend(loc="upper right")
fig.tight_layout()
fig.savefig(out / "clouds.png", dpi=100)
print(f"wrote {out / 'clouds.png'}")
