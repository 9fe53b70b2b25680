"""Single-object accuracy and speed: the ablation table, the peers, and the
leave-one-sequence-out choice of the default.

Every row is a model config of the one engine (a one-node graph unless it says
"3 nodes"), run over whole sequences with ``--seeds`` seeds; success AUC (OTB, 21
thresholds) and precision at 20 px over the frames annotated with a box, the long-term
F-score (tracking precision and recall over the confidence thresholds, Lukežič et al.
2021: frames annotated absent count; the model's calibrated confidence, a peer's
``update`` flag) and, where frames are annotated absent, the precision / recall with
which ``confidence < 0.5`` (a peer: a failed update) flags them, and inference frames per
second (decoding excluded). The peers run on the same frames from the same first box:
OpenCV CSRT, KCF and MIL in the peer virtualenv (``bash benchmarks/peers/setup_env.sh``:
they need ``opencv-contrib``, which the toolkit does not depend on); without it, MIL
alone runs in this process.

Sequences (``../shared/data``):

* ``FaceOcc1`` (occlusion), ``Crossing`` (small, low resolution), ``David``
  (illumination, scale, pose), ``Tiger1`` (fast motion, blur, rotation), ``Girl``
  (rotation), ``Biker`` (fast, small, 640×360), ``MotorRolling`` (fast in-plane rotation)
  and ``UAV10-group3`` (a person among look-alikes from a drone, 1280×720 at 10 frames/s,
  35 frames absent);
* ``PETS persons``, a check no default was chosen on: the ``--persons`` longest
  ground-truth tracks of ``PETS09-S2L1`` (people occluding each other and a lamp post),
  each run as a single-object task from its first to its last annotated frame; the AUC
  is the mean over the tracks.

The last table checks the default against the best peer on each sequence: its mean AUC
over the seeds with the standard error, the margin, and whether it is within 0.05 (the
verdict marked where it lies within two standard errors of that bar: more seeds decide
it; one sequence's AUC moves by up to 0.1 between seeds where a lost target is found
again or not). ``--default-only`` runs the default alone against the peers.

``--loso`` runs the candidate configurations of ``GRID`` on the single-object sequences
and, for each one held out, picks the candidate with the best mean AUC on the others and
reports its AUC on the held-out one: how the default (``pgm.models.single_object``) was
chosen. ``--frame-rate`` chooses, the same way over the sequences at their own frame rate,
half and a third of it (frames dropped), how the noise follows the rate.

    python benchmarks/appearance_eval.py [--seeds 5] [--persons 6] [--quick | --default-only]
                                         [--skip-start 0.25] [--sequences FaceOcc1,David]
    python benchmarks/appearance_eval.py --loso [--seeds 2] [--skip-start 0.25]
    python benchmarks/appearance_eval.py --frame-rate [--seeds 2]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, print_table, single_thread, time_engine  # noqa: E402

single_thread()

import cv2  # noqa: E402
from _peers import SETUP_HINT, frame_paths, peer_python, run_sot_peers  # noqa: E402

from pgm.app.runner import init_box_from_gt  # noqa: E402
from pgm.core.boxes import cxcywh_to_xywh, xywh_to_cxcywh  # noqa: E402
from pgm.evaluation.single_object import single_object_metrics  # noqa: E402
from pgm.inference import Engine  # noqa: E402
from pgm.io.annotations import SingleTrack, load_mot, load_single_gt  # noqa: E402
from pgm.io.video import open_source  # noqa: E402
from pgm.models import part_graph, single_object  # noqa: E402

DEFAULT = dict(appearance=single_object.APPEARANCE, scale_noise=single_object.SCALE_NOISE,
               jump_prob=single_object.JUMP_PROB, redetect=single_object.REDETECT)
OLD = dict(appearance="contrast+template", scale_noise=0.005)
#: the option for a still camera over a textured background (docs/results.md, "A long video")
CONTEXT = "  + context learned from motion (cf(context_rate=0.05))"
CONTEXT_FAST = "  + context learned from motion (cf(context_rate=0.2))"
#: (label, part_graph.Params overrides): the ablation
CONFIGS = [
    ("colour PF (Pérez et al. 2002)", dict(appearance="colour")),
    ("part graph, 3 nodes x 10, colour", part_graph.PRESETS["paper"] | dict(num_particles=10)),
    ("fragments", dict(appearance="fragments")),
    ("GMM-KL", dict(appearance="gmm")),
    ("rings (rotation-invariant)", dict(appearance="rings")),
    ("contrast", dict(appearance="contrast")),
    ("template (NCC)", dict(appearance="template")),
    ("previous default: contrast+template, scale", OLD),
    ("DEFAULT: cf, scale, jumps, re-detection", DEFAULT),
    ("  - re-detection (--redetect 0)", DEFAULT | dict(redetect=0.0)),
    ("  re-detection after 10 low frames", DEFAULT | dict(redetect_patience=10)),
    ("  + in-plane angle (rotation_noise 0.005)", DEFAULT | dict(rotation_noise=0.005)),
    ("  + in-plane angle (rotation_noise 0.01)", DEFAULT | dict(rotation_noise=0.01)),
    ("  + in-plane angle (rotation_noise 0.02)", DEFAULT | dict(rotation_noise=0.02)),
    ("  - jumps", DEFAULT | dict(jump_prob=0.0)),
    ("  - scale (fixed size)", DEFAULT | dict(scale_noise=0.0)),
    ("  - filter updates (first frame only)", DEFAULT | dict(appearance="cf(adapt_rate=0)")),
    ("  - update gate", DEFAULT | dict(appearance="cf(gate=0)")),
    (CONTEXT, DEFAULT | dict(appearance="cf(context_rate=0.05)")),
    (CONTEXT_FAST, DEFAULT | dict(appearance="cf(context_rate=0.2)")),
    ("  + scale filter (cf+scale)", DEFAULT | dict(appearance="cf+scale")),
    ("  size by the scale filter alone (cf(scales=1)+scale)",
     DEFAULT | dict(appearance="cf(scales=1)+scale")),
    ("  + template", DEFAULT | dict(appearance="cf+template")),
    ("  + contrast", DEFAULT | dict(appearance="cf+contrast")),
]
QUICK = {"colour PF (Pérez et al. 2002)", "previous default: contrast+template, scale",
         "DEFAULT: cf, scale, jumps, re-detection", "  - re-detection (--redetect 0)",
         CONTEXT, CONTEXT_FAST}
#: candidates for the default, chosen leave-one-sequence-out (--loso)
GRID = ([(f"cf(lam={lam},padding={pad}), jumps {jp}" + (", re-detection" if rd else ""),
          dict(appearance=f"cf(lam={lam},padding={pad})", scale_noise=0.005, jump_prob=jp,
               redetect=rd))
         for lam in (20, 60) for pad in (1.5, 2) for jp in (0.1, 0.4)
         for rd in (0.0, single_object.REDETECT)]
        + [("cf(lam=60,padding=2)+template, jumps 0.4, re-detection",
            DEFAULT | dict(appearance="cf(lam=60,padding=2)+template")),
           ("previous default: contrast+template", OLD),
           ("DEFAULT, re-appearance 0.001", DEFAULT | dict(reappear_prob=0.001)),
           ("DEFAULT + context learned from motion (context_rate 0.05)",
            DEFAULT | dict(appearance="cf(context_rate=0.05)")),
           ("DEFAULT + scale filter (cf+scale)", DEFAULT | dict(appearance="cf+scale"))])
SINGLE = ("FaceOcc1", "Crossing", "David", "Tiger1", "Girl", "Biker", "MotorRolling",
          "UAV10-group3")
#: the four MILTrack/OTB clips the earlier defaults (and the confidence) were chosen on
FIRST_FOUR = SINGLE[:4]
#: frame rates the sequences' folders do not declare, from their SOURCE.md (UAV123@10fps);
#: with a MOT sequence's declared rate (seqinfo.ini), what the model converts its per-frame
#: noise from (single_object.REFERENCE_FPS; filled in by :func:`sequences`)
DECLARED_FPS: dict[str, float] = {"UAV10-group3": 10.0}


def person_tasks(seq: str, n_persons: int) -> list:
    """The ``n_persons`` longest ground-truth people of the MOT sequence ``seq`` (scored
    rows only), each a single-object task from its first to its last annotated frame;
    empty where the sequence is missing or ``n_persons`` is 0."""
    d = SHARED_DATA / seq
    if n_persons <= 0 or not d.is_dir():
        return []
    src = open_source(d)
    table = load_mot(src.gt_path, kind="gt")
    keep = table.scored
    ids, counts = np.unique(table.ids[keep], return_counts=True)
    chosen = ids[np.argsort(-counts, kind="stable")[:n_persons]]
    tracks = []
    for pid in chosen:
        sel = keep & (table.ids == pid)
        tracks.append(SingleTrack(table.frames[sel], table.boxes[sel]))
    lo = min(int(t.frames[0]) for t in tracks)
    hi = max(int(t.frames[-1]) for t in tracks)
    frames = {n: img for n, img in src.frames() if lo <= n <= hi}
    return [([(n, frames[n]) for n in range(int(t.frames[0]), int(t.frames[-1]) + 1)], t,
             init_box_from_gt(t, int(t.frames[0])),
             frame_paths(src, int(t.frames[0]), int(t.frames[-1]) + 1)) for t in tracks]


def sequences(n_persons: int, names=SINGLE, persons_from=("PETS09-S2L1",)):
    """``name -> list of tasks (frames, gt, init, image paths)``; decoded once. The
    person tracks of each sequence in ``persons_from`` are one more group ("PETS
    persons" for PETS09-S2L1, "<sequence> persons" otherwise)."""
    out = {}
    for name in names:
        if (SHARED_DATA / name).is_dir():
            src = open_source(SHARED_DATA / name)
            if src.fps_declared:
                DECLARED_FPS.setdefault(name, src.fps)
            gt = load_single_gt(src.gt_path)
            frames = list(src.frames())
            out[name] = [(frames, gt, init_box_from_gt(gt, frames[0][0]),
                          frame_paths(src, frames[0][0], frames[-1][0] + 1))]
    for seq in persons_from:
        group = person_tasks(seq, n_persons)
        if group:
            label = "PETS persons" if seq == "PETS09-S2L1" else f"{seq} persons"
            out[label] = group
            src = open_source(SHARED_DATA / seq)
            if src.fps_declared:
                DECLARED_FPS.setdefault(label, src.fps)
    return out


def score(gt, numbers, boxes, skip_start: float = 0.0, confidence=None) -> dict:
    """OTB metrics of ``boxes`` at frames ``numbers``, counting only the frames after
    the first ``skip_start`` share (and the ground truth there); with ``confidence`` per
    frame, the long-term measures too."""
    numbers = np.asarray(numbers)
    first = int(np.floor(skip_start * len(numbers)))
    if first:
        gt = gt.since(numbers[first])
    conf = None if confidence is None else np.asarray(confidence, float)[first:]
    return single_object_metrics(gt, numbers[first:], np.asarray(boxes, float)[first:], conf)


def _skipped(skip_start: float) -> str:
    """A table title's note on the frames left out of the scores."""
    return f", first {skip_start:.0%} of each task's frames not scored" if skip_start else ""


def _long_term(m: dict) -> tuple[float, float, float]:
    """(long-term F, absence precision, absence recall) of one task's metrics (NaN where
    undefined: no confidence, or no absence annotated)."""
    lt, ab = m.get("long_term"), m.get("absence")
    nan = float("nan")
    val = lambda d, k: nan if d is None or d.get(k) is None else float(d[k])  # noqa: E731
    return val(lt, "f_score"), val(ab, "precision"), val(ab, "recall")


class Scores:
    """Per-task scores gathered over seeds: AUC per seed (mean over tasks), and the means
    of precision@20, long-term F and the absence signal's precision and recall."""

    def __init__(self):
        self.aucs, self.rest, self.fps = [], [], []
        #: per seed, the AUC of boxes of the first frame's size at the same centres
        #: (:func:`first_size`: the annotation's convention on David, Tiger1, FaceOcc1)
        self.first_size_aucs: list[float] = []

    @property
    def median_fps(self) -> float:
        return float(np.median(self.fps))

    def add_seed(self, metrics: list[dict], n_frames: int, seconds: float) -> None:
        self.aucs.append(np.mean([m["success_auc"] for m in metrics]))
        lt = np.array([_long_term(m) for m in metrics])
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a column of NaN: undefined
            self.rest.append([np.mean([m["precision_at_20"] for m in metrics])]
                             + list(np.nanmean(lt, axis=0)))
        self.fps.append(n_frames / seconds if seconds > 0 else np.nan)

    def row(self, label: str) -> list:
        auc = np.array(self.aucs)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a column of NaN: undefined
            prec, ltf, ap, ar = np.nanmean(np.array(self.rest, float), axis=0)
        f3 = lambda v: "" if not np.isfinite(v) else f"{v:.3f}"  # noqa: E731
        na = lambda v: f3(v) or "n/a"  # noqa: E731
        absent = "" if not np.isfinite(ap) and not np.isfinite(ar) else f"{na(ap)} / {na(ar)}"
        return [label, f"{auc.mean():.3f}", f"{auc.min():.3f}", f"{auc.max():.3f}",
                f"{prec:.3f}", f3(ltf), absent, self.median_fps]


def frame_step(fps: float | None) -> float:
    """What the single-object model makes of a declared frame rate (None: 1)."""
    return 1.0 if fps is None else single_object.REFERENCE_FPS / fps


def run_config(tasks, overrides, seeds, skip_start: float = 0.0,
               fps: float | None = None) -> Scores:
    """The config on every task, ``seeds`` seeds (:class:`Scores`); with ``skip_start``
    the scores count only the frames after that share of each task's; ``fps``: the
    video's declared frame rate (the per-frame noise converted from
    ``single_object.REFERENCE_FPS``, as the model does)."""
    out = Scores()
    for seed in range(seeds):
        metrics, fixed, n_frames, secs = [], [], 0, 0.0
        for frames, gt, init, _ in tasks:
            h, w = frames[0][1].shape[:2]
            kw = {"n_parts": 1, "num_particles": 100, "frame_size": (w, h),
                  "frame_step": frame_step(fps)} | overrides
            graph = single_object.with_confidence(
                part_graph.build_graph(part_graph.Params(init_box=tuple(init), **kw)))
            conf: list[float] = []
            boxes, s, _ = time_engine(Engine(graph, np.random.default_rng(seed)), frames,
                                      scores=conf)
            numbers = [n for n, _ in frames]
            metrics.append(score(gt, numbers, boxes, skip_start, conf))
            fixed.append(score(gt, numbers, first_size(boxes, init), skip_start)["success_auc"])
            n_frames += len(frames)
            secs += s
        out.add_seed(metrics, n_frames, secs)
        out.first_size_aucs.append(float(np.mean(fixed)))
    return out


def first_size(boxes, init) -> np.ndarray:
    """Boxes ``(x, y, w, h)`` of the first frame's size ``init[2:]`` at the centres of
    ``boxes``: what a tracker that follows the centre scores under an annotation that
    keeps the first frame's size (the MILTrack releases of David, Tiger1 and FaceOcc1,
    ``docs/results.md``)."""
    c = xywh_to_cxcywh(np.asarray(boxes, dtype=float).reshape(-1, 4))
    c[:, 2:] = np.asarray(init, dtype=float)[2:4]
    return cxcywh_to_xywh(c)


def run_mil_here(tasks, skip_start: float = 0.0) -> dict[str, Scores]:
    """OpenCV MIL in this process (the main OpenCV build has it)."""
    metrics, n_frames, secs = [], 0, 0.0
    for frames, gt, init, _ in tasks:
        tracker = cv2.TrackerMIL_create()
        box = tuple(int(round(v)) for v in cxcywh_to_xywh(np.asarray(init, float)))
        tracker.init(frames[0][1], box)
        out, oks = [list(box)], [1.0]
        t0 = time.perf_counter()
        for _, img in frames[1:]:
            ok, b = tracker.update(img)
            out.append(list(b) if ok else out[-1])
            oks.append(float(ok))
        secs += time.perf_counter() - t0
        n_frames += len(frames) - 1
        metrics.append(score(gt, [n for n, _ in frames], out, skip_start, oks))
    s = Scores()
    s.add_seed(metrics, n_frames, secs)
    return {"MIL": s}


def run_peers(tasks, skip_start: float = 0.0) -> dict[str, Scores]:
    """CSRT, KCF and MIL in the peer virtualenv; their confidence is ``update``'s flag
    (a failed update: reported absent)."""
    per: dict[str, tuple[list, int, float]] = {}
    for frames, gt, init, paths in tasks:
        res = run_sot_peers(paths, cxcywh_to_xywh(np.asarray(init, float)))
        for name, r in res.items():
            if "error" in r:
                print(f"  {name}: {r['error']}")
                continue
            m = score(gt, [n for n, _ in frames], r["boxes"], skip_start,
                      r["ok"].astype(float))
            got = per.setdefault(name.upper(), ([], 0, 0.0))
            n = len(frames) - 1
            per[name.upper()] = (got[0] + [m], got[1] + n, got[2] + n / r["fps"])
    out = {}
    for name, (metrics, n, secs) in per.items():
        out[name] = Scores()
        out[name].add_seed(metrics, n, secs)
    return out


def peer_scores(tasks, skip_start: float = 0.0) -> dict[str, Scores]:
    """CSRT, KCF and MIL (the peer virtualenv), or MIL alone in this process."""
    return (run_peers(tasks, skip_start) if peer_python() is not None
            else run_mil_here(tasks, skip_start))


#: the issue's bar: the default no more than this below the best peer on any sequence
BAR = 0.05


def bar_rows(results: dict[str, tuple[Scores, dict[str, Scores]]]) -> list[list]:
    """Per sequence, the default's mean AUC over seeds with its standard error, the best
    peer's, the margin ``default − best`` and whether it is at least ``−BAR``; a verdict
    within two standard errors of the default's mean of the bar is marked ``(seeds)``:
    the seeds' luck carries it. Last, the default's AUC with its boxes held at the first
    frame's size (:func:`first_size`; blank where not measured): not the bar, a reading
    of where an annotation of fixed size puts the loss."""
    rows = []
    for name, (ours, peers) in results.items():
        auc = np.array(ours.aucs)
        se = float(auc.std(ddof=1) / np.sqrt(auc.size)) if auc.size > 1 else float("nan")
        means = {k: float(np.mean(v.aucs)) for k, v in peers.items()}
        best = max(means, key=means.get) if means else None
        margin = float(auc.mean()) - (means[best] if best else float("nan"))
        luck = best is not None and not abs(margin + BAR) > 2 * se  # NaN s.e.: luck
        fixed = f"{np.mean(ours.first_size_aucs):.3f}" if ours.first_size_aucs else ""
        rows.append([name, f"{auc.mean():.3f} ± {se:.3f}",
                     f"{best} {means[best]:.3f}" if best else "-", f"{margin:+.3f}",
                     ("yes" if margin >= -BAR else "no") + (" (seeds)" if luck else ""),
                     fixed])
    return rows


def loso(seqs, seeds: int, skip_start: float = 0.0) -> None:
    """The leave-one-sequence-out choice of the default over ``GRID`` (scored on the
    frames after the first ``skip_start`` share of each sequence's)."""
    names = [n for n in SINGLE if n in seqs]
    table = {}
    rows = []
    for label, overrides in GRID:
        table[label] = {n: float(np.mean(run_config(seqs[n], overrides, seeds, skip_start,
                                                    DECLARED_FPS.get(n)).aucs))
                        for n in names}
        rows.append([label] + [f"{table[label][n]:.3f}" for n in names]
                    + [f"{np.mean(list(table[label].values())):.3f}"])
        print(f"  {label}: " + " ".join(rows[-1][1:]), file=sys.stderr, flush=True)
    print_table(["candidate (part_graph.Params)"] + names + ["mean"], rows,
                title=f"Candidates for the default, success AUC ({seeds} seeds"
                      f"{_skipped(skip_start)})")
    picks = []
    for held in names:
        others = [n for n in names if n != held]
        best = max(table, key=lambda k: np.mean([table[k][n] for n in others]))
        picks.append([held, best, f"{np.mean([table[best][n] for n in others]):.3f}",
                      f"{table[best][held]:.3f}"])
    print_table(["held out", "picked on the others", "AUC there", "AUC held out"], picks,
                title="Leave-one-sequence-out choice")
    print(f"held-out mean AUC: {np.mean([float(p[3]) for p in picks]):.3f}")


def frame_rate_loso(seqs, seeds: int, steps=(1, 2, 3), exponents=(0.0, 0.5, 1.0)) -> None:
    """How the default's per-frame noise should follow the frame rate, leave one sequence
    out over the sequences × frame rate ÷ ``steps`` (frames dropped): the noise read at
    ``single_object.REFERENCE_FPS`` times ``τ^e`` (``τ``: reference frames per video
    frame), ``e`` among ``exponents`` (0: none; ½: a random walk, what the model does)."""
    names = [n for n in SINGLE if n in seqs]
    table: dict[float, dict[tuple[str, int], float]] = {e: {} for e in exponents}
    for name in names:
        frames, gt, init, paths = seqs[name][0]
        for step in steps:
            sub = frames[::step]
            kept = [n for n, _ in sub]
            task = (sub, SingleTrack(gt.frames[np.isin(gt.frames, kept)],
                                     gt.boxes[np.isin(gt.frames, kept)],
                                     gt.absent[np.isin(gt.absent, kept)]), init, paths)
            tau = frame_step(DECLARED_FPS.get(name)) * step
            for e in exponents:
                walk = tau ** e
                over = DEFAULT | {"pos_noise": 0.03 * np.sqrt(init[2] * init[3]) * walk,
                                  "scale_noise": DEFAULT["scale_noise"] * walk}
                table[e][(name, step)] = float(np.mean(run_config([task], over, seeds).aucs))
            print(f"  {name} /{step}: " + " ".join(f"{table[e][(name, step)]:.3f}"
                                                   for e in exponents), file=sys.stderr)
    print_table(["noise x tau^e"] + [f"/{s} mean AUC" for s in steps],
                [[f"e = {e:g}"] + [f"{np.mean([table[e][(n, s)] for n in names]):.3f}"
                                   for s in steps] for e in exponents],
                title=f"Frame rate divided by {steps}, {seeds} seeds")
    rows, held, none = [], [], []
    for out in names:
        score = {e: np.mean([v for k, v in table[e].items() if k[0] != out]) for e in exponents}
        best = max(exponents, key=lambda e: score[e])
        held.append(np.mean([table[best][(out, s)] for s in steps]))
        none.append(np.mean([table[exponents[0]][(out, s)] for s in steps]))
        rows.append([out, f"e = {best:g}", f"{held[-1]:.3f}", f"{none[-1]:.3f}"])
    print_table(["held out", "picked on the others", "AUC held out (mean over rates)",
                 f"e = {exponents[0]:g}"], rows, title="Leave-one-sequence-out choice")
    print(f"held-out mean AUC: {np.mean(held):.3f} (e = {exponents[0]:g}: {np.mean(none):.3f})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--persons", type=int, default=6,
                    help="PETS09-S2L1 person tracks for the held-out check (0: none)")
    ap.add_argument("--quick", action="store_true",
                    help="the default, the learned context (two rates) and two earlier "
                         "models only")
    ap.add_argument("--default-only", action="store_true",
                    help="the default alone against the peers (the bar's check)")
    ap.add_argument("--loso", action="store_true",
                    help="the leave-one-sequence-out choice of the default over GRID")
    ap.add_argument("--skip-start", type=float, default=0.0, metavar="SHARE",
                    help="score only the frames after this share of each sequence's "
                         "(0.25: the long run, not the start, decides; with --loso, the "
                         "choice too)")
    ap.add_argument("--sequences", default=None,
                    help="comma-separated subset (default: all, 'PETS persons' included)")
    ap.add_argument("--frame-rate", action="store_true",
                    help="leave-one-sequence-out choice of how the noise follows the frame "
                         "rate, over the sequences at their rate, half and a third")
    args = ap.parse_args()
    seqs = sequences(0 if args.loso or args.frame_rate else args.persons)
    if args.sequences:
        keep = {s.strip() for s in args.sequences.split(",")}
        seqs = {n: t for n, t in seqs.items() if n in keep}
    if not seqs:
        sys.exit(f"no sequences under {SHARED_DATA}")
    if args.loso:
        loso(seqs, args.seeds, args.skip_start)
        return
    if args.frame_rate:
        frame_rate_loso(seqs, args.seeds)
        return
    if peer_python() is None:
        print(SETUP_HINT + "; MIL alone runs here")
    bar: dict[str, tuple[Scores, dict[str, Scores]]] = {}
    for name, tasks in seqs.items():
        peers = peer_scores(tasks, args.skip_start)
        rows = [sc.row(f"OpenCV {n}") for n, sc in peers.items()]
        for label, overrides in CONFIGS:
            if (args.quick and label not in QUICK) or (args.default_only
                                                        and overrides is not DEFAULT):
                continue
            got = run_config(tasks, overrides, args.seeds, args.skip_start,
                             DECLARED_FPS.get(name))
            rows.append(got.row(label))
            if overrides is DEFAULT:
                bar[name] = (got, peers)
        n = sum(len(t[0]) for t in tasks)
        print_table(["config (100 particles unless stated)", "AUC", "min", "max", "prec@20",
                     "LT F", "absent P / R", "frames/s"], rows,
                    title=f"{name}: {len(tasks)} task(s), {n} frames, {args.seeds} seeds"
                          f"{_skipped(args.skip_start)}")
        sys.stdout.flush()
    print_table(["sequence", "default AUC ± s.e.", "best peer", "margin",
                 f"within {BAR} of it", "default at the first frame's size"], bar_rows(bar),
                title=f"The default against the best peer per sequence ({args.seeds} seeds; "
                      f"'(seeds)': the verdict is within two standard errors of the bar)")


if __name__ == "__main__":
    main()
