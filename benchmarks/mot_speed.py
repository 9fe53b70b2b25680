"""Speed of the multi-target default against the six peers, inference and end to end.

    python benchmarks/mot_speed.py [--sequences MOT16-11,PETS09-S2L1] [--model NAME]
                                   [--no-peers]

On each sequence (public detections; MOT16-11 is 1920x1080), in one run:

* the toolkit's model (default: the multi-target default, built and run as ``pgm track``
  builds and runs it for the sequence): **inference** frames per second (``engine.step``
  only, as ``pgm track`` reports it), the wall time of the same run in this process
  (decoding and the camera's motion included) and its peak traced memory; **end to
  end**, the wall time of ``pgm track SEQ --no-video`` in a fresh process (start-up,
  decoding, camera motion, inference, writing) and of the same with the annotated video;
* the six trackers of the ``trackers`` package (their own venv): frames per second of
  ``tracker.update`` (CMC included for BoT-SORT and McByte) and end to end (the wall
  time of their subprocess per tracker, reading the detections and, for the two with
  camera-motion compensation, decoding the frames).

Columns: ms per frame, frames per second, peak memory (MiB; the toolkit's run: traced
Python heap, numpy buffers included, in a second, traced run; end to end: the process's
maximum resident set), and the ratio of
frames per second to the package's OC-SORT measured in this run (the baseline).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, PeakMemory, machine_note, print_table, single_thread  # noqa: E402

single_thread()

SEQUENCES = ("MOT16-11", "PETS09-S2L1")


def toolkit_inference(name: str, model: str) -> dict:
    """Inference frames/s (``engine.step`` only, as ``pgm track`` reports it) and the peak
    traced memory of a ``pgm track`` run of ``model`` on ``name`` in this process
    (:func:`pgm.app.runner.track_multi`; decoding and the camera's motion are not in the
    inference time, the memory includes them)."""
    import numpy as np

    from pgm.app.runner import track_multi
    from pgm.io.video import open_source
    from pgm.models import get_config
    from pgm.models.config import VideoInfo
    from pgm.observation.detections import PublicDetections

    src = open_source(SHARED_DATA / name)
    det = PublicDetections(SHARED_DATA / name / "det" / "det.txt")
    graph = get_config(model).graph_for({}, VideoInfo(
        *src.size, fps=src.fps, score_range=det.score_range,
        typical_height=float(np.median(det.table.boxes[:, 3]))))
    t0 = time.perf_counter()
    result = track_multi(src, graph, det, rng=0, write_video=False, progress=False)
    wall = time.perf_counter() - t0
    with PeakMemory() as mem:  # a second run, traced (tracemalloc slows it down)
        track_multi(open_source(SHARED_DATA / name), graph, det, rng=0, write_video=False,
                    progress=False)
    return {"frames": result.n_frames, "seconds": result.inference_seconds,
            "peak_mib": mem.peak_mib, "wall": wall}


def toolkit_end_to_end(name: str, model: str, video: bool) -> dict:
    """Wall time and maximum resident set of ``pgm track`` in a fresh process."""
    with tempfile.TemporaryDirectory() as tmp:
        # the CLI in a fresh interpreter that reports its own maximum resident set
        cmd = [sys.executable, "-c", _CLI_WITH_RSS, "track", str(SHARED_DATA / name),
               "--model", model, "--out", tmp, "--quiet"] + ([] if video else ["--no-video"])
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True)
        secs = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"pgm track failed: {r.stderr[-2000:]}")
    rss = [line.split()[1] for line in r.stderr.splitlines() if line.startswith("MAXRSS ")]
    return {"seconds": secs, "rss_mib": float(rss[-1]) / 1024.0 if rss else float("nan")}


#: the CLI in a fresh interpreter reporting its own peak resident set in KiB: the VmHWM of
#: its address space (Linux), since ``ru_maxrss`` keeps the parent's peak across ``exec``
_CLI_WITH_RSS = ("import resource, sys\n"
                 "from pgm.app.cli import main\n"
                 "code = main(sys.argv[1:])\n"
                 "try:\n"
                 "    hwm = [ln.split()[1] for ln in open('/proc/self/status')\n"
                 "           if ln.startswith('VmHWM:')][0]\n"
                 "except (OSError, IndexError):\n"
                 "    hwm = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
                 "print('MAXRSS', hwm, file=sys.stderr)\n"
                 "sys.exit(code)\n")


def peers(name: str, n: int) -> dict[str, dict]:
    """The six peers: update-only frames/s and each subprocess's wall time."""
    from _peers import MOT_PEERS, run_mot_peers

    out = {}
    for peer in MOT_PEERS:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            r = run_mot_peers(SHARED_DATA / name, last_frame=n, trackers=(peer,), workdir=tmp)
            wall = time.perf_counter() - t0
        res = r[peer]
        out[peer] = {"error": res["error"]} if "error" in res else {
            "fps": res["fps"], "wall": wall}
    return out


def main(argv: list[str] | None = None) -> int:
    from pgm.models import DEFAULT_MULTI_TARGET

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sequences", default=",".join(SEQUENCES))
    ap.add_argument("--model", default=DEFAULT_MULTI_TARGET)
    ap.add_argument("--no-peers", action="store_true", help="the toolkit's rows only")
    args = ap.parse_args(argv)
    print(machine_note())
    for name in args.sequences.split(","):
        if not (SHARED_DATA / name).is_dir():
            print(f"{name}: not in {SHARED_DATA}, skipped")
            continue
        inf = toolkit_inference(name, args.model)
        n = inf["frames"]
        e2e = toolkit_end_to_end(name, args.model, video=False)
        e2e_video = toolkit_end_to_end(name, args.model, video=True)
        ps = {} if args.no_peers else peers(name, n)
        base = ps.get("ocsort", {}).get("fps")
        rows = []

        def row(label, secs, mem="-", n=n, rows=rows, base=base):
            fps = n / secs
            rows.append([label, f"{1000 * secs / n:.2f}", f"{fps:.1f}", mem,
                         f"{fps / base:.3f}" if base else "-"])

        row(f"{args.model}: inference", inf["seconds"], f"{inf['peak_mib']:.0f}")
        row(f"{args.model}: run in this process (+ decoding, camera motion)", inf["wall"])
        row(f"{args.model}: end to end, no video", e2e["seconds"], f"{e2e['rss_mib']:.0f}")
        row(f"{args.model}: end to end, with video", e2e_video["seconds"],
            f"{e2e_video['rss_mib']:.0f}")
        for peer, r in ps.items():
            if "error" in r:
                rows.append([f"{peer} (trackers)", "-", "-", "-", r["error"][:60]])
                continue
            row(f"{peer} (trackers): update", n / r["fps"])
            row(f"{peer} (trackers): end to end", r["wall"])
        print_table(["", "ms/frame", "frames/s", "peak MiB", "x OC-SORT (trackers)"], rows,
                    title=f"{name}: {n} frames")
    return 0


if __name__ == "__main__":
    sys.exit(main())
