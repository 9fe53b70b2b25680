"""SORT, ByteTrack and OC-SORT as model configs of the engine, against the ``trackers`` package.

    python benchmarks/classic_trackers.py [--sequences A,B] [--repeats 3] [--no-peers]
                                          [--variants]

On each shared MOT sequence (all frames, public detections, every row), the toolkit's
``sort``, ``bytetrack`` and ``ocsort`` configs (:mod:`pgm.models.sort`,
:mod:`pgm.models.bytetrack`, :mod:`pgm.models.ocsort`:
a plate of exact Kalman box states, data association as a factor) and the ``trackers``
package's SORT, ByteTrack and OC-SORT (2.6.1, default settings, in their own virtualenv:
``bash benchmarks/peers/setup_env.sh``) are fed the same detections — scores mapped
through the logistic when any lies outside [0, 1], as ``benchmarks/peers/mot_peers.py``
does — and scored by the same :func:`pgm.evaluation.mot.evaluate_mot`. Columns: MOTA,
IDF1, HOTA, ID switches, and the difference of MOTA and IDF1 to the package's tracker of
the same name (the parity ``tests/test_peers.py`` checks).

Speed: frames per second of ``engine.step`` (the toolkit) and of ``tracker.update`` (the
package), detections already loaded, no image decoding, one thread; the best of
``--repeats`` runs; the ratio is toolkit / package, both measured in this run. Peak
memory of a toolkit run with ``tracemalloc``.

``--variants``: also every variant of the cores (``--vb-noise``, ``--box-state``,
``--noise scale``, ``--report estimate``).

``--misspecified``: Feng et al. (2015)'s claim on the SORT core — ``sort --noise scale`` and
``vb-sort`` with the detection noise (``meas_std``) set 0.1, 1 and 10 times its value.

``--motions``: Wang, Yin & Man (2008)'s idea on the cores — the box state as particles moved by constant
velocity (``cv``), velocity averaged over three frames (``cv3``) or a GPDM learned on the
*other* sequences' ground-truth trajectories (``gpdm``, ``benchmarks/plate_trackers.py``'s
``train_gpdm``), next to the Kalman core, for ``sort`` and ``ocsort --report estimate``
(camera motion compensated as ``pgm track`` does).

``--vb-choose``: ``vb-sort``'s forgetting factor ρ and prior weight α₀ left one sequence
out (ρ ∈ {0.8, 0.9, 0.95, 0.99} × α₀ ∈ {3, 10, 30}; objective (MOTA + IDF1) / 2), each
held-out sequence next to the shipped setting.

``--choose``: the default multi-target model chosen **leave one sequence out** among the
variants and the appearance variants (colour or fragments models per track, weight 0.5
or 1, on top of ``--report estimate``; these read the decoded frames), each run as ``pgm
track`` runs it: the camera's motion estimated from the frames and compensated where the
camera moves (``--camera-motion auto``; the parity rows have none, as the package).
Objective: the mean of (MOTA + IDF1) / 2 over the other sequences; each held-out sequence
is scored with the variant chosen on the others, next to the best of the package's SORT,
ByteTrack and OC-SORT on it.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, print_table, shared_sequences, single_thread  # noqa: E402

SEQUENCES = ("PETS09-S2L1", "TUD-Campus", "TUD-Stadtmitte", "MOT16-11")


def sequence(name: str):
    """``(detector, ground truth, number of frames, fps)`` of a shared MOT sequence."""
    from pgm.io.annotations import load_mot
    from pgm.io.video import open_source
    from pgm.observation.detections import PublicDetections

    src = open_source(SHARED_DATA / name)
    det = PublicDetections(Path(src.path) / "det" / "det.txt")
    gt = load_mot(src.gt_path, kind="gt")
    return det, gt, len(src), float(src.fps)


def run_graph(graph, det, num_frames: int, seed: int = 0, trace: bool = False,
              motion: dict | None = None, images=None):
    """Run ``graph`` on the detections of frames ``1..num_frames``; returns the tracks
    table, the inference seconds and (``trace``) the peak traced memory in bytes.
    ``motion``: frame number → the camera's image motion (``camera_motions``);
    ``images``: a frame source whose images the frames carry (appearance)."""
    import tracemalloc

    from pgm.core.frame import FrameContext
    from pgm.core.readout import readout
    from pgm.inference import Engine
    from pgm.io.annotations import MotTable

    engine = Engine(graph, seed)
    motion = motion or {}
    if images is None:
        frames = [FrameContext(n, detections=det(n), camera_motion=motion.get(n))
                  for n in range(1, num_frames + 1)]
    else:  # decoded as they are needed (a 1080p sequence would not fit in memory)
        frames = (FrameContext(int(n), image, detections=det(int(n)),
                               camera_motion=motion.get(int(n)))
                  for k, (n, image) in enumerate(images.frames()) if k < num_frames)
    rows_f, rows_i, rows_b, rows_c = [], [], [], []
    if trace:
        tracemalloc.start()
    secs = 0.0
    for ctx in frames:
        t0 = time.perf_counter()
        record = engine.step(ctx)
        secs += time.perf_counter() - t0
        f, i, b, c = readout(engine.graph, record).rows(ctx.index)  # (and filled gaps)
        rows_f += f.tolist()
        rows_i += i.tolist()
        rows_b += b.tolist()
        rows_c += c.tolist()
    peak = tracemalloc.get_traced_memory()[1] if trace else None
    if trace:
        tracemalloc.stop()
    table = MotTable(np.asarray(rows_f, dtype=np.int64), np.asarray(rows_i, dtype=np.int64),
                     np.asarray(rows_b, dtype=float).reshape(-1, 4),
                     np.asarray(rows_c, dtype=float))
    return table, secs, peak


#: the variants of the cores: command-line flags and Params fields
VARIANTS = (
    ("--vb-noise", {"vb_noise": True}),
    ("--box-state xysr", {"box_state": "xysr"}),
    ("--noise scale", {"noise": "scale"}),
    ("--noise scale --vb-noise", {"noise": "scale", "vb_noise": True}),
    ("--report estimate", {"report": "estimate"}),
    ("--box-state xysr --report estimate", {"box_state": "xysr", "report": "estimate"}),
    ("--noise scale --report estimate", {"noise": "scale", "report": "estimate"}),
    ("--noise scale --vb-noise --report estimate",
     {"noise": "scale", "vb_noise": True, "report": "estimate"}),
    ("--noise scale --report estimate --occlusion-gate 3",
     {"noise": "scale", "report": "estimate", "occlusion_gate": 3.0}),
)
#: OC-SORT's state is the paper's (xysr) by default: its variants
OCSORT_VARIANTS = (
    ("--report estimate", {"report": "estimate"}),
    ("--box-state xyxy", {"box_state": "xyxy"}),
    ("--box-state xyxy --noise scale", {"box_state": "xyxy", "noise": "scale"}),
    ("--box-state xyxy --noise scale --vb-noise",
     {"box_state": "xyxy", "noise": "scale", "vb_noise": True}),
    ("--box-state xyxy --noise scale --report estimate",
     {"box_state": "xyxy", "noise": "scale", "report": "estimate"}),
    ("--box-state xyxy --noise scale --vb-noise --report estimate",
     {"box_state": "xyxy", "noise": "scale", "vb_noise": True, "report": "estimate"}),
    ("--box-state xyxy --noise scale --report estimate --occlusion-gate 3",
     {"box_state": "xyxy", "noise": "scale", "report": "estimate", "occlusion_gate": 3.0}),
)


#: appearance variants (on top of --report estimate), which read the frames' images
APPEARANCE_VARIANTS = tuple(
    (f"--report estimate --appearance {cue} --appearance-weight {w:g}",
     {"report": "estimate", "appearance": cue, "appearance_weight": w})
    for cue in ("colour", "fragments") for w in (0.5, 1.0))


def cores():
    """The three cores and their variants: ``(label, module, variants)``."""
    from pgm.models import bytetrack, ocsort, sort

    return (("sort", sort, VARIANTS), ("bytetrack", bytetrack, VARIANTS),
            ("ocsort", ocsort, OCSORT_VARIANTS))


def camera_motions(name: str | Path, num_frames: int) -> dict[int, np.ndarray]:
    """Frame number → the camera's image motion since the previous frame, estimated from
    the frames as ``pgm track --camera-motion auto`` does (frames without significant
    motion left out). ``name``: a shared sequence's name, or a sequence folder."""
    from pgm.io.video import open_source
    from pgm.observation.camera_motion import CameraMotionEstimator

    est = CameraMotionEstimator("auto")
    out = {}
    folder = name if isinstance(name, Path) else SHARED_DATA / name
    for k, (number, image) in enumerate(open_source(folder).frames()):
        if k >= num_frames:
            break
        m = est(image)
        if m is not None:
            out[int(number)] = m
    return out


