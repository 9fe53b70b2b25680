"""SORT and ByteTrack as model configs of the engine, against the ``trackers`` package.

    python benchmarks/classic_trackers.py [--sequences A,B] [--repeats 3] [--no-peers]
                                          [--variants]

On each shared MOT sequence (all frames, public detections, every row), the toolkit's
``sort`` and ``bytetrack`` configs (:mod:`pgm.models.sort`, :mod:`pgm.models.bytetrack`:
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

``--variants``: also every variant of the cores (``--vb-noise``, ``--box-state xysr``).
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, print_table, single_thread  # noqa: E402

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


def run_graph(graph, det, num_frames: int, seed: int = 0, trace: bool = False):
    """Run ``graph`` on the detections of frames ``1..num_frames``; returns the tracks
    table, the inference seconds and (``trace``) the peak traced memory in bytes."""
    import tracemalloc

    from pgm.core.frame import FrameContext
    from pgm.core.readout import readout
    from pgm.inference import Engine
    from pgm.io.annotations import MotTable

    engine = Engine(graph, seed)
    frames = [FrameContext(n, detections=det(n)) for n in range(1, num_frames + 1)]
    rows_f, rows_i, rows_b, rows_c = [], [], [], []
    if trace:
        tracemalloc.start()
    secs = 0.0
    for ctx in frames:
        t0 = time.perf_counter()
        record = engine.step(ctx)
        secs += time.perf_counter() - t0
        t = readout(engine.graph, record)
        rows_f += [ctx.index] * len(t.ids)
        rows_i += t.ids.tolist()
        rows_b += t.boxes.tolist()
        rows_c += t.scores.tolist()
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
)


def graphs(name: str, fps: float, det, variants: bool) -> list[tuple[str, object]]:
    """The toolkit's rows for a sequence: the cores and (``variants``) their variants."""
    from pgm.models import bytetrack, sort

    smap = sort.score_map_for(det.table.conf)
    out = []
    for label, module in (("sort", sort), ("bytetrack", bytetrack)):
        p = replace(module.Params(), fps=fps, score_map=smap)
        out.append((label, module.build_graph(p)))
        if variants:
            for flags, kw in VARIANTS:
                out.append((f"{label} {flags}", module.build_graph(replace(p, **kw))))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", default=None, help="comma-separated subset")
    ap.add_argument("--repeats", type=int, default=3, help="timing runs (best is kept)")
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--variants", action="store_true")
    args = ap.parse_args()
    single_thread()
    from _peers import SETUP_HINT, peer_python, run_mot_peers

    from pgm.evaluation.mot import evaluate_mot

    seqs = [q for q in (args.sequences.split(",") if args.sequences else SEQUENCES)
            if (SHARED_DATA / q).is_dir()]
    if not seqs:
        sys.exit(f"no shared MOT sequence under {SHARED_DATA}")
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
    print_table(["sequence", "tracker", "MOTA", "IDF1", "HOTA", "IDSW", "ΔMOTA", "ΔIDF1"], rows,
                title="SORT / ByteTrack as configs of the engine, against the trackers package "
                      "(Δ: toolkit − package, same detections and scorer)")
    print_table(["sequence", "tracker", "ms/frame", "fps", "peak MiB", "package fps",
                 "ratio"], speed,
                title=f"speed (best of {args.repeats}; the package's update() only, one thread)")


if __name__ == "__main__":
    main()
