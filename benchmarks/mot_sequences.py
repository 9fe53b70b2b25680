"""PHD and VB-PHD on the shared multi-person sequences, next to the peers' figures.

    python benchmarks/mot_sequences.py [--mog2] [--noise-experiment] [--dbn] [--seeds K]
                                       [--lost-seconds S] [--merge-gate G]
                                       [--sigma-factors 0.25,4] [--dbn-calibrate N]
                                       [--scores off|mixture] [--scale-aware]
                                       [--set FIELD=VALUE ...] [--sequences A,B] [--no-peers]

Public detections (``det/det.txt``, all rows) on PETS09-S2L1 (frames 1-240),
TUD-Campus, TUD-Stadtmitte and MOT16-11 (frames 1-300; moving camera; MOT16
protocol); with ``--mog2`` also background subtraction on the full
PETS09-S2L1 video. Scored with :func:`pgm.evaluation.mot.evaluate_mot` (CLEAR / Identity /
HOTA at IoU 0.5, flag-0 rows as ignore regions; OSPA on foot points). Frames per
second are inference only (detection and decoding excluded). The peers — SORT,
ByteTrack and OC-SORT of the ``trackers`` package (2.6.1, default settings; scores outside
[0, 1] through a logistic) — run in the same script from the same detections in their own
virtualenv (``bash benchmarks/peers/setup_env.sh``; never a toolkit dependency) and are
scored by the same :func:`~pgm.evaluation.mot.evaluate_mot` as the toolkit's rows. Without
that virtualenv the bench README's figures are printed instead, marked so (its scorer
counts ID switches slightly differently: TrackEval's CLEAR against the ``motrics``
library's here).

``--seeds K``: public-detection rows are means over seeds 0..K-1 (default 1: seed 0),
with the range of MOTA over the seeds in its own column.

``--lost-seconds S``: how long the track layer keeps a lost track for
re-identification (default 1, as ``pgm track``; 0 turns the lost stage off).
``--merge-gate G``: extraction merge gate in σ (default 3, as ``pgm track``).
``--scores off|mixture``: detection scores in the measurement model (default: as
``pgm track``; ``off`` is the score-blind filter of before).

``--dbn``: also VB-PHD + DBN, leave one sequence out: for each sequence a DBN
(``pgm learn dbn`` defaults: every 3rd frame, 40 fine-tuning epochs, seed 0) is trained
on the other two and its likelihood ratio multiplies into the VB-PHD update (§II-C of
Feng et al. 2015, as read in :mod:`pgm.observation.appearance.dbn`);
the training time is printed. ``--dbn-calibrate N``: detections the DBN factor collects
on the video before re-fitting its calibration without labels (default 60, the
factor's default; 0: keep the trained calibration).

``--sigma-factors F1,F2,...``: a mis-specification experiment — PHD and VB-PHD (seed
0) on each sequence with the nominal measurement σ (and the VB prior's) multiplied by
each factor; VB-PHD learns σ back, the PHD cannot.

``--noise-experiment``: PETS09-S2L1's public detections with extra Gaussian noise on
the box position whose σ drifts from 2 to 12 px over the sequence; PHD with a fixed
σ against VB-PHD.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, print_table, single_thread  # noqa: E402

single_thread()

from _peers import SETUP_HINT, peer_python, run_mot_peers  # noqa: E402

from pgm.app.runner import track_multi  # noqa: E402
from pgm.evaluation.mot import evaluate_mot  # noqa: E402
from pgm.io.annotations import MotTable, load_mot  # noqa: E402
from pgm.io.video import open_source  # noqa: E402
from pgm.models import phd, vb_phd  # noqa: E402
from pgm.models.phd import video_params  # noqa: E402
from pgm.observation.detections import Detections, PublicDetections, make_detector  # noqa: E402

PEERS = {  # bench/README.md (the fallback): MOTA, IDF1, HOTA, IDSW, OSPA(50,1), OSPA(100,2)
    "PETS09-S2L1": {"SORT": (0.612, 0.450, 0.362, 53, 12.2, 32.3),
                    "ByteTrack": (0.594, 0.514, 0.414, 64, 12.7, 34.2),
                    "OC-SORT": (0.657, 0.489, 0.397, 50, 12.5, 32.4)},
    "TUD-Campus": {"SORT": (0.432, 0.484, 0.326, 19, 28.8, 62.2),
                   "ByteTrack": (0.371, 0.451, 0.334, 20, 24.7, 51.5),
                   "OC-SORT": (0.415, 0.488, 0.305, 9, 31.4, 69.3)},
    "TUD-Stadtmitte": {"SORT": (0.505, 0.494, 0.329, 36, 19.0, 42.5),
                       "ByteTrack": (0.458, 0.424, 0.313, 46, 18.6, 42.1),
                       "OC-SORT": (0.537, 0.504, 0.332, 23, 20.9, 50.0)},
    # MOT16 protocol (class 1 scored; classes 2, 7, 8, 12 ignore regions); moving camera;
    # the bench README has no peer figures for it
    "MOT16-11": {},
}
MODELS = (("PHD", phd), ("VB-PHD", vb_phd))


PEER_NAMES = {"sort": "SORT", "bytetrack": "ByteTrack", "ocsort": "OC-SORT"}


def peer_rows(seq: str, d: Path, last_frame: int) -> list[list]:
    """SORT / ByteTrack / OC-SORT run now on ``d``'s public detections and scored like the
    toolkit's rows over frames ``1..last_frame``; the bench README's figures when the
    peer virtualenv is missing."""
    if peer_python() is None:
        return [[seq, f"{peer} (bench README)", *vals[:4], "-", "-", *vals[4:], "-", "-", "-",
                 "-"] for peer, vals in PEERS[seq].items()]
    gt = load_mot(open_source(d).gt_path, kind="gt").until(last_frame)
    rows = []
    for name, r in run_mot_peers(d, last_frame=last_frame).items():
        if "error" in r:
            print(f"{seq} {name}: {r['error']}", file=sys.stderr)
            continue
        m = evaluate_mot(gt, r["table"].until(last_frame), num_frames=last_frame)
        rows.append([seq, PEER_NAMES.get(name, name), m["mota"], m["idf1"], m["hota"],
                     f"{m['id_switches']:.1f}", f"{m['fp']:.1f}", f"{m['fn']:.1f}",
                     m["ospa_50_1"], m["ospa_100_2"], m["ospa2"], r["fps"], "-", "-"])
    return rows


class NoisyDetections:
    """Public detections with extra position noise of a drifting σ (seeded)."""

    def __init__(self, table: MotTable, n_frames: int, lo: float, hi: float, seed: int = 0):
        self.table, self.n, self.lo, self.hi = table, n_frames, lo, hi
        self.rng = np.random.default_rng(seed)
        self.name = f"noisy {lo}-{hi}px"

    def sigma(self, frame: int) -> float:
        return self.lo + (self.hi - self.lo) * (frame - 1) / max(1, self.n - 1)

    def __call__(self, frame, image):
        _, boxes, conf = self.table.at(frame)
        boxes = np.array(boxes, dtype=float)
        boxes[:, :2] += self.sigma(frame) * self.rng.standard_normal((len(boxes), 2))
        return Detections(boxes, np.asarray(conf, dtype=float))


def train_dbn(train_dirs, path: Path, seed: int = 0) -> float:
    """Train a DBN on ``train_dirs`` as ``pgm learn dbn`` does; returns seconds."""
    import time

    from pgm.observation.appearance.dbn import DBN, training_set
    from pgm.observation.appearance.features import PatchFeatures

    t0 = time.perf_counter()
    rng = np.random.default_rng(seed)
    feats = PatchFeatures()
    X, y = training_set([str(d) for d in train_dirs], rng, every=3, features=feats)
    net = DBN()
    net.features_ = feats.to_dict()
    net.fit(X, y, rng, finetune_epochs=40)
    net.save(path)
    return time.perf_counter() - t0


def dbn_check(seq_dir: Path, path: Path, every: int = 5) -> str:
    """The held-out DBN's literal log-ratio (ε = 0) at the annotated people's foot points
    (patch of the median detection size, as in tracking) and at random foot points."""
    from sklearn.metrics import roc_auc_score

    from pgm.core.frame import FrameContext
    from pgm.observation.appearance.dbn import DBNLikelihood

    f = DBNLikelihood("t", model=str(path), epsilon=0.0, stride=0.0)
    src = open_source(seq_dir)
    gt = load_mot(src.gt_path, kind="gt")
    size = np.median(load_mot(src.det_path, kind="det").boxes[:, 2:4], axis=0)
    f.box_size = size
    rng = np.random.default_rng(0)
    W, H = src.size
    pos, neg = [], []
    for n, img in src.frames():
        _, b, _ = gt.at(n)
        if n % every or len(b) == 0:
            continue
        ctx = FrameContext(n, img)
        feet = np.zeros((len(b), 4))
        feet[:, 0], feet[:, 2] = b[:, 0] + b[:, 2] / 2, b[:, 1] + b[:, 3]
        pos += list(f.log_likelihood(feet, ctx))
        rnd = np.zeros((20, 4))
        rnd[:, 0], rnd[:, 2] = rng.uniform(0, W, 20), rng.uniform(size[1], H, 20)
        neg += list(f.log_likelihood(rnd, ctx))
    auc = roc_auc_score(np.r_[np.ones(len(pos)), np.zeros(len(neg))], np.r_[pos, neg])
    return (f"log-ratio at people: median {np.median(pos):.1f}, 10% quantile "
            f"{np.quantile(pos, 0.1):.1f}; at random points: median {np.median(neg):.1f}; "
            f"ROC AUC {auc:.3f}")


def run(seq_dir: Path, module, detector, seed: int = 0, dbn: Path | None = None,
        lost_seconds: float = 1.0, merge_gate: float = 3.0, sigma_factor: float = 1.0,
        dbn_calibrate: int = 60, camera_motion: str = "auto", scale_aware: bool = False,
        scores: str | None = None, overrides: dict | None = None):
    src = open_source(seq_dir)
    gt = load_mot(src.gt_path, kind="gt")
    w, h = src.size
    # lengths in units of a person's height: the median public-detection height (as
    # `pgm track` does); MOG2 has no table up front, so the 75 px reference is used
    table = getattr(detector, "table", None)
    if table is None and src.det_path is not None and isinstance(detector, NoisyDetections):
        table = detector.table
    height = float(np.median(table.boxes[:, 3])) if table is not None else None
    extra = {} if scores is None else {"score_model": scores}
    extra.update(overrides or {})
    params = video_params(module.Params, w, h, src.fps, typical_height=height,
                          lost_seconds=lost_seconds, merge_gate=merge_gate,
                          scale_aware=scale_aware, **extra)
    if sigma_factor != 1.0:
        params = dataclasses.replace(params, sigma=params.sigma * sigma_factor)
    graph = module.build_graph(params)
    if dbn is not None:
        from pgm.observation.appearance.dbn import DBNLikelihood

        graph = graph.with_factors(DBNLikelihood("targets", model=str(dbn),
                                                 calibrate_with=dbn_calibrate,
                                                 name="appearance:dbn"))
    return track_multi(src, graph, detector, rng=np.random.default_rng(seed), gt=gt,
                       write_video=False, progress=False, camera_motion=camera_motion)


def parse_overrides(items) -> dict:
    """``["sigma_log_h=0.15", ...]`` -> ``{"sigma_log_h": 0.15}`` (values read as JSON,
    else kept as strings); a field that ``vb_phd.Params`` lacks is refused by name."""
    import json

    fields = {f.name for f in dataclasses.fields(vb_phd.Params)}
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or key not in fields:
            raise SystemExit(f"--set {item!r}: expected FIELD=VALUE with FIELD one of the "
                             f"(VB-)PHD Params fields")
        try:
            out[key] = json.loads(value)
        except json.JSONDecodeError:
            out[key] = value
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[1])
    ap.add_argument("--mog2", action="store_true", help="also PETS09 video with MOG2")
    ap.add_argument("--noise-experiment", action="store_true")
    ap.add_argument("--dbn", action="store_true",
                    help="also VB-PHD + DBN, trained leaving the sequence out")
    ap.add_argument("--seeds", type=int, default=1, help="seeds per public-detection row")
    ap.add_argument("--dbn-calibrate", type=int, default=60,
                    help="detections collected before the DBN re-fits its calibration (0: off)")
    ap.add_argument("--lost-seconds", type=float, default=1.0,
                    help="track layer: seconds a lost track is kept for re-identification")
    ap.add_argument("--sigma-factors", default=None,
                    help="comma-separated factors on the nominal sigma (mis-specification)")
    ap.add_argument("--merge-gate", type=float, default=3.0,
                    help="extraction: estimates closer than this many sigma are merged")
    ap.add_argument("--camera-motion", choices=("auto", "on", "off"), default="auto",
                    help="global-motion compensation (as pgm track; default auto)")
    ap.add_argument("--scale-aware", action="store_true",
                    help="scale-aware state and noise (lengths in each target's own height)")
    ap.add_argument("--scores", choices=("off", "mixture", "learned"), default=None,
                    help="detection scores in the measurement model (default: as pgm track)")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                    help="override a Params field of the (VB-)PHD rows, e.g. --set "
                         "sigma_log_h=0.15 (value read as JSON; repeatable)")
    ap.add_argument("--sequences", default=None,
                    help="comma-separated subset of the sequences (default: all)")
    ap.add_argument("--no-peers", action="store_true",
                    help="leave SORT / ByteTrack / OC-SORT out (about a minute saved per "
                         "call, e.g. in --set sweeps)")
    args = ap.parse_args()
    overrides = parse_overrides(args.set)
    if not args.no_peers and peer_python() is None:
        print(SETUP_HINT + "; the bench README's peer figures are printed instead",
              file=sys.stderr)
    rows = []
    import tempfile

    tmp = tempfile.TemporaryDirectory()
    seqs = [SHARED_DATA / q for q in PEERS if (SHARED_DATA / q).is_dir()]
    chosen = set(args.sequences.split(",")) if args.sequences else set(PEERS)
    for seq in PEERS:
        d = SHARED_DATA / seq
        if not d.is_dir() or seq not in chosen:
            continue
        runs = [(name, module, None) for name, module in MODELS]
        if args.dbn:
            others = [q for q in seqs if q != d]
            path = Path(tmp.name) / f"dbn-without-{seq}.npz"
            secs = train_dbn(others, path)
            print(f"DBN for {seq}: trained on {', '.join(q.name for q in others)} in "
                  f"{secs:.0f} s; {dbn_check(d, path)}", flush=True)
            runs.append(("VB-PHD + DBN (LOSO)", vb_phd, path))
        last_frame = None
        for name, module, dbn in runs:
            ms = []
            for seed in range(args.seeds):
                r = run(d, module, make_detector("public", open_source(d)), seed=seed, dbn=dbn,
                        lost_seconds=args.lost_seconds, merge_gate=args.merge_gate,
                        dbn_calibrate=args.dbn_calibrate, camera_motion=args.camera_motion,
                        scale_aware=args.scale_aware, scores=args.scores,
                        overrides=overrides)
                m = r.metrics
                last_frame = r.n_frames
                sig = (float(np.median(r.noise_sigma))
                       if r.noise_sigma else np.nan)
                ms.append([m["mota"], m["idf1"], m["hota"], m["id_switches"], m["fp"], m["fn"],
                           m["ospa_50_1"], m["ospa_100_2"], m["ospa2"], r.fps, sig])
            ms = np.array(ms, dtype=float)
            mean = ms.mean(axis=0)
            rows.append([seq, name, *mean[:3], *(f"{v:.1f}" for v in mean[3:6]), *mean[6:10],
                         f"{ms[:, 0].min():.3f}-{ms[:, 0].max():.3f}",
                         "-" if np.isnan(mean[10]) else (f"{mean[10]:.3f} h" if args.scale_aware
                                                         else f"{mean[10]:.1f} px")])
        if not args.no_peers:
            rows.extend(peer_rows(seq, d, last_frame))
    if args.mog2 and (SHARED_DATA / "PETS09-S2L1-video").is_dir():
        d = SHARED_DATA / "PETS09-S2L1-video"
        for name, module in MODELS:
            r = run(d, module, make_detector("mog2", open_source(d)))
            m = r.metrics
            rows.append(["PETS09-S2L1-video (MOG2, 795 fr.)", name, m["mota"], m["idf1"],
                         m["hota"], m["id_switches"], m["fp"], m["fn"], m["ospa_50_1"],
                         m["ospa_100_2"], m["ospa2"], r.fps, "-", "-"])
    print_table(["sequence", "tracker", "MOTA", "IDF1", "HOTA", "ID sw.", "FP", "FN",
                 "OSPA(50,1)", "OSPA(100,2)", "OSPA2(50,1)", "frames/s", "MOTA range",
                 "median σ̂"], rows,
                title="public detections unless stated; " + (
                    f"mean of seeds 0-{args.seeds - 1}" if args.seeds > 1 else "seed 0"))
    if args.sigma_factors:
        rows = []
        for d in seqs:
            for f in (float(v) for v in args.sigma_factors.split(",")):
                for name, module in MODELS:
                    r = run(d, module, make_detector("public", open_source(d)),
                            lost_seconds=args.lost_seconds, merge_gate=args.merge_gate,
                            sigma_factor=f)
                    m = r.metrics
                    rows.append([d.name, f, name, m["mota"], m["idf1"], m["ospa_50_1"],
                                 m["ospa_100_2"]])
        print_table(["sequence", "σ factor", "tracker", "MOTA", "IDF1", "OSPA(50,1)",
                     "OSPA(100,2)"], rows,
                    title="mis-specified measurement σ (nominal × factor), seed 0")
    if args.noise_experiment:
        d = SHARED_DATA / "PETS09-S2L1"
        src = open_source(d)
        table = PublicDetections(src.det_path).table
        rows = []
        for name, module in MODELS:
            det = NoisyDetections(table, len(src), 2.0, 12.0, seed=1)
            r = run(d, module, det)
            m = r.metrics
            sig = np.array(r.noise_sigma) if r.noise_sigma else None
            follow = "-"
            if sig is not None:
                truth = np.array([det.sigma(f) for f in range(1, len(sig) + 1)])
                follow = f"{np.corrcoef(sig, truth)[0, 1]:.2f}"
            rows.append([name, m["mota"], m["idf1"], m["ospa_50_1"], m["ospa_100_2"], follow])
        print_table(["tracker", "MOTA", "IDF1", "OSPA(50,1)", "OSPA(100,2)",
                     "corr(σ̂, σ extra)"], rows,
                    title="noise experiment: PETS09-S2L1 public detections + N(0, σ(t)²) on "
                          "x, y, σ drifting 2 → 12 px")


if __name__ == "__main__":
    main()
