"""Annotated video output: an MP4 written frame by frame, playable in a browser.

:class:`AnnotatedVideoWriter` writes frames as they come, so an interrupted run keeps
the frames written so far; :func:`pgm.plotting.annotate.annotate` draws them.

The video is H.264 (``yuv420p``, even width and height: what every browser plays),
encoded by PyAV's bundled FFmpeg with ``libx264``. Where PyAV is not installed, lacks
an H.264 encoder or cannot open the file, the writer falls back to OpenCV's MPEG-4
part 2 writer (``mp4v``), which desktop players read but browsers refuse. Which one
was used is :attr:`AnnotatedVideoWriter.codec` (``"h264"`` or ``"mp4v"``; the runners
write it to ``run.json`` as ``"video_codec"``) and is logged (logger ``pgm``) when the
fallback is taken.
"""

from __future__ import annotations

import logging
import queue
import threading
from fractions import Fraction
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from pgm.core.errors import InputError, uninterrupted

__all__ = ["AnnotatedVideoWriter", "CODECS", "h264_available", "video_scale",
           "DEFAULT_MAX_SIDE"]

log = logging.getLogger("pgm")

#: codecs the writer can be asked for: ``"auto"`` is H.264 with the ``mp4v`` fallback
CODECS = ("auto", "h264", "mp4v")

#: x264 settings: quality-based rate control, a fast preset (annotation is drawn on the
#: tracker's time budget), ``yuv420p`` for browsers
_X264_OPTIONS = {"crf": "23", "preset": "veryfast"}


def h264_available() -> bool:
    """Whether PyAV is installed with an H.264 encoder (``libx264``)."""
    try:
        import av
    except ImportError:
        return False
    try:
        av.codec.Codec("libx264", "w")
    except Exception:  # noqa: BLE001 - any failure means "not available"
        return False
    return True


class _PyAVSink:
    """H.264 in MP4 through PyAV (``libx264``, ``yuv420p``)."""

    codec = "h264"

    def __init__(self, path: Path, fps: float, size: tuple[int, int]):
        import av

        self._container = av.open(str(path), mode="w", format="mp4")
        try:
            rate = Fraction(fps).limit_denominator(1001)
            self._stream = self._container.add_stream("libx264", rate=rate,
                                                      options=dict(_X264_OPTIONS))
            self._stream.width, self._stream.height = size
            self._stream.pix_fmt = "yuv420p"
        except BaseException:
            self._container.close()
            raise
        self._av = av
        self._pts = 0

    def write(self, bgr: np.ndarray) -> None:
        frame = self._av.VideoFrame.from_ndarray(bgr, format="bgr24")
        frame.pts = self._pts
        self._pts += 1
        for packet in self._stream.encode(frame):
            self._container.mux(packet)

    def close(self) -> None:
        try:
            for packet in self._stream.encode(None):  # flush the encoder's delayed frames
                self._container.mux(packet)
        finally:
            self._container.close()


class _OpenCVSink:
    """MPEG-4 part 2 (``mp4v``) through OpenCV: the fallback."""

    codec = "mp4v"

    def __init__(self, path: Path, fps: float, size: tuple[int, int]):
        self._writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, size)
        if not self._writer.isOpened():
            raise InputError(f"cannot open video writer for {path}")

    def write(self, bgr: np.ndarray) -> None:
        self._writer.write(bgr)

    def close(self) -> None:
        self._writer.release()


#: the long side, in pixels, that the annotated video is scaled down to by default (a 1080p
#: video is written at 1280x720: four ninths of the pixels to encode, and what a screen
#: shows of it anyway)
DEFAULT_MAX_SIDE = 1280

#: frames waiting for the encoder thread at most (bounded memory: the tracker waits
#: when the encoder falls this far behind)
QUEUE_FRAMES = 8


def video_scale(frame_size: tuple[int, int], scale: float | None = None) -> float:
    """The scale a frame of ``(width, height)`` is written at: ``scale`` when given (in
    ``(0, 1]``), else so that its long side is at most :data:`DEFAULT_MAX_SIDE` (1: a
    smaller frame is never enlarged)."""
    if scale is not None:
        s = float(scale)
        if not (np.isfinite(s) and 0 < s <= 1):
            raise InputError(f"the video scale must be in (0, 1], got {scale!r}")
        return s
    return min(1.0, DEFAULT_MAX_SIDE / max(frame_size))


