"""Run the peer trackers in their own virtualenv and read their output back.

The peers (OpenCV CSRT / KCF / MIL; SORT / ByteTrack / OC-SORT, and BoT-SORT / C-BIoU / McByte
on request, from ``trackers`` 2.6.1) are
not toolkit dependencies: ``trackers`` pulls ``opencv-python``, which clashes with the
toolkit's ``opencv-python-headless``, and CSRT / KCF need the contrib build. They live in
``.venv-peers/`` (``bash benchmarks/peers/setup_env.sh``) and run as subprocesses
(``benchmarks/peers/mot_peers.py``, ``sot_peers.py``) that exchange plain files with this
module; the toolkit scores their output with its own metrics
(:func:`pgm.evaluation.mot.evaluate_mot`,
:func:`pgm.evaluation.single_object.single_object_metrics`).

Coordinates: MOT results come back as :class:`pgm.io.annotations.MotTable` read with
``load_mot(path, kind="det")`` (column 7 is a score; 1-based file boxes become the
toolkit's 0-based ones, as for ``gt.txt``). Single-object boxes are exchanged in the
toolkit's 0-based top-left ``(x, y, w, h)``, which are OpenCV's pixel coordinates.

    from _peers import SETUP_HINT, frame_paths, peer_python, run_mot_peers, run_sot_peers
    run_mot_peers(seq, trackers="all")  # + BoT-SORT, C-BIoU, McByte (frames read for CMC)
"""

from __future__ import annotations

import functools
import json
import os
import subprocess
import tempfile
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from pgm.io.annotations import load_mot
from pgm.io.video import FrameSource, ImageSequenceSource, open_source

__all__ = ["SETUP_HINT", "PEERS_DIR", "MOT_PEERS", "DEFAULT_MOT_PEERS", "peer_python",
           "run_mot_peers", "run_sot_peers", "frame_paths"]

REPO = Path(__file__).resolve().parents[1]
PEERS_DIR = Path(__file__).resolve().parent / "peers"
SETUP_HINT = ("peer trackers not installed: run `bash benchmarks/peers/setup_env.sh` "
              "(creates .venv-peers/ with trackers 2.6.1 and opencv-contrib-python-headless)")
_CHECK = "import trackers, cv2; cv2.TrackerCSRT_create"
#: every tracker ``mot_peers.py`` runs (``trackers="all"``), as its ``TRACKERS``: ``botsort``
#: and ``mcbyte`` (no mask manager, its default) take the frames for their camera-motion
#: compensation, the others the detections alone
MOT_PEERS = ("sort", "bytetrack", "ocsort", "botsort", "cbiou", "mcbyte")
#: what :func:`run_mot_peers` runs by default (the three the engine's configs reproduce)
DEFAULT_MOT_PEERS = ("sort", "bytetrack", "ocsort")


@functools.lru_cache(maxsize=None)
def _works(python: str) -> bool:
    """Whether ``python`` imports ``trackers`` and a ``cv2`` with CSRT (checked once)."""
    try:
        r = subprocess.run([python, "-c", _CHECK], capture_output=True, timeout=300,
                           env=_env())
    except (OSError, subprocess.TimeoutExpired):
        return False
    return r.returncode == 0


def peer_python() -> Path | None:
    """The peer venv's interpreter, or None when it is missing or broken.

    ``$PGM_PEERS_PYTHON`` if set, else ``.venv-peers/bin/python`` under the repository
    root; it must ``import trackers, cv2`` with ``cv2.TrackerCSRT_create`` present (checked
    once per interpreter and process). The path is not resolved: a venv's ``python`` is a
    symlink to the base interpreter, which would lose the venv.
    """
    override = os.environ.get("PGM_PEERS_PYTHON")
    candidate = Path(override) if override else REPO / ".venv-peers" / "bin" / "python"
    if not candidate.is_absolute():
        candidate = Path.cwd() / candidate
    if not candidate.exists():
        return None
    return candidate if _works(str(candidate)) else None


