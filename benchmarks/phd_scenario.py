"""PHD and VB-PHD on the reference multi-target scenario: ms per step and OSPA.

    python benchmarks/phd_scenario.py --scenario ../shared/bench/phd_scenario_seed2024.json

The scenario (bench/README.md): 2-D nearly-constant-velocity targets, state
``[px, vx, py, vy]``, 100 steps, σ = 10 m, p_D = 0.9, 10 clutter per scan, true count
3 → 6 → 3. The filters get the measurements only (never the origin labels).
Births here are measurement-driven (Ristic, Clark, Vo & Vo 2012; references in
:mod:`pgm.models.phd`), not the scenario's Gaussian birth intensity. Budgets are set so
that the mean *total* particle count per step (persistent after resampling + newborn) is
close to the Stone Soup counts; the table prints the count actually used. OSPA on
position (c=50, p=1 and c=100, p=2), mean over the 100 steps, for the raw
per-measurement extraction and for the track layer's confirmed tracks; mean over seeds.
Stone Soup SMC-PHD figures from bench/README.md.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import print_table, single_thread  # noqa: E402

single_thread()

from pgm.core.frame import FrameContext  # noqa: E402
from pgm.evaluation.set_distances import ospa  # noqa: E402
from pgm.inference import Engine  # noqa: E402
from pgm.models import phd, vb_phd  # noqa: E402

STONE_SOUP = {1000: (9.1, 19.7, 46.5, 1.04), 5000: (24.5, 13.3, 30.4, 0.53),
              20000: (76.3, 12.75, 29.6, 0.51)}
#: total particles -> (particles per target, min particles, newborn per measurement)
BUDGETS = {1000: (195, 195, 8), 5000: (965, 965, 40), 20000: (3860, 3860, 160)}


def budget(total: int) -> tuple[int, int, int]:
    """The split of ``total`` particles: :data:`BUDGETS`' where it has one, otherwise
    theirs in proportion (per target and minimum 0.193 ``total``, newborns per
    measurement 0.008 ``total``, at least one)."""
    if total in BUDGETS:
        return BUDGETS[total]
    per_target = max(1, round(0.193 * total))
    return per_target, per_target, max(1, round(0.008 * total))


def load(path: Path):
    d = json.loads(path.read_text())
    p = d["params"]
    steps = p["n_steps"]
    truth = [[] for _ in range(steps)]
    for tr in d["truth"]:
        for k, s in enumerate(tr["states"]):
            truth[tr["birth"] + k].append([s[0], s[2]])
    truth = [np.array(t).reshape(-1, 2) for t in truth]
    meas = [np.array(z, dtype=float).reshape(-1, 2) for z in d["measurements"]]
    return p, truth, meas


def run(params_cls, builder, p, meas, truth, total, seed, regularise=False):
    per_target, n_min, n_birth = budget(total)
    area = float(np.prod(np.diff(np.array(p["region"]), axis=1)))
    params = params_cls(area=area, sigma=p["sigma_z"], q=p["q"], dt=p["dt"],
                        p_detect=p["p_detect"], p_survive=p["p_survive"],
                        clutter_rate=p["clutter_rate"], birth_rate=0.1, n_birth=n_birth,
                        birth_velocity_std=10.0, particles_per_target=per_target,
                        min_particles=n_min, max_coast=2, regularise=regularise)
    eng = Engine(builder(params), np.random.default_rng(seed))
    secs, counts = 0.0, []
    o_raw, o_trk, o_raw2, card, sig = [], [], [], [], []
    for k, z in enumerate(meas):
        t0 = time.perf_counter()
        rec = eng.step(FrameContext(k + 1, measurements=z))
        secs += time.perf_counter() - t0
        b = eng.beliefs["targets"]
        counts.append(b.num + (b.newborn.num if b.newborn is not None else 0))
        est = rec.estimates["targets"]
        raw = est["extracted"][:, [0, 2]]
        trk = est["states"][:, [0, 2]]
        o_raw.append(ospa(truth[k], raw, 50, 1))
        o_raw2.append(ospa(truth[k], raw, 100, 2))
        o_trk.append((ospa(truth[k], trk, 50, 1), ospa(truth[k], trk, 100, 2)))
        card.append(abs(len(truth[k]) - est["expected_count"]))
        if "noise" in rec.estimates:
            sig.append(np.sqrt(rec.estimates["noise"]).mean())
    o_trk = np.array(o_trk)
    return {"ms": 1e3 * secs / len(meas), "particles": float(np.mean(counts)),
            "ospa_raw": float(np.mean(o_raw)), "ospa_raw2": float(np.mean(o_raw2)),
            "ospa_trk": float(o_trk[:, 0].mean()), "ospa_trk2": float(o_trk[:, 1].mean()),
            "card": float(np.mean(card)), "sigma": float(np.mean(sig)) if sig else float("nan")}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    ap.add_argument("--scenario", default=str(Path(__file__).resolve().parents[2] / "shared" /
                                              "bench" / "phd_scenario_seed2024.json"))
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--particles", default="1000,5000,20000")
    args = ap.parse_args()
    path = Path(args.scenario)
    if not path.is_file():
        sys.exit(f"scenario not found: {path}")
    p, truth, meas = load(path)
    rows = []
    for total in (int(t) for t in args.particles.split(",")):
        ss = STONE_SOUP.get(total)
        for label, pc, builder in (("PHD", phd.Params, phd.build_graph),
                                   ("VB-PHD", vb_phd.Params, vb_phd.build_graph)):
            res = [run(pc, builder, p, meas, truth, total, s) for s in range(args.seeds)]
            m = {k: float(np.mean([r[k] for r in res])) for k in res[0]}
            ms_median = float(np.median([r["ms"] for r in res]))
            rows.append([label, total, round(m["particles"]), ms_median, m["ospa_raw"],
                         m["ospa_raw2"], m["ospa_trk"], m["ospa_trk2"], m["card"],
                         m["sigma"], ss[0] if ss else "-",
                         f"{ss[0] / ms_median:.1f}x" if ss else "-",
                         ss[1] if ss else "-", ss[2] if ss else "-"])
    print_table(["filter", "N (nominal)", "N used", "ms/step", "OSPA(50,1) raw",
                 "OSPA(100,2) raw", "OSPA(50,1) tracks", "OSPA(100,2) tracks",
                 "|card err|", "mean σ̂", "Stone Soup ms", "speed-up", "SS OSPA(50,1)",
                 "SS OSPA(100,2)"], rows,
                title=f"{path.name}: {len(meas)} steps, {args.seeds} seeds (ms: median; "
                      f"OSPA: mean); σ_true = {p['sigma_z']}")


if __name__ == "__main__":
    main()
