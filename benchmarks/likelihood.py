"""Colour-histogram likelihood benchmark: µs per candidate box.

Prints the columns of the "Colour-histogram likelihood" table of
``shared/bench/README.md`` so the two can be set side by side:

(a) ``ours``: :meth:`pgm.observation.appearance.colour.ColourHistogramScorer.rho` (integral
    histograms over the union of the boxes, template bins only), the frame already
    quantised (its fixed per-frame cost is printed separately);
(b) ``calcHist``: per box, ``cv2.calcHist`` of the HSV image's ROI slice, 16x4x4 bins,
    no mask, normalise, Bhattacharyya (the HSV conversion excluded, as in the README);
(c) ``q+calcHist``: the frame quantised once, then per box ``cv2.calcHist`` of the
    bin image's ROI slice;
and the ratio (b)/(a). ``epan`` and ``grid-u`` are the grid-approximated kernels
(16x16 samples per box). ``peak KiB`` is the tracemalloc peak of one (a) call,
its reusable scratch buffers included (allocated afresh for the measurement).

Fixed per-frame cost: the scorer quantises lazily only the union rectangle of the
boxes (plus a small margin), once per frame and layout. ``ROI q ms`` is that
quantisation for the row's boxes (a fresh frame, nothing quantised yet); ``frame ms``
is a whole (a) call on a fresh ``FrameContext`` (ROI quantisation + scoring: the real
per-frame cost of one likelihood factor). The full-frame quantisation (what a
full-frame ``bins()`` call costs) is printed above each table for comparison.

Boxes are ``--box`` (40x80) with centres drawn N(point, sigma^2) around the first
ground-truth person of PETS09-S2L1 frame 1 (scaled to the frame size); the frame is
that PETS frame resized with ``cv2.resize`` (a random image when the data are absent).
Best of ``--repeats``; one thread (``cv2.setNumThreads(1)``, BLAS threads 1).

``--alternatives`` also times ways of building the integral-histogram cube for the
union rectangle of the N = 1000 boxes (the step that dominates (a)).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from pgm.core.frame import FrameContext  # noqa: E402
from pgm.observation.appearance.colour import ColourHistogramScorer, quantize_colour  # noqa: E402
from pgm.observation.appearance.colour.cache import _FrameBins  # noqa: E402
from pgm.observation.appearance.colour.integral import (  # noqa: E402
    _ROI_MARGIN,
    _bounds,
    _clear_scratch,
    _union_of,
)

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "PETS09-S2L1"


def _size(text: str) -> tuple[int, int]:
    w, h = text.lower().split("x")
    return int(w), int(h)


def best_of(repeats: int, fn, *args) -> float:
    """Best wall time of ``repeats`` calls ``fn(*args)``, seconds."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn(*args)
        best = min(best, time.perf_counter() - t0)
    return best


def load_frame(width: int, height: int) -> tuple[np.ndarray, np.ndarray, str]:
    """Frame resized to ``width x height`` and the point the boxes scatter around."""
    path = DATA / "img1" / "000001.jpg"
    img = cv2.imread(str(path)) if path.exists() else None
    if img is None:
        rng = np.random.default_rng(2024)
        return (rng.integers(0, 256, (height, width, 3), dtype=np.uint8),
                np.array([width / 2, height / 2]), "random image")
    point = np.array([img.shape[1] / 2, img.shape[0] / 2])
    gt = DATA / "gt" / "gt.txt"
    if gt.exists():
        rows = np.loadtxt(gt, delimiter=",", ndmin=2)
        r = rows[rows[:, 0] == 1][0]
        point = np.array([r[2] - 1 + r[4] / 2, r[3] - 1 + r[5] / 2])   # 1-based x, y
    scale = np.array([width / img.shape[1], height / img.shape[0]])
    frame = cv2.resize(img, (width, height), interpolation=cv2.INTER_AREA)
    return frame, point * scale, f"{path.parent.parent.name} frame 1 resized"


def make_boxes(rng, n: int, point, box, sigma: float) -> np.ndarray:
    c = point[None, :] + sigma * rng.standard_normal((n, 2))
    return np.column_stack([c, np.full(n, float(box[0])), np.full(n, float(box[1]))])