class AnnotatedVideoWriter:
    """Write frames to an MP4 file as they come (opened on the first frame).

    Use as a context manager; every :meth:`write` is one frame. With ``background``
    (the default) the frames are scaled and encoded by a thread of their own, up to
    :data:`QUEUE_FRAMES` behind (the encoder releases the interpreter: on two cores the
    tracker does not wait for it); :meth:`close` waits for every frame to be in the file,
    and an encoder failure is raised by the next :meth:`write` or by :meth:`close`.

    Parameters
    ----------
    path : str or Path
        The MP4 file (a symbolic link there is replaced, never followed).
    fps : float
        Frame rate (25 when not a positive finite number).
    codec : {"auto", "h264", "mp4v"}
        ``"auto"`` (default): H.264 through PyAV, else OpenCV's ``mp4v``; ``"h264"``:
        H.264 or an :class:`InputError`; ``"mp4v"``: OpenCV's writer.
    scale : float, optional
        Frames are written at this scale (``(0, 1]``); None (the default): so that the
        long side is at most :data:`DEFAULT_MAX_SIDE` (:func:`video_scale`).
    background : bool
        Encode in a thread of its own (True) or in :meth:`write` (False).

    Attributes
    ----------
    codec : str or None
        The codec written (``"h264"`` or ``"mp4v"``), known once the first frame is
        written.
    size : tuple of int or None
        ``(width, height)`` of the video; H.264 needs both even, so an odd frame is
        padded by one row or column (its last one repeated).
    frames_written : int
    """

    def __init__(self, path: str | Path, fps: float = 25.0, codec: str = "auto",
                 scale: float | None = None, background: bool = True):
        if codec not in CODECS:
            raise ValueError(f"unknown video codec {codec!r} (choose from {CODECS})")
        self.path = Path(path)
        self.fps = float(fps) if fps and np.isfinite(fps) and fps > 0 else 25.0
        self.requested = codec
        if scale is not None:
            video_scale((1, 1), scale)  # checked now, not at the first frame
        self.scale = scale
        self._sink: _PyAVSink | _OpenCVSink | None = None
        self._frame_size: tuple[int, int] | None = None
        self._out_size: tuple[int, int] | None = None
        self.size: tuple[int, int] | None = None
        self.codec: str | None = None
        self.frames_written = 0
        self.background = bool(background)
        self._queue: queue.Queue | None = None
        self._thread: threading.Thread | None = None
        self._failure: BaseException | None = None

    def _open(self, frame_w: int, frame_h: int) -> None:
        s = video_scale((frame_w, frame_h), self.scale)
        w, h = max(2, int(round(frame_w * s))), max(2, int(round(frame_h * s)))
        self._out_size = (w, h)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.is_symlink():  # replaced, never followed
            self.path.unlink()
        sink: Any = None
        if self.requested in ("auto", "h264"):
            size = (w + w % 2, h + h % 2)
            try:
                sink = _PyAVSink(self.path, self.fps, size)
            except Exception as exc:  # noqa: BLE001 - no PyAV, no libx264, FFmpeg refused
                if self.requested == "h264":
                    raise InputError(f"cannot write H.264 video {self.path}: "
                                     f"{type(exc).__name__}: {exc}") from None
                log.warning("H.264 video writer unavailable (%s: %s); writing MPEG-4 part 2 "
                            "(mp4v), which browsers do not play", type(exc).__name__, exc)
                self.path.unlink(missing_ok=True)
        if sink is None:
            size = (w, h)
            sink = _OpenCVSink(self.path, self.fps, size)
        self._sink, self.size, self.codec = sink, size, sink.codec
        self._frame_size = (frame_w, frame_h)
        if self.background:
            self._queue = queue.Queue(maxsize=QUEUE_FRAMES)
            self._thread = threading.Thread(target=self._encode_all, name="pgm-video",
                                            daemon=True)
            self._thread.start()

    def write(self, image: np.ndarray) -> None:
        """Append one BGR (or grey) frame; all frames must have the first frame's size
        (a frame of another size is resized to it)."""
        if self._failure is not None:
            self._raise_failure()
        if image.ndim == 2:
            image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        h, w = image.shape[:2]
        if self._sink is None:
            self._open(w, h)
        elif (w, h) != self._frame_size:
            image = cv2.resize(image, self._frame_size)
        if self._queue is not None:
            self._queue.put(np.array(image, dtype=np.uint8))  # the caller may reuse its own
        else:
            self._encode(image)

    def _encode(self, image: np.ndarray) -> None:
        """Scale, pad and mux one frame (in the encoder thread, or in :meth:`write`)."""
        if self._out_size != self._frame_size:
            image = cv2.resize(image, self._out_size, interpolation=cv2.INTER_AREA)
        image = np.ascontiguousarray(image, dtype=np.uint8)
        pad_w, pad_h = self.size[0] - self._out_size[0], self.size[1] - self._out_size[1]
        if pad_w or pad_h:
            image = cv2.copyMakeBorder(image, 0, pad_h, 0, pad_w, cv2.BORDER_REPLICATE)
        if threading.current_thread() is threading.main_thread():
            with uninterrupted():  # a signal waits for the frame to be muxed
                self._sink.write(image)
        else:  # signals reach the main thread only: nothing cuts the encoder thread
            self._sink.write(image)
        self.frames_written += 1

    def _encode_all(self) -> None:
        """The encoder thread: every queued frame, until the end mark (None). After a
        failure it keeps taking frames (so the tracker never waits on a full queue)."""
        while True:
            image = self._queue.get()
            if image is None:
                return
            if self._failure is None:
                try:
                    self._encode(image)
                except BaseException as exc:  # noqa: BLE001 - handed to the caller
                    self._failure = exc

    def _raise_failure(self) -> None:
        exc, self._failure = self._failure, None
        if isinstance(exc, InputError):
            raise exc
        raise InputError(f"cannot write video {self.path}: {type(exc).__name__}: {exc}")

    def close(self) -> None:
        """Finish the file (waits for the queued frames and flushes the encoder: every
        frame written is in the file)."""
        if self._thread is not None:
            thread, self._thread = self._thread, None
            self._queue.put(None)
            thread.join()
            self._queue = None
        if self._sink is not None:
            sink, self._sink = self._sink, None
            with uninterrupted():  # the index is written whole, or the file plays nothing
                sink.close()
        if self._failure is not None:
            self._raise_failure()

    def __enter__(self) -> AnnotatedVideoWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