FACTORS = (0.1, 1.0, 10.0)


def vb_choose(seqs: list[str]) -> list[list]:
    """``vb-sort``'s ``vb_rho`` × ``vb_alpha0`` chosen on the other sequences, per held-out
    sequence, with the shipped setting's score there."""
    from pgm.evaluation.mot import evaluate_mot
    from pgm.models import sort, vb_sort

    data = {q: sequence(q) for q in seqs}
    grid = [(rho, a0) for rho in (0.8, 0.9, 0.95, 0.99) for a0 in (3.0, 10.0, 30.0)]
    score: dict[tuple, dict[str, dict]] = {}
    for rho, a0 in grid:
        score[(rho, a0)] = {}
        for q, (det, gt, n, fps) in data.items():
            p = replace(vb_sort.Params(), fps=fps, vb_rho=rho, vb_alpha0=a0,
                        score_map=sort.score_map_for(det.table.conf))
            table, _, _ = run_graph(vb_sort.build_graph(p), det, n)
            score[(rho, a0)][q] = evaluate_mot(gt.until(n), table, num_frames=n)
    obj = lambda k, qs: float(np.mean([(score[k][q]["mota"] + score[k][q]["idf1"]) / 2  # noqa: E731
                                       for q in qs]))
    shipped = (vb_sort.Params().vb_rho, vb_sort.Params().vb_alpha0)
    rows = []
    for held in seqs:
        best = max(grid, key=lambda k: obj(k, [q for q in seqs if q != held]))
        m, s = score[best][held], score[shipped][held]
        rows.append([held, f"{best[0]:g}, {best[1]:g}", f"{m['mota']:.3f} / {m['idf1']:.3f}",
                     f"{s['mota']:.3f} / {s['idf1']:.3f}"])
    return rows


