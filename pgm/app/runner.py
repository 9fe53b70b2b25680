"""Run a tracker graph on a video: stream frames, write results as they go, score.

:func:`track` is the one call behind ``pgm track``: it streams the source's frames
through an :class:`~pgm.inference.Engine`, appends each frame's box to a
MOTChallenge ``tracks.txt`` (flushed per frame, so an interrupted run keeps what it
computed), writes an annotated MP4, and — given ground truth — ``metrics.json``.
Inference time is measured around ``engine.step`` only (decoding, drawing and writing
excluded).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from pgm.app.memory import check_memory, estimate_memory, memory_limit
from pgm.app.overlay import Trails, annotated_frame, frame_caption, xy_columns
from pgm.app.record import Recorder, RecordSettings
from pgm.app.run_loop import (
    RunOutputs,
    _record_settings,
    progress_bar,
    run_frames,
)
from pgm.app.track_results import (  # re-exported: runner is where they are imported from
    MultiTrackResult,
    TrackResult,
    confidence_metrics,
    init_box_from_gt,
    output_box,
    output_target,
)
from pgm.core.errors import InputError
from pgm.core.frame import FrameContext
from pgm.core.graph import FactorGraph
from pgm.core.readout import readout
from pgm.evaluation.calibration import confidence_outcomes, lost_signal
from pgm.evaluation.single_object import single_object_metrics
from pgm.inference.engine import Engine, StepRecord
from pgm.io.annotated_video import AnnotatedVideoWriter
from pgm.io.annotations import MotWriter, SingleTrack, TrackRows, load_single_gt
from pgm.io.outputs import prepare_run_folder, provenance, write_json, write_run_status
from pgm.io.video import FrameSource, open_source
from pgm.observation.camera_motion import CameraMotionEstimator
from pgm.plotting.annotate import annotate

__all__ = ["TrackResult", "track", "output_box", "output_target", "confidence_metrics",
           "init_box_from_gt", "MultiTrackResult",
           "track_multi", "estimate_memory", "memory_limit", "check_memory"]


def _pairs(frames: Iterable) -> Iterator[tuple[int, np.ndarray]]:
    """``(frame_number, image)`` pairs of an iterable, each checked as it comes."""
    for item in frames:
        ok = (isinstance(item, tuple) and len(item) == 2
              and isinstance(item[0], (int, np.integer)) and not isinstance(item[0], bool)
              and isinstance(item[1], np.ndarray) and item[1].ndim in (2, 3))
        if not ok:
            what = type(item).__name__ if not isinstance(item, np.ndarray) else \
                f"an array of shape {item.shape}"
            raise InputError(f"source must yield (frame_number, image) pairs, got {what}; "
                             f"pass a path, a FrameSource, or pairs such as "
                             f"enumerate(images, start=1)")
        yield int(item[0]), item[1]


def _frames_of(source) -> tuple[Iterable[tuple[int, np.ndarray]], float, int | None]:
    if isinstance(source, (str, Path)):
        source = open_source(source)
    if isinstance(source, FrameSource):
        return source.frames(), float(source.fps), len(source)
    return _pairs(source), 25.0, None


def source_text(source: Any) -> str | None:
    """How ``run.json`` names a source: a stream URL or camera index as given
    (``Path("http://host/s.ts")`` would read ``http:/host/s.ts``), else its path."""
    spec = getattr(source, "spec", None)
    if isinstance(spec, str):
        return spec
    return str(getattr(source, "path", "")) or None


def check_api_arguments(source: Any, graph: Any, gt: Any, max_frames: Any,
                        gt_types: tuple[type, ...]) -> None:
    """The arguments of :func:`track` and :func:`track_multi` checked up front: a
    ``ValueError`` naming the argument, never an error deep inside a run."""
    if not isinstance(graph, FactorGraph):
        raise InputError(f"graph must be a pgm.FactorGraph (e.g. "
                         f"pgm.models.get_config(NAME).graph_for(...)), got "
                         f"{type(graph).__name__}")
    if gt is not None and not isinstance(gt, (str, Path, *gt_types)):
        raise InputError(f"gt must be a path or a {' or '.join(t.__name__ for t in gt_types)}, "
                         f"got {type(gt).__name__}")
    if not isinstance(source, (str, Path, FrameSource)) and not (
            hasattr(source, "__iter__") and not isinstance(source, (bytes, dict))):
        raise InputError(f"source must be a path, a FrameSource or an iterable of "
                         f"(frame_number, image) pairs, got {type(source).__name__}")
    if max_frames is not None and (isinstance(max_frames, bool) or not isinstance(
            max_frames, (int, np.integer)) or max_frames < 1):
        raise InputError(f"max_frames must be a positive integer (or None: every frame), got "
                         f"{max_frames!r}")


def track(source: str | Path | FrameSource | Iterable[tuple[int, np.ndarray]],
          graph: FactorGraph, *, rng: int | np.random.Generator, out_dir: str | Path | None = None,
          gt: SingleTrack | str | Path | None = None, num_particles: int | None = None,
          write_video: bool = True, show_particles: bool = False, progress: bool = True,
          max_frames: int | None = None, keep_records: bool = False,
          engine_kwargs: dict[str, Any] | None = None, camera_motion: str = "off",
          on_frame: Callable[[StepRecord], None] | None = None,
          memory_limit_bytes: float | None = None,
          record: bool | RecordSettings | dict | None = None,
          lost_below: float | None = None,
          command: Sequence[str] | None = None,
          video_scale: float | None = None, trails: int = 0) -> TrackResult:
    """Track one object through ``source`` with the tracker ``graph``.

    Parameters
    ----------
    source : path, FrameSource or iterable of ``(frame_number, image)``
    graph : FactorGraph
        A single-object tracker (``graph.meta["output"]`` names its box variable(s)).
    rng : int or numpy.random.Generator
        A seed or a generator: the only source of randomness.
    out_dir : path, optional
        Where ``tracks.txt``, ``annotated.mp4``, ``metrics.json``, ``run.json`` and
        the learned ``model.json`` go (nothing is written when omitted).
    gt : SingleTrack or path, optional
        Ground truth for ``metrics.json`` (and thin white boxes in the video).
    num_particles, engine_kwargs
        Passed to :class:`Engine`.
    max_frames : int, optional
        Stop after this many frames.
    camera_motion : {"off", "auto", "on"}
        Global-motion compensation (:mod:`pgm.observation.camera_motion`): ``"auto"``
        moves the particles through the camera's motion on frames where it is
        significant. Off by default for one object: the camera of a single-object video
        usually follows its target, whose image motion is then not the background's
        (the default single-object tracker, seeds 0-1: David, a panning camera, success
        AUC 0.667 off against 0.564 auto; FaceOcc1, Crossing, Tiger1 and the PETS09-S2L1
        people within 0.003; but MOT16-11's people, filmed from a camera walking
        through the crowd, 0.358 off against 0.470 auto).
    memory_limit_bytes : float, optional
        Refuse the run (:class:`InputError`) when :func:`estimate_memory` exceeds this;
        default :func:`memory_limit`.
    record : bool, RecordSettings or dict, optional
        Record what the viewer (``pgm view``) shows into ``out_dir/record``
        (:mod:`pgm.app.record`; ``True``: the default bounds); needs ``out_dir``. Off by
        default; recording draws no random number, so the results are the same.
    lost_below : float, optional
        The lost signal: a frame whose calibrated confidence (the probability that the box
        overlaps the target by half; a model that declares one) is below it is written
        to ``tracks.txt`` as empty — the target is reported lost or out of view — and,
        with ground truth, ``metrics.json`` gets ``"lost"``: the frames flagged, and the
        signal's precision and recall against the frames where the box overlaps the
        truth by less than half (:func:`pgm.evaluation.calibration.lost_signal`). The
        other metrics score every frame's box, flagged or not. Default: off. With a
        model that declares a confidence, ``metrics.json`` also has the long-term
        measures (``"long_term"``: tracking precision, recall and F-score over the
        confidence thresholds) and, where the ground truth marks frames as absent,
        ``"absence"``: how well ``confidence < lost_below`` (0.5 when off) flags them
        (:func:`pgm.evaluation.single_object.absence_signal`).
    command : list of str, optional
        The command line the run came from (``pgm`` first), recorded in ``run.json``
        with the seed, the toolkit's version and its commit
        (:func:`pgm.io.outputs.provenance`).
    video_scale : float, optional
        The annotated video's scale (``(0, 1]``); default: so that its long side is at
        most 1280 px (:func:`pgm.io.annotated_video.video_scale`). It is encoded in a
        thread of its own.
    trails : int
        Draw each identity's last ``trails`` centres in the video (0: none).

    Notes
    -----
    The output folder is prepared by :func:`pgm.io.outputs.prepare_run_folder` (an
    earlier run's results are removed). ``run.json`` says ``"complete": false`` until
    the run has finished and ``metrics.json`` and ``model.json`` are written; an
    interrupted or failed run leaves it ``false`` with ``"stopped"`` saying why, and
    writes neither ``metrics.json`` nor ``model.json``. Every frame must have the first
    frame's size.
    """
    if num_particles is not None and (isinstance(num_particles, bool)
                                      or not isinstance(num_particles, (int, np.integer))
                                      or num_particles < 1):
        raise InputError(f"number of particles must be a positive integer, got {num_particles}")
    check_api_arguments(source, graph, gt, max_frames, (SingleTrack,))
    if lost_below is not None:
        lost_below = float(lost_below)
        if not 0.0 <= lost_below <= 1.0:  # also false for NaN
            raise InputError(f"the lost threshold must be a probability in [0, 1], got "
                             f"{lost_below!r}")
        if "confidence" not in graph.meta:
            raise InputError(f"model {graph.name!r} declares no calibrated confidence: it has "
                             f"no lost signal (the single-object default has one)")
    rec_settings = _record_settings(record, out_dir)
    if isinstance(gt, (str, Path)):
        gt = load_single_gt(gt)
    if isinstance(source, (str, Path)):
        source = open_source(source)
    frames_iter, fps, total = _frames_of(source)
    if max_frames is not None:
        total = min(total, max_frames) if total is not None else max_frames
    size = getattr(source, "size", None) if isinstance(source, FrameSource) else None
    check_memory(graph, size, num_particles=num_particles, limit=memory_limit_bytes)
    engine = Engine(graph, rng, num_particles=num_particles, **(engine_kwargs or {}))
    motion = CameraMotionEstimator(camera_motion, fps=fps)
    out = prepare_run_folder(out_dir) if out_dir is not None else None
    run = {"model": graph.name, "source": source_text(source),
           "num_particles": engine.num_particles, "camera_motion": camera_motion,
           **provenance(rng, command)}
    outputs = RunOutputs(out, run)
    if rec_settings is not None and out is not None:
        outputs.recorder = Recorder(out, engine, rec_settings, fps=fps)
        run["record"] = outputs.recorder.summary()
    if out is not None:
        write_run_status(out, {**run, "frames": 0}, complete=False, stopped="running")
    gt_by_frame = ({int(f): b for f, b in zip(gt.frames, gt.boxes, strict=True)}
                   if gt is not None else {})

    frames_done: list[int] = []
    boxes_done: list[np.ndarray] = []
    scores_done: list[float] = []
    records: list[StepRecord] = []
    outputs.writer = MotWriter(out / "tracks.txt") if out is not None else None
    outputs.video = (AnnotatedVideoWriter(out / "annotated.mp4", fps, scale=video_scale)
                     if out is not None and write_video else None)
    trail = Trails(trails)
    outputs.bar = progress_bar(progress, total, graph.name)

    def context(number, image):
        return FrameContext(number, image, camera_motion=motion(image)), None

    def emit(number, image, record, _):
        box, score = output_target(engine.graph, record)
        frames_done.append(int(number))
        boxes_done.append(box)
        scores_done.append(score)
        if keep_records:
            records.append(record)
        if outputs.writer is not None and (lost_below is None or score >= lost_below):
            outputs.writer.write(number, [1], box[None], [score])
        if outputs.video is not None:
            outputs.video.write(annotated_frame(
                engine, record, image, box, gt_by_frame.get(int(number)), show_particles,
                score=score if "confidence" in engine.graph.meta else None, trails=trail))
        if outputs.recorder is not None:
            outputs.recorder.write(engine, record, image,
                                   targets={"ids": [1], "boxes": box[None], "scores": [score]})
        if on_frame is not None:
            on_frame(record)

    t_start = time.perf_counter()
    _, seconds, _ = run_frames(frames_iter, engine, outputs, max_frames=max_frames,
                               context=context, emit=emit)
    wall = time.perf_counter() - t_start
    seconds += motion.seconds  # the camera's motion is inference too
    frames_arr = np.asarray(frames_done)
    boxes_arr = np.asarray(boxes_done)
    # score the annotated frames up to the last frame processed (max_frames may stop early)
    scores_arr = np.asarray(scores_done)
    conf = scores_arr if "confidence" in engine.graph.meta else None
    metrics = (single_object_metrics(gt.until(frames_arr.max()), frames_arr, boxes_arr, conf,
                                     0.5 if lost_below is None else lost_below)
               if gt is not None else None)
    if metrics is not None and "confidence" in engine.graph.meta:
        metrics["confidence"] = confidence_metrics(metrics, frames_arr, scores_arr)
        if lost_below is not None:
            c, hit = confidence_outcomes(frames_arr, scores_arr, metrics["frames"],
                                         metrics["ious"])
            metrics["lost"] = lost_signal(c, hit, lost_below)
    if out is not None and lost_below is not None:
        run["lost_below"] = lost_below
        run["frames_reported_lost"] = int(np.sum(scores_arr < lost_below))
    result = TrackResult(frames_arr, boxes_arr, metrics, seconds, out, records, scores_arr,
                         wall)
    if out is not None:
        run.update({"frames": len(frames_done), "last_frame": int(frames_arr[-1]),
                    "inference_seconds": seconds, "fps": result.fps,
                    "wall_seconds": wall, "fps_end_to_end": result.end_to_end_fps,
                    "camera_motion_frames": motion.frames_moved,
                    "camera_motion_seconds": motion.seconds,
                    "video": outputs.video is not None, **outputs.summary()})
        if metrics is not None:
            write_json(out / "metrics.json", {**metrics, "fps": result.fps})
        write_json(out / "model.json", engine.graph.to_dict())
        write_run_status(out, run, complete=True)  # last: the folder is now complete
    return result


# -------------------------------------------------------------------------------------
# many targets
# -------------------------------------------------------------------------------------
def track_multi(source: str | Path | FrameSource | Iterable, graph: FactorGraph, detector, *,
                rng: int | np.random.Generator, out_dir: str | Path | None = None,
                gt=None, write_video: bool = True, show_particles: bool = False,
                progress: bool = True, max_frames: int | None = None,
                engine_kwargs: dict[str, Any] | None = None,
                camera_motion: str = "auto",
                memory_limit_bytes: float | None = None,
                drop_frames: Iterable[int] | None = None,
                record: bool | RecordSettings | dict | None = None,
                command: Sequence[str] | None = None,
                video_scale: float | None = None, trails: int = 0) -> MultiTrackResult:
    """Track every target through ``source`` with a set-variable graph (PHD, VB-PHD) or a
    plate graph (one sub-graph per target: ``multi-pf``, ``gpdm``), both run by the one
    :class:`~pgm.inference.Engine`.

    ``detector(frame_number, image) -> Detections`` gives each frame's measurements
    (their foot points); boxes are reported at the track's foot point with the size of
    its associated detections. Writes ``tracks.txt`` (MOTChallenge rows with
    identities, flushed per frame), ``annotated.mp4`` and, given ground truth (a
    :class:`~pgm.io.annotations.MotTable` or a ``gt.txt`` path), ``metrics.json``.
    The output folder, ``run.json``'s ``"complete"`` flag, the memory check and the
    frame-size check are those of :func:`track`.

    ``drop_frames`` (frame numbers) simulates missing frames for a plate graph: their
    images and detections are withheld, the targets are predicted through them (and
    reported and scored there), as a tracker must across a gap in the video.

    ``record`` records what the viewer shows, ``command`` goes into ``run.json``,
    ``video_scale`` scales the annotated video and ``trails`` draws the tracks' last
    centres in it, as for :func:`track`. The video's header says the model, the frame
    and how many tracks it shows; the ground truth's ignored regions are drawn dashed
    and grey, apart from its scored boxes, and a legend says which is which.
    """
    from pgm.evaluation.mot import evaluate_mot
    from pgm.io.annotations import MotTable, load_mot

    check_api_arguments(source, graph, gt, max_frames, (MotTable,))
    rec_settings = _record_settings(record, out_dir)
    if isinstance(gt, (str, Path)):
        gt = load_mot(gt, kind="gt")
    if isinstance(source, (str, Path)):
        source = open_source(source)
    elif not isinstance(source, FrameSource):  # any iterable of frames
        from pgm.io.video import IterableSource

        source = IterableSource(source)
    var = graph.output[0]
    size = source.size
    dropped = set(int(f) for f in (drop_frames or ()))

    table = getattr(detector, "table", None)
    targets = None
    if table is not None and len(table):
        targets = int(np.max(np.unique(table.frames, return_counts=True)[1]))
    check_memory(graph, size, targets=targets, limit=memory_limit_bytes)
    engine = Engine(graph, rng, **(engine_kwargs or {}))
    if dropped and not engine.predicts_missing_frames:
        raise InputError(f"dropped frames need a plate model (one sub-graph per target), not "
                         f"{graph.name!r}")
    motion = CameraMotionEstimator(camera_motion, fps=source.fps)
    noise = [v for v in engine.graph.variables.values() if v.role == "noise"]
    out = prepare_run_folder(out_dir) if out_dir is not None else None
    run = {"model": graph.name, "source": source_text(source), "camera_motion": camera_motion,
           **provenance(rng, command)}
    if dropped:
        run["dropped_frames"] = sorted(dropped)
    outputs = RunOutputs(out, run)
    if rec_settings is not None and out is not None:
        outputs.recorder = Recorder(out, engine, rec_settings, fps=source.fps)
        run["record"] = outputs.recorder.summary()
    if out is not None:
        write_run_status(out, {**run, "frames": 0}, complete=False, stopped="running")
    outputs.writer = MotWriter(out / "tracks.txt") if out is not None else None
    outputs.video = (AnnotatedVideoWriter(out / "annotated.mp4", source.fps, scale=video_scale)
                     if out is not None and write_video else None)
    trail = Trails(trails)
    known = source._known_length()
    total = known if max_frames is None else (max_frames if known is None
                                              else min(known, max_frames))
    outputs.bar = progress_bar(progress, total, graph.name)
    track_rows = TrackRows()
    det_secs = 0.0
    sigmas: list[float] = []

    def context(number, image):
        nonlocal det_secs
        if number in dropped:  # withheld: the tracker predicts through it
            return FrameContext(number), None
        t0 = time.perf_counter()
        dets = detector(number, image)
        det_secs += time.perf_counter() - t0
        return FrameContext(number, image, detections=dets, camera_motion=motion(image)), dets

    def emit(number, image, record, dets):
        if noise:
            sigmas.append(float(np.sqrt(np.mean(record.estimates[noise[0].name]))))
        targets = readout(engine.graph, record)
        ids, boxes, conf = targets.ids, targets.boxes, targets.scores
        # this frame's rows, then any of earlier frames reported now (a gap filled)
        f, i, b, c = targets.rows(number)
        track_rows.extend(f, i, b, c)
        if outputs.writer is not None:
            for g in dict.fromkeys([int(number), *np.unique(f).tolist()]):  # then by frame
                at = f == g
                outputs.writer.write(int(g), i[at], b[at], c[at])
        if outputs.video is not None:
            particles = None
            if show_particles:  # every replica's particles, for a plate
                x = np.asarray(record.beliefs[var].x)
                particles = ({var: x.reshape(-1, x.shape[-1])[
                    :, xy_columns(engine.graph, var)]} if x.size else None)
            gt_boxes = ignored = None
            if gt is not None:  # the scored boxes, and the ignored regions apart
                rows = gt.rows(number)
                gt_boxes, ignored = gt.boxes[rows][gt.scored[rows]], gt.boxes[rows][gt.ignore[rows]]
            words = f"{len(ids)} track{'s' if len(ids) != 1 else ''}"
            if show_particles and targets.text:
                words += f"  {targets.text}"
            outputs.video.write(annotate(image, boxes=boxes, ids=ids.tolist(),
                                         gt_boxes=gt_boxes, particles=particles,
                                         ignore_boxes=ignored if ignored is not None
                                         and len(ignored) else None,
                                         trails=trail.update(ids.tolist(), boxes),
                                         legend=True,
                                         text=frame_caption(graph.name, number, words)))
        if outputs.recorder is not None:
            outputs.recorder.write(engine, record, image, detections=dets,
                                   dropped=number in dropped,
                                   targets={"ids": ids, "boxes": boxes, "scores": conf,
                                            "text": targets.text})

    t_start = time.perf_counter()
    n, secs, number = run_frames(source.frames(), engine, outputs, max_frames=max_frames,
                                 context=context, emit=emit)
    if outputs.writer is not None:  # a finished run's rows in frame order (some came late)
        outputs.writer.sort_by_frame()
    wall = time.perf_counter() - t_start
    secs += motion.seconds  # the camera's motion is inference too
    table = track_rows.table()
    metrics = None
    if gt is not None:
        last = int(number)
        metrics = evaluate_mot(gt.until(last), table, num_frames=last)
        metrics["fps"] = n / secs if secs > 0 else 0.0
        metrics["detector_fps"] = n / det_secs if det_secs > 0 else 0.0
    result = MultiTrackResult(table, metrics, secs, det_secs, n, out, sigmas, wall)
    if out is not None:
        if metrics is not None:
            write_json(out / "metrics.json", metrics)
        run.update({"frames": n, "last_frame": int(number), "inference_seconds": secs,
                    "detector_seconds": det_secs, "fps": result.fps,
                    "wall_seconds": wall, "fps_end_to_end": result.end_to_end_fps,
                    "camera_motion_frames": motion.frames_moved,
                    "camera_motion_seconds": motion.seconds,
                    "video": outputs.video is not None, **outputs.summary()})
        if sigmas:
            run["noise_sigma_per_frame"] = sigmas
        write_json(out / "model.json", engine.graph.to_dict())
        write_run_status(out, run, complete=True)  # last: the folder is now complete
    return result
