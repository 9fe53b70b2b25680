"""GPDM box-motion prediction against constant velocity, leave one sequence out.

For each shared MOT sequence (PETS09-S2L1 7 fps, TUD-Campus 25 fps, TUD-Stadtmitte 25
fps, MOT16-11 30 fps — a *moving camera*, so its image-plane motion mixes the people's
and the camera's), a GPDM (:mod:`pgm.dynamics.gpdm`, default settings unless flags
change them) is trained on the ground-truth trajectories of the *other* sequences and
scored on the held-out one's: from every box with at least 4 boxes of history and 10
frames of future, predict the box 1 frame ahead and 10 frames ahead (a gap of 9
missing frames). Same frames for every method:

* ``cv``: constant velocity of ``(cx, cy, w, h)`` from the last difference;
* ``cv3``: constant velocity averaged over the last three differences;
* ``gpdm``: mean of 20 sampled futures (:func:`~pgm.dynamics.gpdm.predict`);
* ``gpdm-mean``: the mean latent path (``z ← μ_X(z)``).

Errors: centre distance in pixels, and in box heights (divided by the true height).
Also the training time and the time per prediction (both horizons from one call).

    .venv/bin/python benchmarks/gpdm_prediction.py [--mirror] [--max-points 600]
"""

from __future__ import annotations

import argparse
import configparser
import time

import numpy as np
from _common import SHARED_DATA, print_table, single_thread

SEQUENCES = ("PETS09-S2L1", "TUD-Campus", "TUD-Stadtmitte", "MOT16-11")
HISTORY, GAP, PARTICLES = 4, 10, 20


def load(name: str):
    from pgm.dynamics.gpdm import gt_trajectories
    from pgm.io.annotations import load_mot

    folder = SHARED_DATA / name
    ini = configparser.ConfigParser()
    ini.read(folder / "seqinfo.ini")
    fps = float(ini["Sequence"]["frameRate"])
    table = load_mot(folder / "gt" / "gt.txt", kind="gt")
    return gt_trajectories(table, fps=fps, min_length=10, source=name), fps


def evaluate(model, trajs, fps, rng):
    from pgm.dynamics.gpdm import predict, predict_constant_velocity

    errs = {m: {1: [], GAP: []} for m in ("cv", "cv3", "gpdm", "gpdm-mean")}
    secs, calls = 0.0, 0
    for tr in trajs:
        b = tr.boxes
        for t in range(HISTORY - 1, len(b) - GAP):
            hist = b[t - HISTORY + 1: t + 1]
            preds = {
                "cv": predict_constant_velocity(hist, GAP, rng, fps=fps, average=1)[0],
                "cv3": predict_constant_velocity(hist, GAP, rng, fps=fps, average=3)[0],
            }
            t0 = time.perf_counter()
            sampled = predict(model, hist, GAP, rng, PARTICLES, fps=fps)
            secs += time.perf_counter() - t0
            calls += 1
            preds["gpdm"] = sampled.mean(0)
            preds["gpdm-mean"] = predict(model, hist, GAP, rng, 1, fps=fps, noise=False)[0]
            for m, p in preds.items():
                for k in (1, GAP):
                    truth = b[t + k]
                    e = float(np.hypot(*(p[k - 1, :2] - truth[:2])))
                    errs[m][k].append((e, e / truth[3]))
    return errs, 1e3 * secs / max(calls, 1), calls


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mirror", action="store_true", help="mirror the training set")
    ap.add_argument("--max-points", type=int, default=600)
    ap.add_argument("--max-iter", type=int, default=200)
    args = ap.parse_args()
    single_thread()
    from pgm.dynamics.gpdm import GPDMSettings, learn_gpdm

    data = {name: load(name) for name in SEQUENCES}
    settings = GPDMSettings(mirror=args.mirror, max_points=args.max_points,
                            max_iter=args.max_iter)
    rows = []
    for held in SEQUENCES:
        train = [t for name in SEQUENCES if name != held for t in data[name][0]]
        rng = np.random.default_rng(0)
        t0 = time.perf_counter()
        model = learn_gpdm(train, settings, rng)
        train_s = time.perf_counter() - t0
        errs, ms, calls = evaluate(model, data[held][0], data[held][1], rng)
        for m, by_k in errs.items():
            e1, e10 = np.array(by_k[1]), np.array(by_k[GAP])
            rows.append([held + (" (moving cam)" if held == "MOT16-11" else ""), m, calls,
                         float(e1[:, 0].mean()), float(e1[:, 1].mean()),
                         float(e10[:, 0].mean()), float(e10[:, 1].mean()),
                         f"{train_s:.1f}" if m == "gpdm" else "",
                         f"{ms:.1f}" if m == "gpdm" else "",
                         f"{model.info['iterations']}{'' if model.info['converged'] else '*'}"
                         if m == "gpdm" else ""])
    print_table(["held out", "method", "n", "1-step px", "1-step h", f"{GAP}-step px",
                 f"{GAP}-step h", "train s", "ms/pred", "iters"], rows,
                title=f"GPDM vs constant velocity, leave one sequence out "
                      f"(settings: {settings.to_dict()}; * = hit max_iter)")


if __name__ == "__main__":
    main()