def _env() -> dict[str, str]:
    """The subprocess environment: one thread per library; no toolkit paths leaking in."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env.setdefault(var, "1")
    return env


def _tail(text: str, n: int = 600) -> str:
    text = " ".join(text.split())
    return text[-n:] if text else "(no output)"


def _run(cmd: list[str], timeout: float | None) -> tuple[int, str]:
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=_env())
    except subprocess.TimeoutExpired:
        return -1, f"timed out after {timeout} s"
    except OSError as exc:
        return -1, f"could not start {cmd[0]}: {exc}"
    return r.returncode, r.stderr + r.stdout


def _collect(names, data: dict, script: str, code: int, log: str, read) -> dict[str, dict]:
    """Per tracker: ``read(name, entry)`` plus its ``fps`` where the script reported a
    result, its error where it reported one, the script's exit and log tail otherwise."""
    results: dict[str, dict] = {}
    for name in names:
        entry = data.get(name)
        if entry is None:
            results[name] = {"error": f"{script} exit {code}: {_tail(log)}"}
        elif "error" in entry:
            results[name] = {"error": str(entry["error"])}
        else:
            results[name] = {**read(name, entry),
                             "fps": float(entry["fps"]) if entry.get("fps") else float("nan")}
    return results


def run_mot_peers(sequence_dir: str | Path, last_frame: int | None = None,
                  trackers: Sequence[str] | str = DEFAULT_MOT_PEERS,
                  workdir: str | Path | None = None,
                  timeout: float | None = 1800.0,
                  frames: str | Path | None = None) -> dict[str, dict]:
    """Run the ``trackers`` package's MOT trackers on a MOTChallenge sequence's public
    detections (default: SORT / ByteTrack / OC-SORT).

    Parameters
    ----------
    sequence_dir : path
        A MOTChallenge folder with ``det/det.txt`` (and ``seqinfo.ini`` for the frame rate).
    last_frame : int, optional
        Track frames ``1..last_frame`` (default: ``seqLength``).
    trackers : sequence of str, or str
        Names understood by ``mot_peers.py``: ``sort``, ``bytetrack``, ``ocsort``,
        ``botsort``, ``cbiou``, ``mcbyte`` (:data:`MOT_PEERS`); ``"all"`` (or a
        comma-separated string, which may contain ``all``) for every one of them.
    workdir : path, optional
        Where the result files go (``<tracker>.txt``, ``timing.json``); default a new
        temporary folder, left in place so the returned paths stay valid.
    timeout : float, optional
        Seconds for the whole subprocess.
    frames : str or path, optional
        The images for the trackers whose ``update`` takes the frame (``botsort``,
        ``mcbyte``: camera-motion compensation): None / ``"auto"`` finds them in the
        sequence (``<imDir>/``, else its video file), ``"none"`` runs those trackers
        without frames (no CMC), a path names an image folder or a video file.

    Returns
    -------
    dict
        ``{name: {"table": MotTable, "fps": float, "path": Path, "frames": int,
        "seconds": float}}`` (plus ``"images"``: the folder or video the frames were read
        from, None when none, for the trackers that take frames), or
        ``{name: {"error": str}}`` for a tracker that failed (or for all of them when the
        peer venv is missing: the error is :data:`SETUP_HINT`). ``fps`` counts
        ``tracker.update`` time only (CMC included; decoding the frames is not).
    """
    if isinstance(trackers, str):
        trackers = [t for t in trackers.split(",") if t.strip()]
    names: list[str] = []
    for n in (str(t).strip().lower() for t in trackers):
        for m in (MOT_PEERS if n == "all" else (n,)):
            if m not in names:
                names.append(m)
    py = peer_python()
    if py is None:
        return {n: {"error": SETUP_HINT} for n in names}
    seq = Path(sequence_dir).resolve()
    out = (Path(workdir) if workdir is not None
           else Path(tempfile.mkdtemp(prefix=f"pgm-peers-{seq.name}-")))
    out.mkdir(parents=True, exist_ok=True)
    cmd = [str(py), str(PEERS_DIR / "mot_peers.py"), "--sequence", str(seq), "--out", str(out),
           "--trackers", ",".join(names)]
    if last_frame is not None:
        cmd += ["--last-frame", str(int(last_frame))]
    if frames is not None:
        cmd += ["--frames", frames if frames in ("auto", "none")
                else str(Path(frames).expanduser().resolve())]
    code, log = _run(cmd, timeout)
    timing_path = out / "timing.json"
    timing = json.loads(timing_path.read_text()) if timing_path.is_file() else {}
    def read(name, entry):
        path = out / f"{name}.txt"
        res = {"table": load_mot(path, kind="det"), "path": path,
               "frames": int(entry["frames"]), "seconds": float(entry["seconds"])}
        if "images" in entry:
            res["images"] = entry["images"]
        return res

    results = _collect(names, timing, "mot_peers.py", code, log, read)
    return results


