"""How detection scores enter the (VB-)PHD, chosen leave one sequence out.

    .venv/bin/python benchmarks/choose_scores.py [--seeds 3] [--jobs 2] [--cache FILE]

A grid of score settings (:mod:`pgm.factors.scores`): ``off`` (score-blind) and the
online two-class mixture with temper ``γ ∈ {0.25, 0.5, 1}``, birth gate
``P(target | s) ≥ {0, 0.5}`` and the score density of a persisting target's detection
(``target``: the target class's, the literal marked model; ``all``: the marginal of all
detections, so that a tracked person's low-score detection is not written off), each
ungated one also with the shadow rule at IoU 0.3 and 0.4 (no births from a detection
that overlaps a higher-scored one, :func:`pgm.factors.scores.shadowed`), is run
with PHD and VB-PHD on the four shared MOT sequences (public detections, seeds
``0..K-1``), everything else at the ``pgm track`` defaults. For each held-out sequence
the setting with the best mean of ``(MOTA + IDF1) / 2`` over PHD and VB-PHD on the
other three is chosen and scored on the held-out one; the last row is the choice on all
four. A second criterion, the issue's goal as a margin (the worst over the training
sequences of VB-PHD's MOTA and IDF1 minus the larger of the PHD's and the best peer's),
is reported the same way. Runs are cached as JSON lines in ``--cache`` (default
``benchmarks/results/choose_scores.jsonl``), so an interrupted run resumes.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, print_table, single_thread  # noqa: E402

single_thread()

SEQUENCES = ("PETS09-S2L1", "TUD-Campus", "TUD-Stadtmitte", "MOT16-11")
MODELS = ("PHD", "VB-PHD")
#: MOTA and IDF1 of the best of SORT / ByteTrack / OC-SORT per sequence (each metric on
#: its own), from ``python benchmarks/mot_sequences.py`` (same detections and scorer)
BEST_PEER = {"PETS09-S2L1": (0.657, 0.513), "TUD-Campus": (0.432, 0.488),
             "TUD-Stadtmitte": (0.542, 0.503), "MOT16-11": (0.409, 0.566)}


def grid() -> list[dict]:
    out = [{"score_model": "off"}]
    for g, gate, pers in itertools.product((0.25, 0.5, 1.0), (0.0, 0.5), ("target", "all")):
        out.append({"score_model": "mixture", "score_temper": g,
                    "score_birth_min_prob": gate, "score_persisting": pers})
    # the shadow rule (no births from a detection overlapping a higher-scored one), with
    # the settings that have no birth gate of their own
    for cfg in [c for c in out if c.get("score_birth_min_prob", 0.0) == 0.0]:
        for iou in (0.3, 0.4):
            out.append({**cfg, "score_shadow_iou": iou})
    return out


def label(cfg: dict) -> str:
    shadow = (f" shadow={cfg['score_shadow_iou']:g}"
              if cfg.get("score_shadow_iou", 0.0) > 0 else "")
    if cfg["score_model"] == "off":
        return "off" + shadow
    return (f"γ={cfg['score_temper']:g} gate={cfg['score_birth_min_prob']:g} "
            f"persist={cfg['score_persisting']}" + shadow)


def run_one(task: tuple[str, str, int, dict]) -> dict:
    from mot_sequences import run

    from pgm.io.video import open_source
    from pgm.models import phd, vb_phd
    from pgm.observation.detections import make_detector

    seq, model, seed, cfg = task
    d = SHARED_DATA / seq
    module = phd if model == "PHD" else vb_phd
    r = run(d, module, make_detector("public", open_source(d)), seed=seed, overrides=cfg)
    m = r.metrics
    return {"seq": seq, "model": model, "seed": seed, "cfg": label(cfg),
            "mota": m["mota"], "idf1": m["idf1"], "hota": m["hota"]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--cache", type=Path,
                    default=Path(__file__).resolve().parent / "results" / "choose_scores.jsonl")
    args = ap.parse_args()
    seqs = [s for s in SEQUENCES if (SHARED_DATA / s).is_dir()]
    if len(seqs) < 2:
        sys.exit(f"need at least two of {SEQUENCES} under {SHARED_DATA}")
    args.cache.parent.mkdir(parents=True, exist_ok=True)
    done = {}
    if args.cache.exists():
        for line in args.cache.read_text().splitlines():
            r = json.loads(line)
            done[(r["seq"], r["model"], r["seed"], r["cfg"])] = r
    tasks = [(s, m, k, c) for c in grid() for s in seqs for m in MODELS
             for k in range(args.seeds) if (s, m, k, label(c)) not in done]
    print(f"{len(tasks)} runs to do, {len(done)} cached", file=sys.stderr, flush=True)
    with open(args.cache, "a") as fh, ProcessPoolExecutor(args.jobs) as pool:
        for r in pool.map(run_one, tasks):
            done[(r["seq"], r["model"], r["seed"], r["cfg"])] = r
            fh.write(json.dumps(r) + "\n")
            fh.flush()
    labels = [label(c) for c in grid()]

    def score(cfg: str, seq: str, model: str | None = None) -> tuple[float, float]:
        rs = [done[(seq, m, k, cfg)] for m in ([model] if model else MODELS)
              for k in range(args.seeds)]
        return float(np.mean([r["mota"] for r in rs])), float(np.mean([r["idf1"] for r in rs]))

    def objective(cfg: str, train: list[str]) -> float:
        return float(np.mean([sum(score(cfg, s)) / 2 for s in train]))

    def goal(cfg: str, train: list[str]) -> float:
        """The issue's goal as a margin: the worst, over the sequences and MOTA / IDF1,
        of VB-PHD minus the larger of the PHD and the best peer."""
        out = []
        for s in train:
            vb, ph = np.array(score(cfg, s, "VB-PHD")), np.array(score(cfg, s, "PHD"))
            out.append(min((vb - ph).min(), (vb - np.array(BEST_PEER[s])).min()))
        return float(min(out))

    for name, crit in (("mean (MOTA + IDF1) / 2", objective), ("goal margin", goal)):
        choose(name, crit, seqs, labels, score, args.seeds)
    full = [[c, *("{:.3f}/{:.3f}".format(*score(c, s, "VB-PHD")) for s in seqs),
             f"{objective(c, seqs):.4f}", f"{goal(c, seqs):+.3f}"] for c in labels]
    print_table(["setting", *seqs, "mean objective", "goal margin"], full,
                title="VB-PHD MOTA/IDF1 per setting (criteria over PHD and VB-PHD, all four)")


def choose(name, criterion, seqs, labels, score, seeds) -> None:
    """Leave one sequence out under ``criterion(cfg, training sequences)``."""
    rows = []
    for held in [*seqs, None]:
        train = [s for s in seqs if s != held]
        best = max(labels, key=lambda c: criterion(c, train))
        cells = []
        for s in ([held] if held else seqs):
            for m in MODELS:
                mota, idf1 = score(best, s, m)
                off = score("off", s, m)
                cells.append(f"{s} {m} {mota:.3f}/{idf1:.3f} (off {off[0]:.3f}/{off[1]:.3f})")
        rows.append([held or "(all four)", best, "; ".join(cells)])
    print_table(["held out", "chosen on the others", "held-out MOTA/IDF1 (score-blind)"], rows,
                title=f"criterion: {name}; leave one sequence out, mean of seeds 0-{seeds - 1}")


if __name__ == "__main__":
    main()