def int_bounds(boxes: np.ndarray, height: int, width: int):
    """The same integer bounds as the toolkit (round half up, clipped)."""
    x0 = np.floor(boxes[:, 0] - boxes[:, 2] / 2 + 0.5)
    x1 = np.maximum(np.floor(boxes[:, 0] + boxes[:, 2] / 2 + 0.5), x0 + 1)
    y0 = np.floor(boxes[:, 1] - boxes[:, 3] / 2 + 0.5)
    y1 = np.maximum(np.floor(boxes[:, 1] + boxes[:, 3] / 2 + 0.5), y0 + 1)
    return (np.clip(x0, 0, width).astype(int), np.clip(x1, 0, width).astype(int),
            np.clip(y0, 0, height).astype(int), np.clip(y1, 0, height).astype(int))


def per_box_calchist_hsv(hsv: np.ndarray, bounds, q_hist: np.ndarray) -> np.ndarray:
    """(b): per box, cv2.calcHist of the HSV ROI (16x4x4 bins, no mask), then
    rho = 1 - d^2 from cv2.compareHist(HISTCMP_BHATTACHARYYA), which normalises both
    histograms itself (the cheapest per-box loop OpenCV allows)."""
    xa, xb, ya, yb = bounds
    out = np.zeros(len(xa))
    for i in range(len(xa)):
        roi = hsv[ya[i]:yb[i], xa[i]:xb[i]]
        if roi.size == 0:
            continue
        h = cv2.calcHist([roi], [0, 1, 2], None, [16, 4, 4], [0, 180, 0, 256, 0, 256])
        d = cv2.compareHist(h, q_hist, cv2.HISTCMP_BHATTACHARYYA)
        out[i] = 1.0 - d * d
    return out


def per_box_calchist_bins(bins: np.ndarray, n_bins: int, bounds,
                          q_hist: np.ndarray) -> np.ndarray:
    """(c): the frame quantised once, then per box cv2.calcHist of the bin image's
    ROI and cv2.compareHist."""
    xa, xb, ya, yb = bounds
    out = np.zeros(len(xa))
    for i in range(len(xa)):
        roi = bins[ya[i]:yb[i], xa[i]:xb[i]]
        if roi.size == 0:
            continue
        h = cv2.calcHist([roi], [0], None, [n_bins], [0, n_bins])
        d = cv2.compareHist(h, q_hist, cv2.HISTCMP_BHATTACHARYYA)
        out[i] = 1.0 - d * d
    return out


# --- integral-cube alternatives (--alternatives) -----------------------------------------

def _cube_numpy_cumsum(crop, slots, k, dtype):
    h, w = crop.shape
    cube = np.zeros((h + 1, w + 1, k + 1), dtype)
    cube[1:, 1:].reshape(-1, k + 1)[np.arange(h * w), slots[crop].ravel()] = 1
    np.cumsum(cube, axis=0, out=cube)
    np.cumsum(cube, axis=1, out=cube)
    return cube


def _cube_numpy_loops(crop, slots, k, dtype):
    h, w = crop.shape
    cube = np.zeros((h + 1, w + 1, k + 1), dtype)
    cube[1:, 1:].reshape(-1, k + 1)[np.arange(h * w), slots[crop].ravel()] = 1
    for i in range(1, h + 1):
        np.add(cube[i - 1], cube[i], out=cube[i])
    for j in range(1, w + 1):
        np.add(cube[:, j - 1], cube[:, j], out=cube[:, j])
    return cube


def _cube_cv2_pixel_major(crop, slots, k):
    h, w = crop.shape
    outs = []
    for c0 in range(0, k + 1, 128):                  # cv2 takes at most 128 channels
        c1 = min(k + 1, c0 + 128)
        oh = np.zeros((h, w, c1 - c0), np.uint8)
        s = slots[crop]
        m = (s >= c0) & (s < c1)
        oh.reshape(-1, c1 - c0)[np.flatnonzero(m), s[m] - c0] = 1
        outs.append(cv2.integral(oh, sdepth=cv2.CV_32S))
    return outs


