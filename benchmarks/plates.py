"""Plate engine: milliseconds per frame for K targets × N particles per target.

Issue 13, item 7. A synthetic 640×480 scene holds ``K`` small two-band objects (24×48
px, each with its own colours) on a fixed 10×5 grid, drifting and wobbling a few pixels
per frame; the first ``K`` grid cells are used, so every target's box (and therefore the
cost of one colour histogram) is the same for every ``K``.

The model is the single-object colour particle filter (``colour_pf.build_graph``: point-
mass prior, damped AR(2), colour histogram with the template learned in frame 1) with
its transition replaced by ``AR2Transition(relative=True)`` (position noise 0.03 of the
box height, sizes fixed) so one shared transition serves every box, and its variable put
in a plate. The engine's replicas are started with ``Engine.add`` on the true
boxes of frame 1 and stepped with ``lifecycle=False``. The comparison runs ``K``
separate single-object ``Engine`` instances of *the same graph* (without the plate, prior
re-centred on one target's box with ``born_at``; the same per-target generators) one
after the other on the same frames, sharing each frame's ``FrameContext`` (so the
frame's colour quantisation is computed once per frame in both). Both therefore do
the same arithmetic (``max |Δ box|`` reports the largest difference in the final boxes;
rounding differences in the batched histogram pass can flip a resampling draw).

Timing: frame 1 (``add`` / the engines' first step) and ``--warmup`` more frames are
stepped untimed, then ``--frames`` frames are timed (``step`` only); the median over
``--repeats`` runs is reported, the plate and separate runs alternating in each repeat.
Peak memory: tracemalloc (Python heap, numpy buffers included; frames excluded) over a
separate plate run — engine construction, ``add`` and every step — since tracemalloc
slows Python down several times.

Goals of the issue (reported, never asserted): the cost per target-particle is roughly
flat as ``K`` grows; a 20-target frame is faster than 20 separate single-object engines
(``separate / plate > 1``).

    .venv/bin/python benchmarks/plates.py [--targets 1,5,20,50] [--particles 20,100]
        [--frames 15] [--warmup 3] [--repeats 3] [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import PeakMemory, machine_note, print_table, single_thread  # noqa: E402

single_thread()

from pgm import FactorGraph, Plate  # noqa: E402
from pgm.core.boxes import BOX_LABELS  # noqa: E402
from pgm.core.frame import FrameContext  # noqa: E402
from pgm.inference import Engine  # noqa: E402
from pgm.models import colour_pf  # noqa: E402
from pgm.synthetic.scene import ObjectSpec, Scene  # noqa: E402

SIZE = (640, 480)
GRID = (10, 5)  # columns × rows: 50 cells of 64×96 px
OBJ = (24, 48)  # object width × height


def scene(k: int, n_frames: int, seed: int = 0):
    """A rendered sequence with ``k`` objects in the first ``k`` cells of the grid."""
    cols, rows = GRID
    if not 1 <= k <= cols * rows:
        raise SystemExit(f"K must be in [1, {cols * rows}], got {k}")
    rng = np.random.default_rng(seed)
    cw, ch = SIZE[0] / cols, SIZE[1] / rows
    objs = []
    for i in range(k):
        r, c = divmod(i, cols)
        x, y = (c + 0.5) * cw - OBJ[0] / 2, (r + 0.5) * ch - OBJ[1] / 2
        colours = tuple(tuple(int(v) for v in rng.integers(0, 256, 3)) for _ in range(2))
        objs.append(ObjectSpec(box=(x, y, *OBJ), colors=colours,
                               velocity=tuple(rng.uniform(-0.5, 0.5, 2)),
                               wobble=(3.0, 3.0), wobble_phase=float(rng.uniform(0, 6.28)),
                               name=f"t{i}"))
    return Scene(objs, [], size=SIZE, name=f"grid-{k}").render(np.random.default_rng(seed), n_frames)


def centre_box(seq, obj: int, frame: int) -> np.ndarray:
    x, y, w, h = seq.box(obj, frame)
    return np.array([x + w / 2, y + h / 2, w, h])


def graphs(box0: np.ndarray, n: int) -> tuple[FactorGraph, FactorGraph]:
    """(the single-object graph with the shared relative transition, its plated twin)."""
    template = colour_pf.build_graph(colour_pf.Params(init_box=tuple(box0), num_particles=n))
    g = FactorGraph(list(template.variables.values()), [
        f if f.kind != "transition" else type(f)("object", noise_std=[0.03, 0.03, 0, 0],
                                                 damping=0.5, relative=True)
        for f in template.factors.values()], name="pf", meta=template.meta)
    plated = FactorGraph(list(g.variables.values()), list(g.factors.values()), name=g.name,
                         meta=g.meta, plates=[Plate("target", tuple(g.variables))])
    return g, plated


def at_box(g: FactorGraph, box: np.ndarray) -> FactorGraph:
    """``g`` with its prior re-centred on ``box`` (one target's single-object graph)."""
    return FactorGraph(list(g.variables.values()), [
        f if f.kind != "prior" else f.born_at(dict(zip(BOX_LABELS, box, strict=True)), BOX_LABELS)
        for f in g.factors.values()], name=g.name, meta=g.meta)


def run_plate(plated, seq, k, n, warmup, seed, trace_memory=False):
    """Seconds in the timed ``step`` calls, final boxes (K, 4) and peak traced MiB."""
    mem = PeakMemory() if trace_memory else None
    if mem is not None:
        mem.__enter__()
    eng = Engine(plated, np.random.default_rng(seed), num_particles=n)
    boxes = np.stack([centre_box(seq, i, 1) for i in range(k)])
    eng.add(boxes, FrameContext(1, seq.frames[0]),
            rngs=[np.random.default_rng([seed, i]) for i in range(k)])
    secs = 0.0
    for f in range(2, seq.n_frames + 1):
        ctx = FrameContext(f, seq.frames[f - 1])
        t0 = time.perf_counter()
        rec = eng.step(ctx, lifecycle=False)
        if f > warmup + 1:
            secs += time.perf_counter() - t0
    if mem is not None:
        mem.__exit__(None, None, None)
    assert eng.num_targets == k
    return secs, rec.estimates["object"][:, :4], (mem.peak_mib if mem else float("nan"))


def run_separate(g, seq, k, n, warmup, seed):
    """Seconds in the timed ``step`` calls of ``k`` engines stepped one after the other,
    and their final boxes (K, 4)."""
    engines = [Engine(at_box(g, centre_box(seq, i, 1)), np.random.default_rng([seed, i]),
                      num_particles=n) for i in range(k)]
    ctx = FrameContext(1, seq.frames[0])
    for e in engines:
        e.step(ctx)
    secs = 0.0
    for f in range(2, seq.n_frames + 1):
        ctx = FrameContext(f, seq.frames[f - 1])
        t0 = time.perf_counter()
        recs = [e.step(ctx) for e in engines]
        if f > warmup + 1:
            secs += time.perf_counter() - t0
    return secs, np.stack([r.estimates["object"][:4] for r in recs])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--targets", default="1,5,20,50", help="K values, comma-separated")
    ap.add_argument("--particles", default="20,100", help="N values, comma-separated")
    ap.add_argument("--frames", type=int, default=15, help="timed frames per run")
    ap.add_argument("--warmup", type=int, default=3, help="untimed frames after frame 1")
    ap.add_argument("--repeats", type=int, default=3, help="runs per setting (median)")
    ap.add_argument("--quick", action="store_true",
                    help="K = 1, 3 and N = 20 over 3 frames, one repeat (for the tests)")
    args = ap.parse_args()
    if args.quick:
        args.targets, args.particles = "1,3", "20"
        args.frames, args.warmup, args.repeats = 3, 1, 1
    ks = [int(v) for v in args.targets.split(",")]
    ns = [int(v) for v in args.particles.split(",")]
    if args.frames < 1 or args.warmup < 0 or args.repeats < 1:
        raise SystemExit("--frames and --repeats must be >= 1, --warmup >= 0")
    n_frames = 1 + args.warmup + args.frames
    print(machine_note())
    rows = []
    per_tp: dict[tuple[int, int], float] = {}
    ratio: dict[tuple[int, int], float] = {}
    for k in ks:
        seq = scene(k, n_frames)
        for n in ns:
            g, plated = graphs(centre_box(seq, 0, 1), n)
            t_plate, t_sep, diffs = [], [], []
            for r in range(args.repeats):
                sp, bp, _ = run_plate(plated, seq, k, n, args.warmup, seed=r)
                ss, bs = run_separate(g, seq, k, n, args.warmup, seed=r)
                t_plate.append(sp)
                t_sep.append(ss)
                diffs.append(float(np.abs(bp - bs).max()))
            peak = run_plate(plated, seq, k, n, args.warmup, seed=0, trace_memory=True)[2]
            ms_p = 1e3 * float(np.median(t_plate)) / args.frames
            ms_s = 1e3 * float(np.median(t_sep)) / args.frames
            per_tp[k, n] = 1e3 * ms_p / (k * n)
            ratio[k, n] = ms_s / ms_p
            rows.append([k, n, ms_p, 1e3 / ms_p, per_tp[k, n], peak, ms_s, ratio[k, n],
                         f"{max(diffs):.2g}"])
    print_table(["K", "N", "plate ms/frame", "plate frames/s", "µs per target-particle",
                 "plate peak MiB (tracemalloc)", "separate ms/frame", "separate / plate",
                 "max |Δ box| px"], rows,
                title=f"one engine with a plate vs K separate engines, colour PF, {SIZE[0]}x{SIZE[1]} "
                      f"synthetic grid, median of {args.repeats} over {args.frames} frames "
                      f"({args.warmup} warm-up frames excluded)")
    print("\ngoals (reported, not asserted):")
    for n in ns:
        flat = [f"K={k}: {per_tp[k, n]:.3g}" for k in ks]
        spread = max(per_tp[k, n] for k in ks) / min(per_tp[k, n] for k in ks)
        print(f"  µs per target-particle flat in K, N={n}: {', '.join(flat)} "
              f"(max/min {spread:.2f})")
    for n in ns:
        if (20, n) in ratio:
            verdict = "faster" if ratio[20, n] > 1 else "NOT faster"
            print(f"  K=20, N={n}: plate {verdict} than 20 separate engines "
                  f"(separate / plate = {ratio[20, n]:.2f})")


if __name__ == "__main__":
    main()
