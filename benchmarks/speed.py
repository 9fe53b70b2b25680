"""Speed where users run it: the defaults end to end at their native resolution, the peers in
the same run.

    python benchmarks/speed.py [--sections mot,camera,memory,sot,phd] [--sequences A,B]
                               [--sot A,B] [--frames N] [--repeats 3] [--no-peers] [--seeds 3]
                               [--memory-frames 6000]

``mot`` — on each shared MOT sequence (public detections, native resolution; MOT16-11 is
1920x1080): the time to only **decode** its frames (one thread, one frame after another,
each held until the next is decoded as a tracker holds it: the baseline), then for the
multi-target default and each classic core, run as ``pgm track`` runs them
(:func:`pgm.app.runner.track_multi`, tracks written, no video): **inference** frames/s
(``engine.step`` plus the camera's motion) and **end to end** frames/s (from the first
frame read to the last row written), the median of ``--repeats`` runs
interleaved with as many decoding runs (the machine's speed drifts: only ratios measured
side by side mean much); the default's ``engine.step`` and camera motion *alone*, on the
first 150 frames decoded beforehand (no decoding thread sharing the two cores), scaled to
the sequence's length; the whole ``pgm track SEQ --no-video`` process (start-up and
evaluation included) with its maximum resident set; the six ``trackers`` peers'
``update`` frames/s on the same detections (their own venv,
``bash benchmarks/peers/setup_env.sh``). On the largest sequence, the default's resident
memory is sampled through a run: its peak over the first and the second half says whether
memory stays flat over a video's length.

``memory`` — the multi-target default's engine over a long synthetic stream
(``--memory-frames``, default 6 000: people born at random, walking for 2 to 10 seconds,
on a fixed 640x480 image): the Python allocations it holds (``tracemalloc``) and the
process's resident set at a quarter, a half and the whole of the stream, and the growth per
1 000 frames between the first and the last — whether memory stays flat over a long video,
past the 300 frames of the ``mot`` section's sample.

``camera`` — the camera's motion on the shared moving-camera sequence (MOT16-11), estimated
as before issue 39 (every frame shrunk to 640 wide, 400 corners found anew) and as now
(halved to 480 wide, 200 corners followed), each against a finer estimate (960 wide, 1000
corners): ms per frame and the corner error.

``sot`` — on each single-object sequence (its first ``--frames`` frames): the single-object
default's inference frames/s (``engine.step``; decoding excluded) against OpenCV's CSRT,
KCF and MIL (``update`` only; the peers' venv), each the median of ``--repeats`` runs
interleaved, and the ratio to CSRT.

``phd`` — the reference multi-target scenario (``../shared/bench``): the PHD filter at the
nominal particle counts of the bench's Stone Soup SMC-PHD rows (10^3, 5·10^3, 2·10^4) and
Stone Soup 1.9.1's SMC-PHD itself in the same run (the peers' venv,
``peers/phd_peers.py``: per-measurement extraction as the bench README's figures), ms per
step (the filter: median over ``--seeds`` seeds) and OSPA(50, 1) by the toolkit's metric
for both, and the ratio of the times (to the README's figure where Stone Soup is not
installed); then the filter's speed and accuracy over particle counts from 250 to 2·10^4,
and, for each Stone Soup row, the cheapest of them at or below its OSPA (the speed ratio at
equal or better accuracy), with the filter's per-measurement extraction and with its
confirmed tracks, plain and with regularised resampling.

Columns: ms per frame, frames per second, peak memory (MiB, maximum resident set of a fresh
process), and the ratios named in each table's header.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import SHARED_DATA, machine_note, print_table, single_thread  # noqa: E402

single_thread()

MOT_SEQUENCES = ("MOT16-11", "PETS09-S2L1", "PETS09-S2L1-video", "TUD-Campus",
                 "TUD-Stadtmitte")
SOT_SEQUENCES = ("David", "FaceOcc1", "Tiger1", "Girl", "Crossing", "Biker", "MotorRolling",
                 "UAV10-group3")
CORES = ("sort", "bytetrack", "ocsort", "botsort", "cbiou")
BENCH = Path(__file__).resolve().parents[2] / "shared" / "bench"


# decoding ----------------------------------------------------------------------------
def decode_seconds(name: str) -> tuple[float, int]:
    """Seconds to decode every frame of ``name`` in this thread, one after another (the
    toolkit's own decoding, without its read-ahead thread), and the frame count.

    Each frame is held until the next is decoded, as a tracker holds the frame it works
    on: a loop that drops each 1080p frame before decoding the next paid about 3 ms more a
    frame (9.4 against 6.4 ms on MOT16-11, this machine), the allocator handing the
    process fresh pages for every frame, which made decoding look slower than it is in a
    run."""
    from pgm.io import video

    src = video.open_source(SHARED_DATA / name)
    t0 = time.perf_counter()
    n = 0
    if isinstance(src, video.ImageSequenceSource):
        held: list = [None]  # the last frame, held until the next is decoded
        for path in src.files:
            held[0] = video._read_image(path)
            n += 1
    else:
        for _ in src._decode(1, None):
            n += 1
    return time.perf_counter() - t0, n


# the toolkit's multi-target runs -------------------------------------------------------
def mot_graph(name: str, model: str):
    from pgm.io.video import open_source
    from pgm.models import get_config
    from pgm.models.config import VideoInfo
    from pgm.observation.detections import PublicDetections

    src = open_source(SHARED_DATA / name)
    det = PublicDetections(SHARED_DATA / name / "det" / "det.txt")
    graph = get_config(model).graph_for({}, VideoInfo(
        *src.size, fps=src.fps, score_range=det.score_range,
        typical_height=float(np.median(det.table.boxes[:, 3]))))
    return graph, det


def mot_run(name: str, model: str) -> dict:
    """One run as ``pgm track`` runs it (tracks written, no video): inference and end-to-end
    seconds as it reports them."""
    from pgm.app.runner import track_multi
    from pgm.io.video import open_source

    graph, det = mot_graph(name, model)
    with tempfile.TemporaryDirectory() as tmp:
        r = track_multi(open_source(SHARED_DATA / name), graph, det, rng=0, out_dir=tmp,
                        write_video=False, progress=False)
    return {"frames": r.n_frames, "inference": r.inference_seconds, "wall": r.wall_seconds}


def inference_alone(name: str, model: str, frames: int = 150) -> dict:
    """Seconds of ``engine.step`` and of the camera's motion on the first ``frames`` frames,
    decoded beforehand (nothing else running: no decoding thread sharing the cores)."""
    from pgm.core.frame import FrameContext
    from pgm.inference import Engine
    from pgm.io.video import open_source
    from pgm.observation.camera_motion import CameraMotionEstimator

    graph, det = mot_graph(name, model)
    images = list(open_source(SHARED_DATA / name).frames(1, frames + 1))  # held: ~1 GB at 1080p
    engine, motion = Engine(graph, np.random.default_rng(0)), CameraMotionEstimator("auto")
    step = 0.0
    for number, image in images:
        ctx = FrameContext(number, image, detections=det(number, image),
                           camera_motion=motion(image))
        t0 = time.perf_counter()
        engine.step(ctx)
        step += time.perf_counter() - t0
    return {"frames": len(images), "step": step, "camera": motion.seconds}


class RssSampler:
    """This process's resident set (MiB), sampled every ``period`` seconds on a thread."""

    def __init__(self, period: float = 0.02):
        self.period, self.samples = period, []
        self._stop = threading.Event()

    @staticmethod
    def rss_mib() -> float:
        with open("/proc/self/statm") as f:
            pages = int(f.read().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 2**20

    def __enter__(self):
        def loop():
            while not self._stop.is_set():
                self.samples.append(self.rss_mib())
                time.sleep(self.period)

        self._thread = threading.Thread(target=loop, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()


def cli_process(name: str, model: str) -> dict:
    """Wall seconds and maximum resident set of ``pgm track SEQ --no-video`` in a fresh
    process (start-up, decoding, inference, writing and evaluation)."""
    from mot_speed import toolkit_end_to_end

    return toolkit_end_to_end(name, model, video=False)


def mot_section(names: list[str], repeats: int, peers: bool, cores: list[str]) -> None:
    from pgm.models import DEFAULT_MULTI_TARGET

    largest = max(names, key=lambda q: _pixels(q))
    # first, before anything this process holds could lift the resident set it samples
    _memory_over_run(largest, DEFAULT_MULTI_TARGET)
    for name in names:
        decode, runs = [], {m: [] for m in [DEFAULT_MULTI_TARGET, *cores]}
        for k in range(repeats):  # interleaved: each ratio's two sides see the same drift
            decode.append(decode_seconds(name)[0])
            for m in runs:
                if k == 0 or m == DEFAULT_MULTI_TARGET:
                    runs[m].append(mot_run(name, m))
        n = runs[DEFAULT_MULTI_TARGET][0]["frames"]
        dec = statistics.median(decode)
        alone = [inference_alone(name, DEFAULT_MULTI_TARGET) for _ in range(repeats)]
        k = alone[0]["frames"]
        step = statistics.median(a["step"] for a in alone) * n / k
        camera = statistics.median(a["camera"] for a in alone) * n / k
        proc = cli_process(name, DEFAULT_MULTI_TARGET)
        ps = _mot_peers(name, n) if peers else {}
        base = ps.get("ocsort", {}).get("fps")
        rows = []

        def row(label, secs, mem="-", rows=rows, n=n, dec=dec, base=base):
            fps = n / secs
            rows.append([label, f"{1000 * secs / n:.2f}", f"{fps:.1f}", mem,
                         f"{secs / dec:.3f}", f"{fps / base:.3f}" if base else "-"])

        row("decode only (one thread)", dec)
        row(f"{DEFAULT_MULTI_TARGET}: alone, frames decoded before: engine.step", step)
        row(f"{DEFAULT_MULTI_TARGET}: alone: the camera's motion", camera)
        row(f"{DEFAULT_MULTI_TARGET}: alone: both", step + camera)
        for m, rs in runs.items():
            inf = statistics.median(r["inference"] for r in rs)
            wall = statistics.median(r["wall"] for r in rs)
            tag = " (default)" if m == DEFAULT_MULTI_TARGET else ""
            row(f"{m}{tag}: inference (+ camera motion)", inf)
            row(f"{m}{tag}: end to end, no video", wall)
        row(f"{DEFAULT_MULTI_TARGET}: pgm track process (start-up, evaluation)",
            proc["seconds"], f"{proc['rss_mib']:.0f}")
        for peer, r in ps.items():
            if "error" in r:
                rows.append([f"{peer} (trackers)", "-", "-", "-", "-", r["error"][:60]])
                continue
            row(f"{peer} (trackers): update", n / r["fps"])
        print_table(["", "ms/frame", "frames/s", "peak MiB", "x decode time",
                     "x OC-SORT (trackers) fps"], rows,
                    title=f"{name}: {n} frames, {_size(name)}; median of {repeats} runs "
                          f"(the default's and decoding's), one for the cores")


def _memory_over_run(name: str, model: str) -> None:
    with RssSampler() as s:
        mot_run(name, model)
    half = max(1, len(s.samples) // 2)
    first, second = max(s.samples[:half]), max(s.samples[half:] or s.samples)
    print(f"{name}, {model}: resident memory over one run: peak {first:.0f} MiB in its first "
          f"half, {second:.0f} MiB in its second ({len(s.samples)} samples)")


def _mot_peers(name: str, n: int) -> dict[str, dict]:
    from _peers import MOT_PEERS, run_mot_peers

    out = {}
    for peer in MOT_PEERS:
        with tempfile.TemporaryDirectory() as tmp:
            r = run_mot_peers(SHARED_DATA / name, last_frame=n, trackers=(peer,), workdir=tmp)
        out[peer] = r[peer]
    return out


def _pixels(name: str) -> int:
    from pgm.io.video import open_source

    w, h = open_source(SHARED_DATA / name).size
    return w * h


def _size(name: str) -> str:
    from pgm.io.video import open_source

    w, h = open_source(SHARED_DATA / name).size
    return f"{w}x{h}"


# the camera's motion ----------------------------------------------------------------------
#: how the camera's motion was estimated before issue 39: every frame shrunk to 640 wide,
#: 400 corners found anew, 21-pixel windows over 3 levels
CAMERA_BEFORE = {"max_side": 640, "max_corners": 400, "win_size": 21, "pyramid_levels": 3,
                 "track": False, "halve": False, "flow_epsilon": 0.01}
#: the reference the two are held against: 960 wide (one halving of 1080p), 1000 corners
#: found anew, 21-pixel windows over 4 levels
CAMERA_REFERENCE = {"max_side": 960, "max_corners": 1000, "win_size": 21, "pyramid_levels": 4,
                    "track": False, "flow_epsilon": 0.01}


def camera_section(name: str, frames: int) -> None:
    """The camera's motion on the moving-camera sequence, estimated as before and as now,
    each held against a finer estimate: ms per frame, how far each moves the image's
    corners from where the reference moves them (full-resolution pixels), and the
    median corner shift itself (the size of what is estimated)."""
    from pgm.io.video import open_source
    from pgm.observation.camera_motion import CameraMotionEstimator

    src = open_source(SHARED_DATA / name)
    images = [img for _, img in src.frames(1, frames + 1)]
    w, h = src.size
    corners = np.array([[0, 0], [w, 0], [0, h], [w, h]], dtype=float)

    def moved(A):
        return corners @ A[:, :2].T + A[:, 2]

    def run(settings):
        est = CameraMotionEstimator("on", **settings)
        out, t0 = [], time.perf_counter()
        for img in images:
            out.append(est(img))
        return out, (time.perf_counter() - t0) / len(images)

    ref, _ = run(CAMERA_REFERENCE)
    shift = [np.abs(moved(A) - corners).max() for A in ref if A is not None]
    rows = []
    for label, settings in (("before (640 wide, 400 corners anew)", CAMERA_BEFORE),
                            ("now (defaults: halved, 200 followed)", {})):
        got, secs = run(settings)
        err = [np.abs(moved(a) - moved(r)).max() for a, r in zip(got, ref, strict=True)
               if a is not None and r is not None]
        e = np.quantile(err, [0.5, 0.95, 1.0]) if err else [float("nan")] * 3
        rows.append([label, f"{1000 * secs:.2f}", sum(a is not None for a in got[1:]),
                     f"{e[0]:.2f}", f"{e[1]:.2f}", f"{e[2]:.2f}"])
    print_table(["camera motion", "ms/frame", "frames with a fit", "corner error median px",
                 "95%", "max"], rows,
                title=f"{name}: {len(images)} frames; error against a finer estimate "
                      f"(960 wide, 1000 corners); its median corner shift "
                      f"{np.median(shift):.1f} px per frame")


# memory over a long stream -----------------------------------------------------------
def memory_section(frames: int) -> None:
    """The default's engine over ``frames`` synthetic frames: held Python allocations and
    resident memory at a quarter, a half and the end (see the module's docstring)."""
    import tracemalloc

    from pgm.core.frame import FrameContext
    from pgm.inference import Engine
    from pgm.models import get_config
    from pgm.models.config import VideoInfo
    from pgm.observation.detections import Detections

    rng = np.random.default_rng(0)
    w, h = 640, 480
    image = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
    graph = get_config("ocsort-colour").graph_for({}, VideoInfo(
        w, h, fps=30.0, score_range=(0.0, 1.0), typical_height=80.0))
    engine = Engine(graph, np.random.default_rng(0))
    people: list[list[float]] = []  # x, y, vx, vy, last frame
    marks = sorted({max(1, frames // 4), max(1, frames // 2), frames})
    rows = []
    tracemalloc.start()
    try:
        for t in range(1, frames + 1):
            if rng.random() < 0.08:
                people.append([rng.uniform(50, w - 50), rng.uniform(100, h - 100),
                               rng.normal(0, 1.5), rng.normal(0, 0.5),
                               t + rng.integers(60, 300)])
            people = [p for p in people if p[4] > t and 0 < p[0] < w and 0 < p[1] < h]
            for p in people:
                p[0] += p[2]
                p[1] += p[3]
            boxes = np.array([[p[0] - 15, p[1] - 40, 30, 80] for p in people]).reshape(-1, 4)
            boxes += rng.normal(0, 1.5, boxes.shape)
            engine.step(FrameContext(t, image, detections=Detections(
                boxes, rng.uniform(0.3, 1.0, len(boxes)))))
            if t in marks:
                rows.append([t, tracemalloc.get_traced_memory()[0] / 2**20,
                             RssSampler.rss_mib(), len(people)])
    finally:
        tracemalloc.stop()
    per = ((rows[-1][1] - rows[0][1]) / max(rows[-1][0] - rows[0][0], 1) * 1000
           if len(rows) > 1 else float("nan"))
    print_table(["frame", "Python allocations held, MiB", "resident MiB", "people on view"],
                [[t, f"{a:.2f}", f"{r:.0f}", n] for t, a, r, n in rows],
                title=f"the default's engine over {frames} synthetic frames (640x480, "
                      f"tracemalloc on): growth {per:.3f} MiB per 1 000 frames from frame "
                      f"{rows[0][0]} on")


# one object -----------------------------------------------------------------------------
def sot_section(names: list[str], frames: int, peers: bool, repeats: int) -> None:
    from _peers import frame_paths, run_sot_peers

    from pgm.app.runner import init_box_from_gt, track
    from pgm.io.annotations import load_single_gt
    from pgm.io.video import open_source
    from pgm.models import DEFAULT_SINGLE_OBJECT, get_config
    from pgm.models.config import VideoInfo

    rows = []
    for name in names:
        src = open_source(SHARED_DATA / name)
        gt = load_single_gt(src.gt_path)
        c = init_box_from_gt(gt, 1)
        w, h = src.size
        graph = get_config(DEFAULT_SINGLE_OBJECT).graph_for({}, VideoInfo(
            width=w, height=h, fps=float(src.fps), init_box=tuple(float(v) for v in c)))
        n = min(frames, len(src))
        ours, fps = [], {}
        for _ in range(repeats):  # interleaved, each side's median
            ours.append(track(src, graph, rng=0, write_video=False, progress=False,
                              max_frames=n).fps)
            if peers:
                xywh = [c[0] - c[2] / 2, c[1] - c[3] / 2, c[2], c[3]]
                for k, v in run_sot_peers(frame_paths(src, 1, n + 1), xywh).items():
                    fps.setdefault(k, []).append(v.get("fps", float("nan")))
        ours = statistics.median(ours)
        fps = {k: statistics.median(v) for k, v in fps.items()}
        csrt = fps.get("csrt")
        rows.append([name, f"{w}x{h}", n, f"{ours:.1f}",
                     *(f"{fps[k]:.1f}" if k in fps and np.isfinite(fps[k]) else "-"
                       for k in ("csrt", "kcf", "mil")),
                     f"{ours / csrt:.2f}" if csrt else "-"])
    print_table(["sequence", "size", "frames", f"{DEFAULT_SINGLE_OBJECT} fps", "CSRT fps",
                 "KCF fps", "MIL fps", "x CSRT"], rows,
                title=f"one object: inference frames/s (decoding excluded), peers' update "
                      f"frames/s (OpenCV, their own venv); medians of {repeats} runs, "
                      f"interleaved")


# the PHD filter --------------------------------------------------------------------------
def phd_section(seeds: int, totals: list[int], peers: bool) -> None:
    import phd_scenario
    from _peers import run_phd_peer

    from pgm.evaluation.set_distances import ospa

    path = BENCH / "phd_scenario_seed2024.json"
    if not path.is_file():
        print(f"\nphd: {path} not found, skipped")
        return
    p, truth, meas = phd_scenario.load(path)
    ss = run_phd_peer(path, totals, seeds) if peers else {"error": "--no-peers"}

    def ospa_of(estimates):
        return float(np.mean([ospa(t, np.asarray(e, dtype=float).reshape(-1, 2), 50, 1)
                              for t, e in zip(truth, estimates, strict=True)]))

    # every particle count run once: the curve serves both tables
    curve = phd_curve(seeds, p, truth, meas, sorted(set(PHD_CURVE) | set(totals)))
    ran = "error" not in ss
    points = ({n: (float(np.median([r["ms"] for r in ss[n]])),
                   float(np.mean([ospa_of(r["estimates"]) for r in ss[n]])))
               for n in totals if n in ss} if ran else
              {n: phd_scenario.STONE_SOUP[n][:2] for n in totals
               if n in phd_scenario.STONE_SOUP})
    equal_accuracy_table(curve, points, seeds, path.name,
                         "same run" if ran else
                         "the bench README's figures: Stone Soup not run here")
    rows = []
    for total in totals:
        ms, ours = curve[total, False][:2]
        readme = phd_scenario.STONE_SOUP.get(total)
        if ran and total in points:
            ss_ms, ss_ospa = points[total]
            rows.append([total, f"{ms:.2f}", f"{ours:.1f}", f"{ss_ms:.2f}", f"{ss_ospa:.1f}",
                         f"{ss_ms / ms:.1f}", readme[0] if readme else "-"])
        else:
            rows.append([total, f"{ms:.2f}", f"{ours:.1f}", "-", "-",
                         f"{readme[0] / ms:.1f} (README)" if readme else "-",
                         readme[0] if readme else "-"])
    note = ("Stone Soup 1.9.1 run in this run (peers' venv)" if ran else
            f"Stone Soup not run ({ss['error'][:80]}): the ratio is to the bench README's "
            f"figure")
    print_table(["N", "PHD ms/step", "PHD OSPA(50,1)", "Stone Soup ms/step",
                 "Stone Soup OSPA(50,1)", "x Stone Soup speed", "README Stone Soup ms"], rows,
                title=f"PHD filter on {path.name}: ms per step (filter; median over {seeds} "
                      f"seeds), OSPA(50,1) mean over seeds (per-measurement extraction, the "
                      f"toolkit's metric for both); {note}")


#: the PHD filter's particle counts for the speed-accuracy curve (the equal-OSPA table)
PHD_CURVE = (250, 500, 1000, 2000, 3000, 5000, 10000, 20000)


def phd_curve(seeds: int, p, truth, meas, counts) -> dict[tuple[int, bool], tuple]:
    """``(N, regularise) -> (ms per step (median over seeds), OSPA(50, 1) of the
    extraction, of the confirmed tracks (means))`` of the PHD filter on the scenario."""
    import phd_scenario

    from pgm.models import phd

    curve = {}
    for total in counts:
        for reg in (False, True):
            res = [phd_scenario.run(phd.Params, phd.build_graph, p, meas, truth, total, s,
                                    regularise=reg) for s in range(seeds)]
            curve[total, reg] = (float(np.median([r["ms"] for r in res])),
                                 float(np.mean([r["ospa_raw"] for r in res])),
                                 float(np.mean([r["ospa_trk"] for r in res])))
    return curve


def equal_accuracy_table(curve: dict[tuple[int, bool], tuple],
                         points: dict[int, tuple[float, float]], seeds: int, scenario: str,
                         source: str) -> None:
    """The PHD filter's cost at Stone Soup's accuracy: its speed-accuracy ``curve``
    (:func:`phd_curve`), then, for each of Stone Soup's rows ``points`` (``N -> (ms per
    step, OSPA(50, 1))``), the cheapest particle count of the curve whose mean OSPA(50, 1)
    is at or below Stone Soup's, and the ratio of the ms per step — with the filter's
    per-measurement extraction (as Stone Soup's figures) and with its track layer's
    confirmed tracks (the toolkit's output; Stone Soup's SMC-PHD has no track layer);
    plain and with regularised resampling."""
    def cells(v):  # ms, extraction, tracks
        return [f"{v[0]:.2f}", f"{v[1]:.1f}", f"{v[2]:.1f}"]

    counts = sorted({n for n, _ in curve})
    print_table(["N", "ms/step", "OSPA(50,1) extraction", "OSPA(50,1) tracks",
                 "regularised: ms/step", "extraction", "tracks"],
                [[n, *cells(curve[n, False]), *cells(curve[n, True])] for n in counts],
                title=f"PHD filter on {scenario}: speed and accuracy by particle count, plain "
                      f"and with regularised resampling ({seeds} seeds: ms median, OSPA mean)")

    def cheapest(target, reg, k):  # k: 1 the extraction's OSPA, 2 the tracks'
        ok = [(v[0], n, v[k]) for (n, r), v in curve.items() if r == reg and v[k] <= target]
        return min(ok) if ok else None  # (ms, N, OSPA)

    rows = []
    for total, (ss_ms, ss_ospa) in points.items():
        row = [total, f"{ss_ms:.2f}", f"{ss_ospa:.1f}"]
        for reg in (False, True):
            for k in (1, 2):
                got = cheapest(ss_ospa, reg, k)
                row.append("not reached" if got is None else
                           f"N={got[1]}: {got[0]:.2f} ms, {got[2]:.1f}, x{ss_ms / got[0]:.1f}")
        rows.append(row)
    print_table(["Stone Soup N", "Stone Soup ms/step", "Stone Soup OSPA(50,1)",
                 "PHD extraction", "PHD tracks", "regularised: extraction", "tracks"], rows,
                title=f"At equal or better accuracy: the cheapest particle count of the PHD "
                      f"filter whose OSPA(50,1) is at or below Stone Soup's, and its speed "
                      f"ratio ({source})")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sections", default="mot,camera,memory,sot,phd")
    ap.add_argument("--memory-frames", type=int, default=6000,
                    help="synthetic frames for the memory section (default 6000)")
    ap.add_argument("--camera-frames", type=int, default=300,
                    help="frames of MOT16-11 for the camera section (default 300)")
    ap.add_argument("--sequences", default=",".join(MOT_SEQUENCES))
    ap.add_argument("--sot", default=",".join(SOT_SEQUENCES))
    ap.add_argument("--frames", type=int, default=150,
                    help="frames per single-object sequence (default 150)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--cores", default=",".join(CORES),
                    help="the classic cores timed beside the default")
    ap.add_argument("--phd-particles", default="1000,5000,20000",
                    help="nominal particle counts (those of the bench's Stone Soup rows)")
    ap.add_argument("--no-peers", action="store_true", help="the toolkit's rows only")
    args = ap.parse_args(argv)
    sections = set(args.sections.split(","))
    print(machine_note())
    present = [q for q in args.sequences.split(",") if (SHARED_DATA / q).is_dir()]
    if "mot" in sections and present:
        mot_section(present, max(1, args.repeats), not args.no_peers,
                    [c for c in args.cores.split(",") if c])
    if "memory" in sections:
        memory_section(max(4, args.memory_frames))
    if "camera" in sections and (SHARED_DATA / "MOT16-11").is_dir():
        camera_section("MOT16-11", args.camera_frames)
    sot = [q for q in args.sot.split(",") if (SHARED_DATA / q).is_dir()]
    if "sot" in sections and sot:
        sot_section(sot, args.frames, not args.no_peers, max(1, args.repeats))
    if "phd" in sections:
        phd_section(args.seeds, [int(t) for t in args.phd_particles.split(",")],
                    not args.no_peers)
    return 0


if __name__ == "__main__":
    sys.exit(main())
