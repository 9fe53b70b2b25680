"""Per-target trackers (plates) on the shared MOT sequences: multi-pf, gpdm and baselines.

Issue 13, item 6. On each shared MOT sequence, from its public detections, every run
scored with the toolkit's MOT protocol (``pgm.evaluation.mot.evaluate_mot``):

* ``--choose``: the ``multi-pf`` defaults chosen **leave one sequence out** over a small
  grid (detection strength × mutual exclusion × frames a target coasts): for each held-out
  sequence the setting with the best mean (MOTA + IDF1)/2 on the *other* sequences is
  scored on it; the table prints every fold's pick and its held-out score;
* ``multi-pf`` (one colour particle filter per person) and ``multi-pf --parts 2`` (a
  two-band part graph per person);
* ``gpdm`` with a GPDM trained on the *other* sequences' ground-truth trajectories
  (``pgm.dynamics.gpdm.learn_gpdm``, default settings), next to the same tracker with
  constant velocity (``cv``) and constant velocity averaged over three frames (``cv3``),
  on all frames and with frames withheld (``--drop`` spec, default ``30/10``: the last
  10 of every 30 frames, predicted through and scored);
* VB-PHD (the toolkit's default multi-target model) and, when the peer virtualenv exists
  (``bash benchmarks/peers/setup_env.sh``), SORT / ByteTrack / OC-SORT on the same
  detections.

Columns: MOTA, IDF1, HOTA, Wang et al.'s (2008) error rate (frames with a miss-tracked target),
ID switches, frames per second of inference. One-step and 10-frame-gap prediction
errors of the motion models are ``benchmarks/gpdm_prediction.py``'s.

    .venv/bin/python benchmarks/plate_trackers.py [--choose] [--seeds 1] [--sequences A,B]
"""

from __future__ import annotations

import argparse
import itertools
import sys
import tempfile
from pathlib import Path

import numpy as np
from _common import SHARED_DATA, print_table, shared_sequences, single_thread

SEQUENCES = ("PETS09-S2L1", "TUD-Campus", "TUD-Stadtmitte", "MOT16-11")
GRID = {"detection_strength": (200.0, 2000.0, 20000.0), "exclusion": (0.0, 10.0),
        "max_coast": (0, 2, 5)}


def _params(module, fps: float, **kw):
    from pgm.core.plate import Lifecycle

    coast = kw.pop("max_coast", None)
    if coast is not None:
        kw["lifecycle"] = Lifecycle(max_coast=coast, max_lost=max(30, coast))
    return module.Params(fps=fps, **kw)


def run(seq: str, graph, seed: int = 0, drop: str | None = None) -> dict:
    from pgm.app.cli import parse_drop_frames
    from pgm.app.runner import track_multi
    from pgm.io.annotations import load_mot
    from pgm.io.video import open_source
    from pgm.observation.detections import make_detector

    src = open_source(SHARED_DATA / seq)
    det = make_detector("public", src)
    r = track_multi(src, graph, det, rng=np.random.default_rng(seed),
                    gt=load_mot(src.gt_path, kind="gt"), write_video=False, progress=False,
                    drop_frames=parse_drop_frames(drop, len(src)))
    return {**r.metrics, "fps": r.fps}


def fps_of(seq: str) -> float:
    from pgm.io.video import open_source

    return float(open_source(SHARED_DATA / seq).fps)


def choose(seqs: list[str], seed: int) -> list[list]:
    from pgm.models import multi_pf

    keys = list(GRID)
    settings = [dict(zip(keys, vals, strict=True)) for vals in itertools.product(*GRID.values())]
    score: dict[tuple, dict[str, dict]] = {}
    for s in settings:
        key = tuple(s.values())
        score[key] = {}
        for q in seqs:
            m = run(q, multi_pf.build_graph(_params(multi_pf, fps_of(q), **s)), seed)
            score[key][q] = m
            print(f"  grid {s} {q}: MOTA {m['mota']:.3f} IDF1 {m['idf1']:.3f}", flush=True)

    def obj(key, qs):
        return float(np.mean([(score[key][q]["mota"] + score[key][q]["idf1"]) / 2
                              for q in qs]))

    rows = []
    for held in seqs + ["(all)"]:
        train = [q for q in seqs if q != held]
        best = max(score, key=lambda k: obj(k, train))
        label = ", ".join(f"{k}={v}" for k, v in zip(keys, best, strict=True))
        if held == "(all)":
            rows.append(["(chosen on all)", label, "-", "-", f"{obj(best, seqs):.3f}"])
        else:
            m = score[best][held]
            rows.append([held, label, m["mota"], m["idf1"], f"{obj(best, train):.3f}"])
    return rows