def misspecified(seqs: list[str]) -> list[list]:
    """``sort --noise scale`` and ``vb-sort`` with ``meas_std`` times each of
    :data:`FACTORS`."""
    from pgm.evaluation.mot import evaluate_mot
    from pgm.models import sort, vb_sort

    rows = []
    for q in seqs:
        det, gt, n, fps = sequence(q)
        row = [q]
        for f in FACTORS:
            for module in (sort, vb_sort):
                p = replace(module.Params(), fps=fps, noise="scale",
                            score_map=sort.score_map_for(det.table.conf))
                p = replace(p, meas_std=p.meas_std * f)
                table, _, _ = run_graph(module.build_graph(p), det, n)
                m = evaluate_mot(gt.until(n), table, num_frames=n)
                row.append(f"{m['mota']:.3f} / {m['idf1']:.3f}")
        rows.append(row)
    return rows


def motions(seqs: list[str]) -> list[list]:
    """``sort`` and ``ocsort --report estimate`` with each motion model; the GPDM of each
    sequence learned on the other sequences' ground truth."""
    import tempfile

    from plate_trackers import train_gpdm

    from pgm.evaluation.mot import evaluate_mot
    from pgm.models import ocsort, sort

    tmp = Path(tempfile.mkdtemp())
    rows = []
    for q in seqs:
        det, gt, n, fps = sequence(q)
        cam = camera_motions(q, n)
        model = train_gpdm([s for s in SEQUENCES if s != q and (SHARED_DATA / s).is_dir()],
                           tmp / f"gpdm-without-{q}.npz")
        for core, module, kw in (("sort", sort, {}), ("ocsort --report estimate", ocsort,
                                                      {"report": "estimate"})):
            row = [q, core]
            for motion in ("kalman", "cv", "cv3", "gpdm"):
                p = replace(module.Params(), fps=fps, motion=motion, gpdm=str(model),
                            score_map=sort.score_map_for(det.table.conf), **kw)
                table, secs, _ = run_graph(module.build_graph(p), det, n, motion=cam)
                m = evaluate_mot(gt.until(n), table, num_frames=n)
                row.append(f"{m['mota']:.3f} / {m['idf1']:.3f} ({n / secs:.0f})")
            rows.append(row)
            print("  " + " | ".join(row), flush=True)
    return rows


