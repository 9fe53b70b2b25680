"""Stone Soup's SMC-PHD filter on the bench's multi-target scenario, run in the peers' venv.

    .venv-peers/bin/python benchmarks/peers/phd_peers.py --scenario SCENARIO.json
        --out RESULT.json [--particles 1000,5000,20000] [--seeds 3]

Stone Soup 1.9.1 (``stonesoup``): ``SMCPHDPredictor`` (the ``expansion`` birth scheme: a
tenth of the particle count born each step from the scenario's birth intensity, the four
Gaussians of weight 0.03 each) and ``SMCPHDUpdater`` (systematic resampling back to N
particles), the scenario's constant-velocity model, position measurements, p_D, clutter
intensity and survival. Stone Soup's SMC-PHD extracts no states: as for the bench README's
figures, each measurement whose hypothesis carries a weight above 0.5 gives the weighted
mean of the particles for it (per-measurement extraction, Ristic, Clark & Vo 2010), read
from the weights the updater computed (no second pass).

``RESULT.json``: ``{"N": {"seed": {"ms": filter ms per step (predict + update, extraction
excluded), "extract_ms": ..., "estimates": [[[x, y], ...] per step]}}}``; OSPA is computed
by the toolkit's benchmark (``benchmarks/speed.py``) with its own metric.
"""

from __future__ import annotations

import argparse
import datetime
import json
import sys
import time

import numpy as np
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.transition.linear import (
    CombinedLinearGaussianTransitionModel,
    ConstantVelocity,
)
from stonesoup.predictor.particle import SMCPHDPredictor
from stonesoup.resampler.particle import SystematicResampler
from stonesoup.sampler.particle import ParticleSampler
from stonesoup.types.array import StateVectors
from stonesoup.types.detection import Detection, MissedDetection
from stonesoup.types.hypothesis import SingleHypothesis
from stonesoup.types.multihypothesis import MultipleHypothesis
from stonesoup.types.state import ParticleState
from stonesoup.updater.particle import SMCPHDUpdater

#: the fraction of the particle count born each step (Stone Soup's ``birth_probability``)
BIRTH_FRACTION = 0.1


class _KeepingUpdater(SMCPHDUpdater):
    """Stone Soup's SMC-PHD updater keeping the per-hypothesis log-weights it computes (for
    the extraction, without a second pass)."""

    def get_log_weights_per_hypothesis(self, hypotheses):
        self.last = super().get_log_weights_per_hypothesis(hypotheses)
        return self.last


def run(scenario: dict, n: int, seed: int) -> dict:
    p = scenario["params"]
    rng = np.random.default_rng(seed)
    np.random.seed(seed)  # noqa: NPY002 (Stone Soup's resampler draws from the global one)
    means = np.array(p["birth_means"], dtype=float)
    std = np.array(p["birth_std"], dtype=float)
    dt = float(p["dt"])
    area = float(np.prod(np.diff(np.array(p["region"], dtype=float), axis=1)))
    birth_mass = float(p["birth_weight"]) * len(means)

    def birth(num_samples):
        comp = rng.integers(0, len(means), int(num_samples))
        return means[comp] + rng.standard_normal((int(num_samples), 4)) * std

    transition = CombinedLinearGaussianTransitionModel(
        [ConstantVelocity(float(p["q"])), ConstantVelocity(float(p["q"]))])
    measurement = LinearGaussian(ndim_state=4, mapping=(0, 2),
                                 noise_covar=np.eye(2) * float(p["sigma_z"]) ** 2)
    sampler = ParticleSampler(distribution_func=birth, params={"num_samples": n}, ndim_state=4)
    predictor = SMCPHDPredictor(transition_model=transition,
                                death_probability=-np.log(float(p["p_survive"])) / dt,
                                birth_probability=BIRTH_FRACTION, birth_rate=birth_mass,
                                birth_sampler=sampler)
    updater = _KeepingUpdater(measurement_model=measurement, resampler=SystematicResampler(),
                              prob_detect=float(p["p_detect"]),
                              clutter_intensity=float(p["clutter_rate"]) / area, num_samples=n)
    t0 = datetime.datetime(2024, 1, 1)
    state = ParticleState(StateVectors(birth(n).T), log_weight=np.full(n, np.log(birth_mass / n)),
                          timestamp=t0)
    filter_s = extract_s = 0.0
    estimates = []
    for k, z in enumerate(scenario["measurements"]):
        when = t0 + datetime.timedelta(seconds=dt * (k + 1))
        dets = [Detection(np.array(m, dtype=float).reshape(2, 1), timestamp=when,
                          measurement_model=measurement) for m in z]
        a = time.perf_counter()
        prediction = predictor.predict(state, timestamp=when, random_state=rng)
        hyps = MultipleHypothesis([SingleHypothesis(prediction, MissedDetection(timestamp=when))]
                                  + [SingleHypothesis(prediction, d) for d in dets])
        state = updater.update(hyps)
        b = time.perf_counter()
        w = np.exp(updater.last[:, 1:])                      # (particles, measurements)
        mass = w.sum(axis=0)
        keep = np.flatnonzero(mass > 0.5)
        x = np.asarray(prediction.state_vector, dtype=float)  # (4, particles)
        est = (x[[0, 2]] @ w[:, keep] / mass[keep]).T if len(keep) else np.zeros((0, 2))
        extract_s += time.perf_counter() - b
        filter_s += b - a
        estimates.append(est.tolist())
    steps = len(scenario["measurements"])
    return {"ms": 1e3 * filter_s / steps, "extract_ms": 1e3 * extract_s / steps,
            "estimates": estimates}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--particles", default="1000,5000,20000")
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args(argv)
    with open(args.scenario) as f:
        scenario = json.load(f)
    out = {}
    for n in (int(v) for v in args.particles.split(",")):
        out[str(n)] = {str(s): run(scenario, n, s) for s in range(args.seeds)}
    with open(args.out, "w") as f:
        json.dump(out, f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