def run_sot_peers(frames_paths: Iterable[str | Path], init_xywh: Sequence[float],
                  trackers: Sequence[str] = ("csrt", "kcf", "mil"), seed: int = 0,
                  timeout: float | None = 1800.0) -> dict[str, dict]:
    """Run OpenCV's CSRT / KCF / MIL on image files, initialised with ``init_xywh``.

    Parameters
    ----------
    frames_paths : iterable of path
        The image files in order (see :func:`frame_paths`); the first is the init frame.
    init_xywh : (x, y, w, h)
        Top-left box on the first frame, toolkit (= OpenCV) 0-based pixel coordinates,
        e.g. ``gt.boxes[0]`` of :func:`pgm.io.annotations.load_single_gt` when the ground
        truth annotates frame 1. OpenCV is initialised with it rounded to integers.
    trackers : sequence of str
        ``csrt``, ``kcf``, ``mil``.
    seed : int
        ``cv2.setRNGSeed`` before each tracker (MIL samples at random; CSRT and KCF are
        deterministic).
    timeout : float, optional
        Seconds for the whole subprocess.

    Returns
    -------
    dict
        ``{name: {"boxes": ndarray (T, 4) top-left xywh, first row = init_xywh,
        "ok": ndarray (T,) of bool (OpenCV's ``update`` succeeded), "fps": float,
        "failed_frames": int}}`` (a failed ``update`` keeps the previous box),
        or ``{name: {"error": str}}``. ``fps`` is frames 2..T over the ``update`` time.
    """
    names = [str(n).lower() for n in trackers]
    py = peer_python()
    if py is None:
        return {n: {"error": SETUP_HINT} for n in names}
    frames = [str(Path(p).resolve()) for p in frames_paths]
    init = [float(v) for v in np.asarray(init_xywh, dtype=float).reshape(4)]
    with tempfile.TemporaryDirectory(prefix="pgm-peers-sot-") as tmp:
        task, res = Path(tmp) / "task.json", Path(tmp) / "result.json"
        task.write_text(json.dumps({"frames": frames, "init": init}))
        code, log = _run([str(py), str(PEERS_DIR / "sot_peers.py"), "--task", str(task),
                          "--out", str(res), "--trackers", ",".join(names),
                          "--seed", str(int(seed))], timeout)
        data = json.loads(res.read_text()) if res.is_file() else {}
    results = _collect(names, data, "sot_peers.py", code, log, lambda name, entry: {
        "boxes": np.asarray(entry["boxes"], dtype=float).reshape(-1, 4),
        "ok": np.asarray(entry.get("ok", [True] * len(entry["boxes"])), dtype=bool),
        "failed_frames": int(entry["failed_frames"])})
    return results


def run_phd_peer(scenario: str | Path, totals: Sequence[int], seeds: int,
                 timeout: float | None = 3600.0) -> dict:
    """Stone Soup's SMC-PHD on the bench's scenario (``peers/phd_peers.py``): ``{N: [{"ms",
    "extract_ms", "estimates"}, ...] per seed}``, or ``{"error": str}`` when the peers' venv
    or Stone Soup in it is missing or the run fails."""
    py = peer_python()
    if py is None:
        return {"error": SETUP_HINT}
    with tempfile.TemporaryDirectory(prefix="pgm-peers-phd-") as tmp:
        res = Path(tmp) / "result.json"
        code, log = _run([str(py), str(PEERS_DIR / "phd_peers.py"), "--scenario",
                          str(Path(scenario).resolve()), "--out", str(res), "--particles",
                          ",".join(str(int(t)) for t in totals), "--seeds", str(int(seeds))],
                         timeout)
        if not res.is_file():
            return {"error": f"phd_peers.py exit {code}: {_tail(log)}"}
        data = json.loads(res.read_text())
    return {int(n): [runs[k] for k in sorted(runs, key=int)] for n, runs in data.items()}


def frame_paths(source: str | Path | FrameSource, start: int = 1,
                stop: int | None = None) -> list[Path]:
    """Image files of frames ``start <= n < stop`` (1-based, as ``source.frames``).

    Frame *n* of an image-folder source (MOT ``img1/``, OTB ``img/``, MILTrack ``imgs/``)
    is ``source.files[n - 1]``, the same pairing with the ground truth that
    :func:`pgm.io.video.open_source` uses (FaceOcc1: ``img00000.png`` is frame 1;
    David: ``img00001.png``; Tiger1: ``img00000.png``). Videos have no files: ``ValueError``.
    """
    src = open_source(source) if isinstance(source, (str, Path)) else source
    if not isinstance(src, ImageSequenceSource):
        raise ValueError(f"{src.path} is not an image-folder source; the OpenCV peers "
                         "read image files")
    end = len(src.files) if stop is None else min(int(stop) - 1, len(src.files))
    return list(src.files[int(start) - 1:end])
