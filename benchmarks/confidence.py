"""Is the single-object tracker's confidence calibrated? Reliability diagram and ECE,
leave-one-sequence-out.

The default single-object model (``pgm.models.single_object``) reports per frame the
probability that its box overlaps the truth by at least half: the log peak-to-sidelobe
ratio of its correlation filter's response map at the estimate (MOSSE's failure signal,
a ratio of the map to itself) and the log of the posterior's spread (particles' centre
standard deviation over the box size)
mapped through a logistic (:func:`pgm.core.readout.confidence`). This script

1. runs the model over the eight single-object sequences of ``../shared/data``
   (``--sequences``; frames annotated absent, UAV10-group3's, count as misses) and the
   ``--persons`` longest person tracks of
   PETS09-S2L1 (``--person-sequences``: also of TUD-Campus, TUD-Stadtmitte and MOT16-11)
   run as single-object tasks, one group per sequence (people crossing each other,
   occluders, a moving camera: where the tracker does fail — a calibration needs
   failures to learn from)
   with ``--seeds`` seeds and collects, at every annotated frame, the features
   (``--features``: the two the model ships, or the response over its running peak too)
   and the outcome (IoU ≥ 0.5);
2. for each group, fits the logistic on the others and scores the held-out one:
   how well it ranks hits above misses (AUROC, where the group has both), its
   reliability diagram, expected calibration error (ECE, 10 bins) and Brier score,
   against the shipped coefficients and against a constant (the other groups' hit rate, weighted
   as the fit is: what a tracker with no confidence signal can do);
3. prints the logistic fitted on all groups (what ``single_object.CONFIDENCE`` ships);
4. the **lost signal** (``pgm track --lost-below P``: a frame whose confidence is below
   ``P`` is reported as lost): for each threshold of ``--lost``, its precision (the share
   of flagged frames where the box overlaps the truth by less than half) and recall (the
   share of such frames flagged), with the held-out confidences and with the shipped
   ones, every video weighted equally.

The fit weights every group (video) equally (``--weighting videos``, the default): the
unit a calibration must transfer to is a video a user has not shown us, and with
per-frame weights the longest group (the six PETS people: 70 % of the frames)
decides the fit alone. The summary gives the held-out ECE per video (its mean: what a
user sees on their own video) with a coarse reliability diagram (five bins) per held-out
video, and the held-out predictions pooled twice: with every video weighted equally (a
frame of a video drawn at random: what a user can expect before running theirs) and
with every frame weighted equally.

    python benchmarks/confidence.py [--seeds 2] [--persons 6] [--person-sequences A,B]
                                    [--weighting videos|frames] [--lost 0.1,0.2,0.3,0.5]
                                    [--sequences all|first-four|A,B] [--features psr,spread]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, print_table, single_thread  # noqa: E402

single_thread()

from appearance_eval import DECLARED_FPS, FIRST_FOUR, SINGLE, sequences  # noqa: E402
from sklearn.linear_model import LogisticRegression  # noqa: E402
from sklearn.metrics import roc_auc_score  # noqa: E402

from pgm.app.runner import output_target  # noqa: E402
from pgm.core.frame import FrameContext  # noqa: E402
from pgm.core.readout import posterior_spread  # noqa: E402
from pgm.evaluation.calibration import lost_signal, reliability, video_weights  # noqa: E402
from pgm.evaluation.single_object import single_object_metrics  # noqa: E402
from pgm.inference import Engine  # noqa: E402
from pgm.models import single_object  # noqa: E402

#: MOT sequences whose longest ground-truth people are tracked as single objects, one
#: group per sequence: crowds, crossings and occluders, where the tracker does fail
PERSON_SEQUENCES = ("PETS09-S2L1", "TUD-Campus", "TUD-Stadtmitte", "MOT16-11")


#: the features a fit may use (``--features``): the log peak-to-sidelobe ratio, the log
#: posterior spread, the log response over the running peak
FEATURES = ("psr", "spread", "response")
#: the declaration's key of each feature's coefficient (the PSR's is ``slope``)
KEYS = {"psr": "slope", "spread": "spread_slope", "response": "response_slope"}


def collect(tasks, seeds: int, fps: float | None = None):
    """``(features (K, 3), outcome, shipped confidence)`` at the annotated frames of every
    task, all seeds: the frames with a box (outcome: IoU >= 0.5) and those annotated
    absent (outcome: a miss, whatever the box: nothing is there to overlap); ``fps``: the
    video's declared frame rate (``single_object.Params.fps``)."""
    feats, hits, shipped = [], [], []
    for seed in range(seeds):
        for frames, gt, init, _ in tasks:
            graph = single_object.build_graph(single_object.Params(init_box=tuple(init),
                                                                   fps=fps))
            engine = Engine(graph, np.random.default_rng(seed))
            factor = engine.graph.factors[engine.graph.meta["confidence"]["factor"]]
            numbers, boxes, f_seq, c_seq = [], [], [], []
            for number, img in frames:
                record = engine.step(FrameContext(number, img))
                box, score = output_target(engine.graph, record)
                numbers.append(number)
                boxes.append(box)
                f_seq.append([factor.confidence_feature,
                              np.log(max(posterior_spread(record, "object"), 1e-6)),
                              factor.confidence_response])
                c_seq.append(score)
            m = single_object_metrics(gt, np.array(numbers), np.array(boxes))
            at = {n: k for k, n in enumerate(numbers)}
            absent = [int(f) for f in gt.absent if int(f) in at]
            idx = [at[f] for f in m["frames"]] + [at[f] for f in absent]
            feats.append(np.array(f_seq)[idx])
            shipped.append(np.array(c_seq)[idx])
            hits.append(np.concatenate([np.array(m["ious"]) >= 0.5,
                                        np.zeros(len(absent), dtype=bool)]))
    return np.concatenate(feats), np.concatenate(hits), np.concatenate(shipped)