def train_gpdm(train: list[str], path: Path) -> Path:
    from pgm.dynamics.gpdm import GPDMSettings, gt_trajectories, learn_gpdm
    from pgm.io.annotations import load_mot

    trajs = []
    for q in train:
        trajs += gt_trajectories(load_mot(SHARED_DATA / q / "gt" / "gt.txt", kind="gt"),
                                 fps=fps_of(q), min_length=10, source=q)
    model = learn_gpdm(trajs, GPDMSettings(max_points=600), rng=np.random.default_rng(0))
    model.save(path)
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--choose", action="store_true",
                    help="choose multi-pf's defaults leave one sequence out over the grid")
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--sequences", default=None, help="comma-separated subset")
    ap.add_argument("--drop", default="30/10", help="--drop-frames spec of the gap rows")
    ap.add_argument("--no-gpdm", action="store_true", help="skip the gpdm rows")
    args = ap.parse_args()
    single_thread()
    from pgm.models import gpdm, multi_pf, vb_phd

    seqs = shared_sequences(args.sequences, SEQUENCES)
    if args.choose:
        print_table(["held out", "chosen on the others", "MOTA", "IDF1", "train obj"],
                    choose(seqs, 0), title="multi-pf defaults, leave one sequence out "
                                           f"(grid {GRID})")
    tmp = Path(tempfile.mkdtemp())
    rows = []
    for q in seqs:
        fps = fps_of(q)
        runs = [("multi-pf", multi_pf.build_graph(_params(multi_pf, fps)), None),
                ("multi-pf --parts 2", multi_pf.build_graph(_params(multi_pf, fps, n_parts=2)),
                 None)]
        if not args.no_gpdm:
            model = train_gpdm([s for s in SEQUENCES if s != q and (SHARED_DATA / s).is_dir()],
                               tmp / f"gpdm-without-{q}.npz")
            for motion in ("gpdm", "cv", "cv3"):
                kw = {"model": str(model)} if motion == "gpdm" else {}
                g = gpdm.build_graph(_params(gpdm, fps, motion=motion, **kw))
                runs += [(f"gpdm --motion {motion}", g, None),
                         (f"gpdm --motion {motion} (drop {args.drop})", g, args.drop)]
        for name, graph, drop in runs:
            ms = [run(q, graph, seed, drop) for seed in range(args.seeds)]

            def mean(k, ms=ms):
                vals = [m[k] for m in ms if m.get(k) is not None]
                return float(np.mean(vals)) if vals else None

            rows.append([q, name, mean("mota"), mean("idf1"), mean("hota"), mean("error_rate"),
                         mean("id_switches"), mean("fps")])
            print(f"  {q} {name}: MOTA {rows[-1][2]:.3f} IDF1 {rows[-1][3]:.3f}", flush=True)
        rows.append([q, "vb-phd (default)", *_vb_phd(q, vb_phd, args.seeds)])
        rows += _peers(q)
    print_table(["sequence", "tracker", "MOTA", "IDF1", "HOTA", "error rate", "IDSW", "fps"],
                rows, title=f"per-target trackers on public detections ({args.seeds} seed(s))")


def _vb_phd(q: str, module, seeds: int) -> list:
    from pgm.app.runner import track_multi
    from pgm.io.annotations import load_mot
    from pgm.io.video import open_source
    from pgm.models.phd import video_params
    from pgm.observation.detections import make_detector

    ms = []
    for seed in range(seeds):
        src = open_source(SHARED_DATA / q)
        det = make_detector("public", src)
        w, h = src.size
        params = video_params(module.Params, w, h, src.fps,
                              typical_height=float(np.median(det.table.boxes[:, 3])))
        r = track_multi(src, module.build_graph(params), det, rng=np.random.default_rng(seed),
                        gt=load_mot(src.gt_path, kind="gt"), write_video=False, progress=False)
        ms.append({**r.metrics, "fps": r.fps})
    return [float(np.mean([m[k] for m in ms])) for k in
            ("mota", "idf1", "hota", "error_rate", "id_switches", "fps")]


def _peers(q: str) -> list[list]:
    from _peers import SETUP_HINT, peer_python, run_mot_peers

    from pgm.evaluation.mot import evaluate_mot
    from pgm.io.annotations import load_mot
    from pgm.io.video import open_source

    if peer_python() is None:
        print(f"{q}: {SETUP_HINT}; peer rows skipped", file=sys.stderr)
        return []
    src = open_source(SHARED_DATA / q)
    last = len(src)
    gt = load_mot(src.gt_path, kind="gt").until(last)
    rows = []
    for name, r in run_mot_peers(SHARED_DATA / q, last_frame=last).items():
        if "error" in r:
            print(f"{q} {name}: {r['error']}", file=sys.stderr)
            continue
        m = evaluate_mot(gt, r["table"].until(last), num_frames=last)
        rows.append([q, name, m["mota"], m["idf1"], m["hota"], m["error_rate"],
                     m["id_switches"], r["fps"]])
    return rows


if __name__ == "__main__":
    main()
