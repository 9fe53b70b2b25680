"""The one run loop of :func:`pgm.app.runner.track` and :func:`~pgm.app.runner.track_multi`:
frames in, the engine stepped and timed, results handed out as they come, and a run that
stops — an error, a signal — leaving its folder saying so."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pgm.app.record import Recorder, RecordSettings, record_settings
from pgm.core.errors import InputError, Interrupted, uninterrupted, user_message
from pgm.core.frame import FrameContext
from pgm.inference.engine import Engine, StepRecord
from pgm.io.annotated_video import AnnotatedVideoWriter
from pgm.io.outputs import write_run_status

__all__ = ["RunOutputs", "run_frames"]


@dataclass
class RunOutputs:
    """What a run writes as it goes (each optional) and closes however it ends: its
    folder, its ``run.json`` fields so far, the progress bar, the result, video and
    record writers."""

    out: Path | None
    run: dict[str, Any] = field(default_factory=dict)
    bar: Any = None
    writer: Any = None
    video: AnnotatedVideoWriter | None = None
    recorder: Recorder | None = None

    def close(self) -> None:
        _close(self.bar, self.writer, self.video, self.recorder)

    def summary(self) -> dict[str, Any]:
        """What ``run.json`` says about the video's codec and the record."""
        return _outputs(self.video, self.recorder)


def run_frames(frames: Iterable[tuple[int, np.ndarray]], engine: Engine,
               outputs: RunOutputs, *, max_frames: int | None,
               context: Callable[[int, np.ndarray], tuple[FrameContext, Any]],
               emit: Callable[[int, np.ndarray, StepRecord, Any], None]
               ) -> tuple[int, float, int]:
    """Step ``engine`` through ``frames`` (at most ``max_frames``): each frame's size is
    checked against the first's, its :class:`FrameContext` built by ``context(number,
    image) -> (ctx, extra)``, the engine's step timed (the inference seconds: decoding,
    detecting, drawing and writing excluded), and ``emit(number, image, record, extra)``
    writes what the frame gave. However the loop ends the writers are closed; a run that
    stops writes ``run.json`` with why and what it completed, and no frame at all is an
    :class:`InputError`. Returns ``(frames, inference seconds, last frame number)``."""
    first: tuple[int, int] | None = None
    n, secs, last = 0, 0.0, None
    try:
        for k, (number, image) in enumerate(frames):
            if max_frames is not None and k >= max_frames:
                break
            first = _check_frame_size(first, image, number)
            ctx, extra = context(number, image)
            t0 = time.perf_counter()
            record = engine.step(ctx)
            secs += time.perf_counter() - t0
            with uninterrupted():  # a frame's outputs are written whole and counted
                emit(number, image, record, extra)
                n, last = n + 1, int(number)
            if outputs.bar is not None:
                outputs.bar.update(1)
    except BaseException as exc:
        outputs.close()
        if outputs.out is not None:
            _record_stop(outputs.out, {**outputs.run, **outputs.summary(), "frames": n,
                                       "last_frame": last}, exc)
        raise
    outputs.close()
    if n == 0:
        if outputs.out is not None:
            _record_stop(outputs.out, {**outputs.run, "frames": 0},
                         InputError("the source has no frames"))
        raise InputError("the source has no frames")
    return n, secs, int(last)


def progress_bar(progress: bool, total: int | None, name: str) -> Any:
    """A tqdm bar when ``progress`` (none when stderr is not a terminal)."""
    if not progress:
        return None
    from tqdm import tqdm

    return tqdm(total=total, unit="frame", desc=name, leave=False, disable=None)


def _close(*things) -> None:
    """Close the progress bar, result writer, video writer and recorder that were opened."""
    for thing in things:
        if thing is not None:
            thing.close()


def _record_settings(record: bool | RecordSettings | dict | None,
                     out_dir: str | Path | None) -> RecordSettings | None:
    """The recording settings of a run (``None``: off); recording needs an output folder."""
    settings = record_settings(record)
    if settings is not None and out_dir is None:
        raise InputError("recording a run (record=...) needs an output folder (out_dir)")
    return settings


def _outputs(video: AnnotatedVideoWriter | None, recorder: Recorder | None) -> dict[str, Any]:
    """What ``run.json`` says about the video's codec and the record (when there are)."""
    out: dict[str, Any] = {}
    if video is not None and video.codec is not None:
        out["video_codec"] = video.codec
    if recorder is not None:
        out["record"] = recorder.summary()
    return out


def _check_frame_size(first: tuple[int, int] | None, image: np.ndarray,
                      number: int) -> tuple[int, int]:
    """Every frame must have the first frame's ``(width, height)`` (also for an iterable
    of frames that is no :class:`FrameSource`); returns that size."""
    h, w = image.shape[:2]
    if first is not None and (w, h) != tuple(first):
        raise InputError(f"frame {number} is {w}x{h} but the sequence's frames are "
                         f"{first[0]}x{first[1]}; every frame must have the same size")
    return (int(w), int(h)) if first is None else first


def _record_stop(out: Path, info: dict[str, Any], exc: BaseException) -> None:
    """``run.json`` of a run that did not finish: ``"complete": false`` and why."""
    if isinstance(exc, Interrupted):
        why = f"interrupted by {exc.name}"
    elif isinstance(exc, KeyboardInterrupt):
        why = "interrupted by SIGINT"
    else:
        msg = user_message(exc)
        why = f"error: {msg}" if msg is not None else f"internal error: {type(exc).__name__}"
    try:
        write_run_status(out, info, complete=False, stopped=why)
    except (OSError, ValueError):  # the original failure matters more than this record
        pass
