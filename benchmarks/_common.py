"""Helpers shared by the benchmark scripts (not part of the package)."""

from __future__ import annotations

import os
import sys
import tracemalloc
from pathlib import Path

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def shared_sequences(chosen: str | None, default: tuple[str, ...]) -> list[str]:
    """The sequences to run: ``chosen`` (comma-separated) or ``default``, those present
    under ``../shared/data``; exits with a message when none is."""
    names = chosen.split(",") if chosen else list(default)
    seqs = [q for q in names if (SHARED_DATA / q).is_dir()]
    if not seqs:
        sys.exit(f"none of {names} under {SHARED_DATA}")
    return seqs


def single_thread() -> None:
    """One thread per library, as the reference figures were measured."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    import cv2

    cv2.setNumThreads(1)


def machine_note() -> str:
    """One line about the machine a benchmark ran on (cores, load, versions)."""
    import platform

    import numpy as np

    cpus = os.cpu_count()
    try:
        usable = len(os.sched_getaffinity(0))
    except AttributeError:
        usable = cpus
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (f"machine: {platform.machine()} {platform.processor() or ''} {cpus} logical cores "
            f"({usable} usable, load {load:.1f}), one thread per library "
            f"(OMP/OPENBLAS/MKL/OpenCV = 1), Python {platform.python_version()}, numpy "
            f"{np.__version__}; timings vary with other load on the machine")


def print_table(header: list[str], rows: list[list], title: str | None = None) -> None:
    """Print a plain-text table with right-aligned columns."""
    cells = [[str(c) for c in header]] + [[_fmt(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    if title:
        print(f"\n{title}")
    print("  ".join(h.rjust(w) for h, w in zip(cells[0], widths, strict=True)))
    print("  ".join("-" * w for w in widths))
    for r in cells[1:]:
        print("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)))


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.3g}" if abs(v) < 100 else f"{v:.1f}"
    return str(v)


class PeakMemory:
    """Peak Python-heap allocation (tracemalloc; numpy buffers included) in MiB."""

    def __enter__(self):
        tracemalloc.start()
        return self

    def __exit__(self, *exc):
        self.peak_mib = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()


def time_engine(engine, frames, trace_memory: bool = False, scores: list | None = None):
    """Step ``engine`` through decoded ``frames``; time ``engine.step`` only.

    Returns top-left boxes ``(T, 4)``, seconds in ``engine.step`` and the peak traced
    memory in MiB (NaN unless ``trace_memory``: tracemalloc slows Python down several
    times, so timing runs leave it off). ``scores``: a list to which each frame's score
    (the model's calibrated confidence, 1 where it declares none) is appended.
    """
    import time

    import numpy as np

    from pgm.app.runner import output_target
    from pgm.core.frame import FrameContext

    boxes, secs = [], 0.0
    mem = PeakMemory() if trace_memory else None
    if mem is not None:
        mem.__enter__()
    for number, image in frames:
        ctx = FrameContext(number, image)
        t0 = time.perf_counter()
        rec = engine.step(ctx)
        secs += time.perf_counter() - t0
        box, score = output_target(engine.graph, rec)  # top-left x, y, w, h
        boxes.append(box)
        if scores is not None:
            scores.append(score)
    if mem is not None:
        mem.__exit__(None, None, None)
    return np.array(boxes), secs, (mem.peak_mib if mem is not None else float("nan"))