def choose(seqs: list[str], peer_best: dict[str, tuple[float, float]]) -> list[list]:
    """The default chosen leave one sequence out among the cores × variants, each run as
    ``pgm track`` runs it (the camera's motion compensated where the camera moves); one
    row per held-out sequence."""
    from pgm.evaluation.mot import evaluate_mot
    from pgm.models import sort

    data = {q: sequence(q) for q in seqs}
    motions = {q: camera_motions(q, data[q][2]) for q in seqs}
    from pgm.io.video import open_source

    score: dict[str, dict[str, dict]] = {}
    for core, module, variants in cores():
        for flags, kw in [("", {})] + list(variants) + list(APPEARANCE_VARIANTS):
            label = " ".join(x for x in (core, flags) if x)
            score[label] = {}
            for q in seqs:
                det, gt, n, fps = data[q]
                p = replace(module.Params(), fps=fps, score_map=sort.score_map_for(
                    det.table.conf), **kw)
                images = open_source(SHARED_DATA / q) if kw.get("appearance") else None
                table, _, _ = run_graph(module.build_graph(p), det, n, motion=motions[q],
                                        images=images)
                score[label][q] = evaluate_mot(gt.until(n), table, num_frames=n)
            print(f"  {label}: " + ", ".join(f"{score[label][q]['mota']:.3f}/"
                                             f"{score[label][q]['idf1']:.3f}" for q in seqs),
                  flush=True)

    def obj(label, qs):
        return float(np.mean([(score[label][q]["mota"] + score[label][q]["idf1"]) / 2
                              for q in qs]))

    rows = []
    for held in seqs + ["(all)"]:
        train = [q for q in seqs if q != held]
        best = max(score, key=lambda k: obj(k, train))
        if held == "(all)":
            rows.append(["(chosen on all four)", best, None, None, None, None,
                         round(obj(best, seqs), 4)])
            continue
        m = score[best][held]
        pm, pi = peer_best.get(held, (None, None))
        rows.append([held, best, m["mota"], m["idf1"], pm, pi, round(obj(best, train), 4)])
    ranking = sorted(score, key=lambda k: -obj(k, seqs))
    print_table(["variant"] + [f"{q} MOTA/IDF1" for q in seqs] + ["mean obj"],
                [[k] + [f"{score[k][q]['mota']:.3f}/{score[k][q]['idf1']:.3f}" for q in seqs]
                 + [round(obj(k, seqs), 4)] for k in ranking],
                title="every variant on every sequence (ranked by the mean objective)")
    return rows