def fit(x: np.ndarray, y: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """Logistic ``P(hit | x) = σ(a + x · b)`` on the chosen features ``x`` (scikit-learn's
    default mild L2 penalty, C = 1: a sequence where every frame is a hit has no finite
    optimum), frames weighted by ``weights`` (all 1 when None): ``[a, *b]``."""
    lr = LogisticRegression(C=1.0).fit(x, y.astype(int), sample_weight=weights)
    return np.concatenate([lr.intercept_, lr.coef_[0]]).astype(float)


def sigmoid(z):
    return 0.5 * (1.0 + np.tanh(0.5 * z))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--persons", type=int, default=6,
                    help="person tracks per MOT sequence, one group each (0: none)")
    ap.add_argument("--person-sequences", default="PETS09-S2L1",
                    help="comma-separated MOT sequences whose people are groups (default "
                         "PETS09-S2L1, what the shipped fit used; all four: "
                         + ",".join(PERSON_SEQUENCES) + ")")
    ap.add_argument("--weighting", choices=("videos", "frames"), default="videos",
                    help="fit with every group weighted equally (default) or every frame")
    ap.add_argument("--lost", default="0.1,0.2,0.3,0.5",
                    help="thresholds of the lost signal's table (comma-separated)")
    ap.add_argument("--features", default="psr,spread",
                    help="comma-separated features of the fit, of " + ",".join(FEATURES)
                         + " (default psr,spread: the shipped fit's)")
    ap.add_argument("--sequences", default="all",
                    help="'all' (the eight single-object sequences: the shipped fit, the "
                         "default), 'first-four' (FaceOcc1, Crossing, David, Tiger1: the fit "
                         "shipped before the eight) or a comma-separated list")
    args = ap.parse_args()
    use = [FEATURES.index(f.strip()) for f in args.features.split(",")]
    if not use or use[0] != 0 or len(set(use)) != len(use):
        sys.exit(f"--features: psr first, then any of {FEATURES[1:]}, each once")
    names = {"first-four": FIRST_FOUR, "all": SINGLE}.get(
        args.sequences, tuple(s.strip() for s in args.sequences.split(",")))
    groups = sequences(args.persons, names=names,
                       persons_from=[s for s in args.person_sequences.split(",") if s])
    data = {n: (lambda d: (d[0][:, use], d[1], d[2]))(
        collect(tasks, args.seeds, DECLARED_FPS.get(n))) for n, tasks in groups.items()}
    if len(data) < 2:
        sys.exit(f"need at least two of {names} under {SHARED_DATA}")

    def training(names):
        xs = np.concatenate([data[n][0] for n in names])
        ys = np.concatenate([data[n][1] for n in names])
        labels = np.concatenate([[n] * len(data[n][1]) for n in names])
        return xs, ys, (video_weights(labels) if args.weighting == "videos" else None)

    rows, pooled_c, pooled_y, pooled_const, eces, per_video = [], [], [], [], [], {}
    pooled_shipped = []
    for held, (x, y, shipped) in data.items():
        xs, ys, ws = training([n for n in data if n != held])
        coef = fit(xs, ys, ws)
        c = sigmoid(coef[0] + x @ coef[1:])
        r = reliability(c, y)
        r_ship = reliability(shipped, y)
        r_const = reliability(np.full(len(y), np.average(ys, weights=ws)), y)
        eces.append(r["ece"])
        per_video[held] = {round(b["lo"], 1): f"{b['hit_rate']:.2f} ({b['n']})"
                           for b in reliability(c, y, n_bins=5)["bins"]}
        pooled_c.append(c)
        pooled_y.append(y)
        pooled_shipped.append(shipped)
        pooled_const.append(np.full(len(y), np.average(ys, weights=ws)))
        auroc = f"{roc_auc_score(y, c):.2f}" if 0 < y.mean() < 1 else "-"
        rows.append([held, len(y), f"{y.mean():.3f}", f"{c.mean():.3f}", auroc, f"{r['ece']:.3f}",
                     f"{r['brier']:.3f}", f"{r_const['ece']:.3f}", f"{r_const['brier']:.3f}",
                     f"{r_ship['ece']:.3f}", " / ".join(f"{v:.2f}" for v in coef)])
    print_table(["held-out group", "frames", "hit rate", "mean conf", "AUROC", "ECE", "Brier",
                 "ECE const", "Brier const", "ECE shipped",
                 "fit on others: intercept / " + " / ".join(args.features.split(","))], rows,
                title=f"Leave-one-sequence-out calibration ({args.seeds} seeds; outcome: "
                      f"IoU >= 0.5 at annotated frames; fit weighting: {args.weighting})")
    print(f"\nmean held-out ECE per video: {np.mean(eces):.3f} over {len(eces)} groups")
    edges = np.linspace(0.0, 1.0, 6)
    print_table(["held-out group"] + [f"{lo:.1f}-{hi:.1f}"
                                      for lo, hi in zip(edges[:-1], edges[1:], strict=True)],
                [[held] + [per_bin.get(round(lo, 1), "-") for lo in edges[:-1]]
                 for held, per_bin in per_video.items()],
                title="Reliability per video, held out: hit rate (frames) in each confidence "
                      "bin")
    c, y = np.concatenate(pooled_c), np.concatenate(pooled_y)
    video_of = np.concatenate([[n] * len(data[n][1]) for n in data])  # the order of pooled_*
    for weights, how in ((video_weights(video_of), "every video weighted equally (a frame of "
                                                   "a video drawn at random)"),
                         (None, "every frame weighted equally")):
        r = reliability(c, y, weights=weights)
        r_const = reliability(np.concatenate(pooled_const), y, weights=weights)
        print_table(["confidence bin", "frames", "share", "mean confidence", "hit rate", "gap"],
                    [[f"{b['lo']:.1f}-{b['hi']:.1f}", b["n"], f"{b['share']:.3f}",
                      f"{b['confidence']:.3f}", f"{b['hit_rate']:.3f}",
                      f"{b['hit_rate'] - b['confidence']:+.3f}"] for b in r["bins"]],
                    title=f"Reliability diagram, held-out predictions pooled, {how}: "
                          f"ECE {r['ece']:.3f}, Brier {r['brier']:.3f} (constant: ECE "
                          f"{r_const['ece']:.3f}, Brier {r_const['brier']:.3f})")
    lost_rows = []
    vw = video_weights(video_of)
    shipped_all = np.concatenate(pooled_shipped)
    for t in (float(v) for v in args.lost.split(",") if v):
        held_out = lost_signal(c, y, t, weights=vw)
        ship = lost_signal(shipped_all, y, t, weights=vw)
        fmt = lambda v: "-" if v is None else f"{v:.3f}"  # noqa: E731
        lost_rows.append([f"{t:.2f}", held_out["flagged"], held_out["lost"],
                          fmt(held_out["precision"]), fmt(held_out["recall"]),
                          ship["flagged"], fmt(ship["precision"]), fmt(ship["recall"])])
    print_table(["lost below", "flagged", "lost frames", "precision", "recall",
                 "flagged (shipped)", "precision (shipped)", "recall (shipped)"], lost_rows,
                title="The lost signal (confidence below the threshold) against the frames "
                      "where the box overlaps the truth by less than half; held-out and "
                      "shipped confidences, every video weighted equally")
    xs, ys, ws = training(list(data))
    coef = fit(xs, ys, ws)
    r = reliability(sigmoid(coef[0] + xs @ coef[1:]), ys, weights=video_weights(video_of))
    got = ", ".join([f"intercept {coef[0]:.3f}"] + [f"{KEYS[FEATURES[i]]} {v:.3f}"
                                                   for i, v in zip(use, coef[1:], strict=True)])
    print(f"\nfitted on all {len(data)} groups: {got} (shipped: {single_object.CONFIDENCE}); "
          f"its ECE on them, every video weighted equally: {r['ece']:.3f}")
    print(f"held-out AUROC, mean over the groups with hits and misses: "
          f"{np.mean([float(r[4]) for r in rows if r[4] != '-']):.3f}")


if __name__ == "__main__":
    main()
