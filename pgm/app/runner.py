"""Run a tracker graph on a video: stream frames, write results as they go, score.

:func:`track` is the one call behind ``pgm track``: it streams the source's frames
through an :class:`~pgm.inference.Engine`, appends each frame's box to a
MOTChallenge ``tracks.txt`` (flushed per frame, so an interrupted run keeps what it
computed), writes an annotated MP4, and — given ground truth — ``metrics.json``.
Inference time is measured around ``engine.step`` only (decoding, drawing and writing
excluded).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pgm.core.errors import InputError
from pgm.core.frame import FrameContext
from pgm.core.graph import FactorGraph
from pgm.core.readout import readout
from pgm.evaluation.calibration import reliability
from pgm.evaluation.single_object import single_object_metrics
from pgm.inference.engine import Engine, StepRecord
from pgm.io.annotated_video import AnnotatedVideoWriter
from pgm.io.annotations import MotWriter, SingleTrack, load_single_gt
from pgm.io.video import FrameSource, open_source
from pgm.observation.camera_motion import CameraMotionEstimator
from pgm.plotting.annotate import annotate

__all__ = ["TrackResult", "track", "output_box", "output_target", "confidence_metrics",
           "init_box_from_gt", "MultiTrackResult",
           "track_multi"]


@dataclass
class TrackResult:
    """What :func:`track` produced.

    Attributes
    ----------
    frames : ndarray (T,)
        1-based frame numbers processed.
    boxes : ndarray (T, 4)
        Estimated top-left ``x, y, w, h`` (0-based) per frame.
    metrics : dict or None
        OTB metrics against the ground truth, when given.
    inference_seconds : float
        Time spent in ``engine.step`` (decoding, drawing and writing excluded).
    out_dir : Path or None
    records : list of StepRecord
        Kept only with ``keep_records=True``.
    scores : ndarray (T,)
        The model's calibrated confidence per frame (the probability that the box
        overlaps the truth by half; :func:`pgm.core.readout.confidence`), 1 for a model
        that declares none.
    """

    frames: np.ndarray
    boxes: np.ndarray
    metrics: dict[str, Any] | None
    inference_seconds: float
    out_dir: Path | None = None
    records: list[StepRecord] = field(default_factory=list)
    scores: np.ndarray | None = None

    @property
    def fps(self) -> float:
        """Frames per second of inference."""
        return len(self.frames) / self.inference_seconds if self.inference_seconds > 0 else 0.0


def output_box(graph: FactorGraph, record: StepRecord) -> np.ndarray:
    """The object's top-left ``(x, y, w, h)`` in one step record, from the graph's readout
    (:mod:`pgm.core.readout`; the model config decides what its estimates mean)."""
    return output_target(graph, record)[0]


def output_target(graph: FactorGraph, record: StepRecord) -> tuple[np.ndarray, float]:
    """The object's top-left ``(x, y, w, h)`` and its score (the model's calibrated
    confidence, 1 where it declares none) in one step record."""
    targets = readout(graph, record)
    if len(targets) != 1:
        raise ValueError(f"model {graph.name!r} reported {len(targets)} targets; a "
                         f"single-object run needs exactly one")
    return targets.boxes[0], float(targets.scores[0])


def _xy_columns(graph: FactorGraph, variable: str) -> list[int]:
    """Columns of ``variable`` that hold an image position (by its labels)."""
    labels = graph.variables[variable].labels or ()
    for pair in (("cx", "cy"), ("px", "py"), ("x", "y")):
        if all(name in labels for name in pair):
            return [labels.index(pair[0]), labels.index(pair[1])]
    return [0, 1]


def init_box_from_gt(gt: SingleTrack, first_frame: int = 1) -> np.ndarray:
    """The ground-truth box of ``first_frame`` as ``(cx, cy, w, h)``."""
    hit = np.flatnonzero(gt.frames == first_frame)
    if hit.size == 0:
        raise InputError(f"ground truth has no box for frame {first_frame}: give --init")
    x, y, w, h = gt.boxes[hit[0]]
    return np.array([x + w / 2, y + h / 2, w, h])


def _frames_of(source) -> tuple[Iterable[tuple[int, np.ndarray]], float, int | None]:
    if isinstance(source, (str, Path)):
        source = open_source(source)
    if isinstance(source, FrameSource):
        return source.frames(), float(source.fps), len(source)
    return source, 25.0, None


def track(source: str | Path | FrameSource | Iterable[tuple[int, np.ndarray]],
          graph: FactorGraph, *, rng: np.random.Generator, out_dir: str | Path | None = None,
          gt: SingleTrack | str | Path | None = None, num_particles: int | None = None,
          write_video: bool = True, show_particles: bool = False, progress: bool = True,
          max_frames: int | None = None, keep_records: bool = False,
          engine_kwargs: dict[str, Any] | None = None, camera_motion: str = "auto",
          on_frame: Callable[[StepRecord], None] | None = None) -> TrackResult:
    """Track one object through ``source`` with the tracker ``graph``.

    Parameters
    ----------
    source : path, FrameSource or iterable of ``(frame_number, image)``
    graph : FactorGraph
        A single-object tracker (``graph.meta["output"]`` names its box variable(s)).
    rng : numpy.random.Generator
    out_dir : path, optional
        Where ``tracks.txt``, ``annotated.mp4``, ``metrics.json``, ``run.json`` and
        the learned ``model.json`` go (nothing is written when omitted).
    gt : SingleTrack or path, optional
        Ground truth for ``metrics.json`` (and thin white boxes in the video).
    num_particles, engine_kwargs
        Passed to :class:`Engine`.
    max_frames : int, optional
        Stop after this many frames.
    camera_motion : {"auto", "on", "off"}
        Global-motion compensation (:mod:`pgm.observation.camera_motion`): ``"auto"``
        moves the particles through the camera's motion on frames where it is
        significant.
    """
    if num_particles is not None and (isinstance(num_particles, bool)
                                      or not isinstance(num_particles, (int, np.integer))
                                      or num_particles < 1):
        raise InputError(f"number of particles must be a positive integer, got {num_particles}")
    if isinstance(gt, (str, Path)):
        gt = load_single_gt(gt)
    frames_iter, fps, total = _frames_of(source)
    if max_frames is not None:
        total = min(total, max_frames) if total is not None else max_frames
    engine = Engine(graph, rng, num_particles=num_particles, **(engine_kwargs or {}))
    motion = CameraMotionEstimator(camera_motion)
    out = Path(out_dir) if out_dir is not None else None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    gt_by_frame = ({int(f): b for f, b in zip(gt.frames, gt.boxes, strict=True)}
                   if gt is not None else {})

    frames_done: list[int] = []
    boxes_done: list[np.ndarray] = []
    scores_done: list[float] = []
    records: list[StepRecord] = []
    seconds = 0.0
    writer = MotWriter(out / "tracks.txt") if out is not None else None
    video = (AnnotatedVideoWriter(out / "annotated.mp4", fps)
             if out is not None and write_video else None)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=total, unit="frame", desc=graph.name, leave=False)
    try:
        for k, (number, image) in enumerate(frames_iter):
            if max_frames is not None and k >= max_frames:
                break
            ctx = FrameContext(number, image, camera_motion=motion(image))
            t0 = time.perf_counter()
            record = engine.step(ctx)
            seconds += time.perf_counter() - t0
            box, score = output_target(engine.graph, record)
            frames_done.append(int(number))
            boxes_done.append(box)
            scores_done.append(score)
            if keep_records:
                records.append(record)
            if writer is not None:
                writer.write(number, [1], box[None], [score])
            if video is not None:
                video.write(_annotated_frame(engine, record, image, box,
                                             gt_by_frame.get(int(number)), show_particles))
            if on_frame is not None:
                on_frame(record)
            if bar is not None:
                bar.update(1)
    finally:
        _close(bar, writer, video)
    if not frames_done:
        raise InputError("the source has no frames")
    frames_arr = np.asarray(frames_done)
    boxes_arr = np.asarray(boxes_done)
    # score the annotated frames up to the last frame processed (max_frames may stop early)
    scores_arr = np.asarray(scores_done)
    metrics = (single_object_metrics(gt.until(frames_arr.max()), frames_arr, boxes_arr)
               if gt is not None else None)
    if metrics is not None and "confidence" in engine.graph.meta:
        metrics["confidence"] = confidence_metrics(metrics, frames_arr, scores_arr)
    result = TrackResult(frames_arr, boxes_arr, metrics, seconds, out, records, scores_arr)
    if out is not None:
        run = {"model": graph.name, "frames": len(frames_done),
               "num_particles": engine.num_particles, "inference_seconds": seconds,
               "fps": result.fps, "camera_motion": camera_motion,
               "camera_motion_frames": motion.frames_moved}
        if metrics is not None:
            metrics = {**metrics, "fps": result.fps}
            (out / "metrics.json").write_text(json.dumps(metrics, indent=1))
        (out / "run.json").write_text(json.dumps(run, indent=1))
        engine.graph.save(out / "model.json")
    return result


def confidence_metrics(metrics: dict[str, Any], frames: np.ndarray,
                       scores: np.ndarray) -> dict[str, Any]:
    """The per-frame confidence and its calibration on the scored frames (outcome: IoU
    at least 0.5), for ``metrics.json``."""
    at = dict(zip(frames.tolist(), scores.tolist(), strict=True))
    scored = [(at[f], iou) for f, iou in zip(metrics["frames"], metrics["ious"], strict=True)
              if f in at]
    out: dict[str, Any] = {"frames": frames.tolist(), "values": scores.tolist()}
    if scored:
        c, iou = np.array(scored, dtype=float).T
        out["calibration"] = reliability(c, iou >= 0.5)
    return out


def _close(*things) -> None:
    """Close the progress bar, result writer and video writer that were opened."""
    for thing in things:
        if thing is not None:
            thing.close()


def _annotated_frame(engine: Engine, record: StepRecord, image: np.ndarray, box: np.ndarray,
                     gt_box: np.ndarray | None, show_particles: bool) -> np.ndarray:
    particles = weights = parts = messages = None
    names = engine.graph.output
    if show_particles:
        particles = {n: record.beliefs[n].x[:, _xy_columns(engine.graph, n)] for n in names}
        weights = {n: record.beliefs[n].weights for n in names}
        messages = {f"{s}->{d}": m.x for (s, d), m in record.messages.items()}
    if len(names) > 1:
        parts = {n: record.estimates[n] for n in names}
    ess = "ESS " + "/".join(f"{v:.0f}" for v in record.ess.values())
    return annotate(image, boxes=box[None], ids=[1],
                    gt_boxes=None if gt_box is None else gt_box[None], particles=particles,
                    particle_weights=weights, messages=messages, part_boxes=parts,
                    text=f"{engine.graph.name} frame {record.frame} {ess}")


# -------------------------------------------------------------------------------------
# many targets
# -------------------------------------------------------------------------------------
@dataclass
class MultiTrackResult:
    """What :func:`track_multi` produced: the result table, metrics and timings."""

    table: Any
    metrics: dict[str, Any] | None
    inference_seconds: float
    detector_seconds: float
    n_frames: int
    out_dir: Path | None = None
    noise_sigma: list[float] = field(default_factory=list)

    @property
    def fps(self) -> float:
        """Frames per second of inference (detection and decoding excluded)."""
        return self.n_frames / self.inference_seconds if self.inference_seconds > 0 else 0.0


def track_multi(source: str | Path | FrameSource, graph: FactorGraph, detector, *,
                rng: np.random.Generator, out_dir: str | Path | None = None,
                gt=None, write_video: bool = True, show_particles: bool = False,
                progress: bool = True, max_frames: int | None = None,
                engine_kwargs: dict[str, Any] | None = None,
                camera_motion: str = "auto") -> MultiTrackResult:
    """Track every target through ``source`` with a set-variable graph (PHD, VB-PHD).

    ``detector(frame_number, image) -> Detections`` gives each frame's measurements
    (their foot points); boxes are reported at the track's foot point with the size of
    its associated detections. Writes ``tracks.txt`` (MOTChallenge rows with
    identities, flushed per frame), ``annotated.mp4`` and, given ground truth (a
    :class:`~pgm.io.annotations.MotTable` or a ``gt.txt`` path), ``metrics.json``.
    """
    from pgm.evaluation.mot import evaluate_mot
    from pgm.io.annotations import MotTable, load_mot

    if isinstance(gt, (str, Path)):
        gt = load_mot(gt, kind="gt")
    if isinstance(source, (str, Path)):
        source = open_source(source)
    var = graph.output[0]
    engine = Engine(graph, rng, **(engine_kwargs or {}))
    motion = CameraMotionEstimator(camera_motion)
    motion_secs = 0.0
    noise = [v for v in engine.graph.variables.values() if v.role == "noise"]
    out = Path(out_dir) if out_dir is not None else None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    writer = MotWriter(out / "tracks.txt") if out is not None else None
    video = (AnnotatedVideoWriter(out / "annotated.mp4", source.fps)
             if out is not None and write_video else None)
    total = len(source) if max_frames is None else min(len(source), max_frames)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=total, unit="frame", desc=graph.name, leave=False)
    rows_f, rows_i, rows_b, rows_c = [], [], [], []
    secs = det_secs = 0.0
    n = 0
    sigmas: list[float] = []
    try:
        for k, (number, image) in enumerate(source.frames()):
            if max_frames is not None and k >= max_frames:
                break
            t0 = time.perf_counter()
            dets = detector(number, image)
            det_secs += time.perf_counter() - t0
            t0 = time.perf_counter()
            moved = motion(image)
            motion_secs += time.perf_counter() - t0
            ctx = FrameContext(number, image, detections=dets, camera_motion=moved)
            t0 = time.perf_counter()
            record = engine.step(ctx)
            secs += time.perf_counter() - t0
            n += 1
            if noise:
                sigmas.append(float(np.sqrt(np.mean(record.estimates[noise[0].name]))))
            targets = readout(engine.graph, record)
            ids, boxes, conf = targets.ids, targets.boxes, targets.scores
            rows_f += [number] * len(ids)
            rows_i += ids.tolist()
            rows_b += boxes.tolist()
            rows_c += conf.tolist()
            if writer is not None and len(ids):
                writer.write(number, ids, boxes, conf)
            if video is not None:
                particles = None
                if show_particles:
                    b = record.beliefs[var]
                    particles = ({var: b.x[:, _xy_columns(engine.graph, var)]}
                                 if b.num else None)
                gt_boxes = None
                if gt is not None:
                    gt_boxes = gt.at(number)[1]
                video.write(annotate(image, boxes=boxes, ids=ids.tolist(), gt_boxes=gt_boxes,
                                     particles=particles,
                                     text=f"{graph.name} frame {number} {targets.text}"))
            if bar is not None:
                bar.update(1)
    finally:
        _close(bar, writer, video)
    if n == 0:
        raise InputError("the source has no frames")
    table = MotTable(np.asarray(rows_f, dtype=np.int64), np.asarray(rows_i, dtype=np.int64),
                     np.asarray(rows_b, dtype=float).reshape(-1, 4),
                     np.asarray(rows_c, dtype=float))
    metrics = None
    if gt is not None:
        last = int(number)
        metrics = evaluate_mot(gt.until(last), table, num_frames=last)
        metrics["fps"] = n / secs if secs > 0 else 0.0
        metrics["detector_fps"] = n / det_secs if det_secs > 0 else 0.0
    result = MultiTrackResult(table, metrics, secs, det_secs, n, out, sigmas)
    if out is not None:
        if metrics is not None:
            (out / "metrics.json").write_text(json.dumps(metrics, indent=1))
        run = {"model": graph.name, "frames": n, "inference_seconds": secs,
               "detector_seconds": det_secs, "fps": result.fps,
               "camera_motion": camera_motion, "camera_motion_frames": motion.frames_moved,
               "camera_motion_seconds": motion_secs}
        if sigmas:
            run["noise_sigma_per_frame"] = sigmas
        (out / "run.json").write_text(json.dumps(run, indent=1))
        engine.graph.save(out / "model.json")
    return result
