"""What the annotated video costs a run, end to end.

The multi-target default on one shared sequence (MOT16-11, 1920x1080, by default), as
``pgm track SEQ --out DIR`` runs it, three ways in one process:

* ``no video``: ``--no-video``;
* ``video``: the annotated video as it is written now — scaled so that its long side is
  at most 1280 px and encoded by a thread of its own;
* ``video, full size, in the loop``: as it was written before (every frame at full
  resolution, encoded between two frames of the tracker).

and the time to only decode the frames. Printed: wall seconds (from the first frame read
to the last row and video frame written), end-to-end frames per second, the ratio to
``no video`` in the same run, and the peak resident memory of the process so far.

    python benchmarks/video_cost.py [--sequence MOT16-11] [--max-frames N]
"""

from __future__ import annotations

import argparse
import functools
import resource
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, machine_note, print_table  # noqa: E402

import pgm.app.runner as runner  # noqa: E402
from pgm.app.cli import main as pgm_main  # noqa: E402
from pgm.io.annotated_video import AnnotatedVideoWriter  # noqa: E402
from pgm.io.video import open_source  # noqa: E402


def peak_mib() -> float:
    """The process's peak resident memory so far (MiB; Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run(seq: Path, out: Path, extra: list[str]) -> float:
    t0 = time.perf_counter()
    code = pgm_main(["track", str(seq), "--out", str(out), "--quiet", *extra])
    if code != 0:
        raise SystemExit(f"pgm track {seq} failed ({code})")
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sequence", default="MOT16-11")
    ap.add_argument("--max-frames", type=int, default=None)
    args = ap.parse_args()
    seq = SHARED_DATA / args.sequence
    if not seq.is_dir():
        raise SystemExit(f"{seq} not found")
    limit = ["--max-frames", str(args.max_frames)] if args.max_frames else []
    src = open_source(seq)
    t0 = time.perf_counter()
    n = sum(1 for k, _ in zip(range(args.max_frames or 10 ** 9), src.frames(), strict=False))
    decode = time.perf_counter() - t0
    rows = [["decode only", f"{decode:.1f}", f"{n / decode:.1f}", "", f"{peak_mib():.0f}"]]
    with tempfile.TemporaryDirectory() as tmp:
        base = run(seq, Path(tmp) / "a", ["--no-video", *limit])
        rows.append(["no video", f"{base:.1f}", f"{n / base:.1f}", "1.00", f"{peak_mib():.0f}"])
        wall = run(seq, Path(tmp) / "b", limit)
        rows.append(["video (≤1280 px, own thread)", f"{wall:.1f}", f"{n / wall:.1f}",
                     f"{wall / base:.2f}", f"{peak_mib():.0f}"])
        runner.AnnotatedVideoWriter = functools.partial(AnnotatedVideoWriter, scale=1.0,
                                                        background=False)
        try:
            old = run(seq, Path(tmp) / "c", limit)
        finally:
            runner.AnnotatedVideoWriter = AnnotatedVideoWriter
        rows.append(["video, full size, in the loop", f"{old:.1f}", f"{n / old:.1f}",
                     f"{old / base:.2f}", f"{peak_mib():.0f}"])
    print_table(["run", "wall s", "frames/s", "x no video", "peak MiB"], rows,
                title=f"{args.sequence}, {n} frames {src.size[0]}x{src.size[1]}, the default "
                      f"multi-target model; {machine_note()}")


if __name__ == "__main__":
    main()