def graphs(name: str, fps: float, det, variants: bool) -> list[tuple[str, object]]:
    """The toolkit's rows for a sequence: the cores and (``variants``) their variants."""
    from pgm.models import sort

    smap = sort.score_map_for(det.table.conf)
    out = []
    for label, module, options in cores():
        p = replace(module.Params(), fps=fps, score_map=smap)
        out.append((label, module.build_graph(p)))
        if variants:
            for flags, kw in options:
                out.append((f"{label} {flags}", module.build_graph(replace(p, **kw))))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", default=None, help="comma-separated subset")
    ap.add_argument("--repeats", type=int, default=3, help="timing runs (best is kept)")
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--variants", action="store_true")
    ap.add_argument("--misspecified", action="store_true",
                    help="sort --noise scale against vb-sort with the noise 0.1/1/10 times")
    ap.add_argument("--motions", action="store_true",
                    help="the cores with particle motion models (cv, cv3, a GPDM learned on "
                         "the other sequences) against their Kalman filter")
    ap.add_argument("--vb-choose", action="store_true",
                    help="vb-sort's forgetting factor and prior weight left one sequence out")
    ap.add_argument("--choose", action="store_true",
                    help="choose the default among the variants leave one sequence out")
    args = ap.parse_args()
    single_thread()
    from _peers import SETUP_HINT, peer_python, run_mot_peers

    from pgm.evaluation.mot import evaluate_mot

    seqs = shared_sequences(args.sequences, SEQUENCES)
    peers_ok = not args.no_peers and peer_python() is not None
    if not args.no_peers and not peers_ok:
        print(SETUP_HINT, file=sys.stderr)
    rows, speed = [], []
    for q in seqs:
        det, gt, n, fps = sequence(q)
        gt_q = gt.until(n)
        peer: dict[str, dict] = {}
        if peers_ok:
            best: dict[str, float] = {}
            for _ in range(args.repeats):
                for name, r in run_mot_peers(SHARED_DATA / q, last_frame=n).items():
                    if "error" in r:
                        print(f"{q} {name}: {r['error']}", file=sys.stderr)
                        continue
                    best[name] = max(best.get(name, 0.0), r["fps"])
                    peer[name] = {**evaluate_mot(gt_q, r["table"].until(n), num_frames=n),
                                  "fps": best[name]}
        for label, graph in graphs(q, fps, det, args.variants):
            table, secs, _ = run_graph(graph, det, n)
            for _ in range(args.repeats - 1):
                secs = min(secs, run_graph(graph, det, n)[1])
            _, _, peak = run_graph(graph, det, n, trace=True)
            m = evaluate_mot(gt_q, table, num_frames=n)
            core = label.split()[0]
            ref = peer.get(core)
            rows.append([q, label, m["mota"], m["idf1"], m["hota"], m["id_switches"],
                         None if ref is None else m["mota"] - ref["mota"],
                         None if ref is None else m["idf1"] - ref["idf1"]])
            speed.append([q, label, 1000 * secs / n, n / secs, peak / 2**20,
                          None if ref is None else ref["fps"],
                          None if ref is None else (n / secs) / ref["fps"]])
            print(f"  {q} {label}: MOTA {m['mota']:.4f} IDF1 {m['idf1']:.4f}", flush=True)
        for name, m in peer.items():
            rows.append([q, f"trackers {name}", m["mota"], m["idf1"], m["hota"],
                         m["id_switches"], None, None])
    if args.motions:
        print_table(["sequence", "core", "kalman", "cv", "cv3", "gpdm"], motions(seqs),
                    title="MOTA / IDF1 (frames per second) with the learned or averaged motion "
                          "models of Wang, Yin & Man (2008) in place of the Kalman filter's "
                          "constant velocity")
    if args.vb_choose:
        print_table(["held out", "picked (rho, alpha0)", "MOTA / IDF1", "shipped MOTA / IDF1"],
                    vb_choose(seqs),
                    title="vb-sort's VB settings, leave one sequence out")
    if args.misspecified:
        print_table(["sequence"] + [f"{f:g}x {m}" for f in FACTORS for m in ("sort", "vb-sort")],
                    misspecified(seqs),
                    title="MOTA / IDF1 with the detection noise mis-specified (sort --noise scale "
                          "against vb-sort)")
    if args.choose:
        peer_best = {}
        for q in seqs:
            ms = [r for r in rows if r[0] == q and r[1].startswith("trackers ")]
            if ms:
                peer_best[q] = (max(r[2] for r in ms), max(r[3] for r in ms))
        print_table(["held out", "chosen on the others", "MOTA", "IDF1", "best peer MOTA",
                     "best peer IDF1", "train obj"], choose(seqs, peer_best),
                    title="default multi-target variant, leave one sequence out")
    print_table(["sequence", "tracker", "MOTA", "IDF1", "HOTA", "IDSW", "ΔMOTA", "ΔIDF1"], rows,
                title="SORT / ByteTrack as configs of the engine, against the trackers package "
                      "(Δ: toolkit − package, same detections and scorer)")
    print_table(["sequence", "tracker", "ms/frame", "fps", "peak MiB", "package fps",
                 "ratio"], speed,
                title=f"speed (best of {args.repeats}; the package's update() only, one thread)")


if __name__ == "__main__":
    main()