def _cube_cv2_bin_major(crop, slots, k, cn):
    h, w = crop.shape
    g = -(-k // cn)
    plane = h * w * cn
    s = np.arange(k + 1)
    off = np.where(s < k, (s // cn) * plane + s % cn, g * plane)
    lin = np.take(off[slots], crop) + np.arange(0, plane, cn).reshape(h, w)
    oh = np.zeros((g + 1) * plane, np.uint8)
    oh[lin.ravel()] = 1
    return cv2.integral(oh[:g * plane].reshape(g * h, w, cn), sdepth=cv2.CV_32S)


def alternatives(bins, n_bins, q, boxes, repeats):
    height, width = bins.shape
    xa, xb, ya, yb = int_bounds(boxes, height, width)
    crop = bins[ya.min():yb.max(), xa.min():xb.max()]
    print(f"\n  integral cube over the union ({crop.shape[1]}x{crop.shape[0]}) of "
          f"N={len(boxes)} boxes, ms (best of {repeats}):")
    support = np.flatnonzero(q > 0)
    for label, sel in (("all bins", np.arange(n_bins)), ("template bins", support)):
        k = len(sel)
        slots = np.full(n_bins, k, np.intp)
        slots[sel] = np.arange(k)
        cases = [
            ("np.cumsum int32 pixel-major", _cube_numpy_cumsum, np.int32),
            ("np.cumsum uint16 pixel-major", _cube_numpy_cumsum, np.uint16),
            ("np.add row/col loops uint16", _cube_numpy_loops, np.uint16),
            ("cv2.integral pixel-major", _cube_cv2_pixel_major),
            ("cv2.integral bin planes (cn=1)", _cube_cv2_bin_major, 1),
            ("cv2.integral groups of 4 (used)", _cube_cv2_bin_major, 4),
        ]
        print(f"    {label} ({k}):", ", ".join(
            f"{c[0]} {best_of(repeats, c[1], crop, slots, k, *c[2:]) * 1e3:.2f}" for c in cases))


# --- main --------------------------------------------------------------------------------

def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="384x288,768x576")
    ap.add_argument("--n", default="30,100,300,1000,3000")
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--layout", default="hsv,perez",
                    help="comma-separated layouts for (a): perez, hsv, rgb")
    ap.add_argument("--box", default="40x80", help="box size WxH")
    ap.add_argument("--sigma", type=float, default=20.0)
    ap.add_argument("--no-kernels", action="store_true",
                    help="skip the grid-kernel columns")
    ap.add_argument("--alternatives", action="store_true",
                    help="also time integral-cube construction alternatives")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    sizes = [_size(s) for s in args.sizes.split(",")]
    ns = [int(n) for n in args.n.split(",")]
    box = _size(args.box)
    layouts = args.layout.split(",")

    for layout in layouts:
        print(f"\n## layout {layout!r} (ours) vs per-box cv2.calcHist HSV 16x4x4; "
              f"boxes {box[0]}x{box[1]}, sigma {args.sigma:g} px; µs per box, best of "
              f"{args.repeats}")
        for width, height in sizes:
            frame, point, source = load_frame(width, height)
            scorer = ColourHistogramScorer(layout)
            kernels = {k: ColourHistogramScorer(layout, kernel=k)
                       for k in ("epanechnikov", "grid-uniform")}
            quant = best_of(args.repeats, quantize_colour, frame, layout)
            hsv_t = best_of(args.repeats, cv2.cvtColor, frame, cv2.COLOR_BGR2HSV)
            ctx = FrameContext(1, frame)
            bins = scorer.bins(ctx)                    # per-frame work done once
            t_box = np.array([point[0], point[1], box[0], box[1]])
            q = scorer.template(ctx, t_box)
            hsv = cv2.cvtColor(frame, cv2.COLOR_BGR2HSV)
            hsv_scorer = ColourHistogramScorer("hsv")
            q_hsv = hsv_scorer.template(frame, t_box).astype(np.float32)
            q_hsv = q_hsv.reshape(16, 4, 4)
            q_bins = q.astype(np.float32)
            for s in kernels.values():
                s.q = q
            print(f"\n{width}x{height} ({source}); full-frame quantisation "
                  f"{quant * 1e3:.2f} ms (of which cvtColor {hsv_t * 1e3:.2f} ms); "
                  f"template occupies {np.count_nonzero(q)} of {scorer.n_bins} bins")
            head = (f"{'size':>9} {'N':>5} {'(a) ours':>9} {'(b) calcHist':>12} "
                    f"{'(c) q+calcHist':>14} {'(b)/(a)':>8}")
            if not args.no_kernels:
                head += f" {'epan':>7} {'grid-u':>7}"
            print(head + f" {'peak KiB':>9} {'ROI q ms':>9} {'frame ms':>9}")
            rng = np.random.default_rng(7)
            for n in ns:
                boxes = make_boxes(rng, n, point, box, args.sigma)
                bounds = int_bounds(boxes, height, width)
                ta = best_of(args.repeats, scorer.rho, ctx, boxes)
                reps = max(3, args.repeats // 3)
                tb = best_of(reps, per_box_calchist_hsv, hsv, bounds, q_hsv)
                tc = best_of(reps, per_box_calchist_bins, bins, scorer.n_bins, bounds,
                             q_bins)
                if layout == "hsv":                    # (a) and (b) compute the same
                    assert np.allclose(scorer.rho(ctx, boxes),
                                       per_box_calchist_hsv(hsv, bounds, q_hsv)
                                       * _in_frac(boxes, height, width), atol=1e-5)
                _clear_scratch()                       # peak including the scratch
                tracemalloc.start()
                scorer.rho(ctx, boxes)
                peak = tracemalloc.get_traced_memory()[1]
                tracemalloc.stop()
                us = 1e6 / n
                line = (f"{width}x{height:<3} {n:>5} {ta * us:>9.2f} {tb * us:>12.2f} "
                        f"{tc * us:>14.2f} {tb / ta:>8.1f}")
                if not args.no_kernels:
                    te = best_of(args.repeats, kernels["epanechnikov"].rho, ctx, boxes)
                    tg = best_of(args.repeats, kernels["grid-uniform"].rho, ctx, boxes)
                    line += f" {te * us:>7.2f} {tg * us:>7.2f}"
                tq = best_of(args.repeats, roi_quantisation, frame, scorer, boxes)
                tf = best_of(args.repeats, fresh_frame_rho, frame, scorer, boxes)
                print(line + f" {peak / 1024:>9.0f} {tq * 1e3:>9.3f} {tf * 1e3:>9.3f}")
            if args.alternatives:
                alternatives(bins, scorer.n_bins, q,
                             make_boxes(np.random.default_rng(7), 1000, point, box,
                                        args.sigma), max(3, args.repeats // 3))


def roi_quantisation(frame: np.ndarray, scorer: ColourHistogramScorer,
                     boxes: np.ndarray) -> None:
    """The lazy scheme's fixed per-frame work for these boxes: quantise the union
    rectangle of the boxes (plus the margin) of a frame with nothing quantised yet."""
    ints, inside, _ = _bounds(boxes, *frame.shape[:2])
    union, _ = _union_of(ints, inside)
    if union is not None:
        _FrameBins(frame, scorer._canon).ensure(*union, margin=_ROI_MARGIN)


def fresh_frame_rho(frame: np.ndarray, scorer: ColourHistogramScorer,
                    boxes: np.ndarray) -> None:
    """One likelihood evaluation on a new frame: ROI quantisation plus scoring."""
    scorer.rho(FrameContext(1, frame), boxes)


def _in_frac(boxes, height, width):
    xa, xb, ya, yb = int_bounds(boxes, height, width)
    x0 = np.floor(boxes[:, 0] - boxes[:, 2] / 2 + 0.5)
    x1 = np.maximum(np.floor(boxes[:, 0] + boxes[:, 2] / 2 + 0.5), x0 + 1)
    y0 = np.floor(boxes[:, 1] - boxes[:, 3] / 2 + 0.5)
    y1 = np.maximum(np.floor(boxes[:, 1] + boxes[:, 3] / 2 + 0.5), y0 + 1)
    return (xb - xa) * (yb - ya) / ((x1 - x0) * (y1 - y0))


if __name__ == "__main__":
    main()
