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
from fractions import Fraction
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from pgm.core.errors import InputError, uninterrupted

__all__ = ["AnnotatedVideoWriter", "CODECS", "h264_available"]

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


class AnnotatedVideoWriter:
    """Write frames to an MP4 file as they come (opened on the first frame).

    Use as a context manager; every :meth:`write` is one frame.

    Parameters
    ----------
    path : str or Path
        The MP4 file (a symbolic link there is replaced, never followed).
    fps : float
        Frame rate (25 when not a positive finite number).
    codec : {"auto", "h264", "mp4v"}
        ``"auto"`` (default): H.264 through PyAV, else OpenCV's ``mp4v``; ``"h264"``:
        H.264 or an :class:`InputError`; ``"mp4v"``: OpenCV's writer.

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

    def __init__(self, path: str | Path, fps: float = 25.0, codec: str = "auto"):
        if codec not in CODECS:
            raise ValueError(f"unknown video codec {codec!r} (choose from {CODECS})")
        self.path = Path(path)
        self.fps = float(fps) if fps and np.isfinite(fps) and fps > 0 else 25.0
        self.requested = codec
        self._sink: _PyAVSink | _OpenCVSink | None = None
        self._frame_size: tuple[int, int] | None = None
        self.size: tuple[int, int] | None = None
        self.codec: str | None = None
        self.frames_written = 0

    def _open(self, w: int, h: int) -> None:
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
        self._frame_size = (w, h)

    def write(self, image: np.ndarray) -> None:
        """Append one BGR (or grey) frame; all frames must have the first frame's size
        (a frame of another size is resized to it)."""
        if image.ndim == 2:
            image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        h, w = image.shape[:2]
        if self._sink is None:
            self._open(w, h)
        elif (w, h) != self._frame_size:
            image = cv2.resize(image, self._frame_size)
        image = np.ascontiguousarray(image, dtype=np.uint8)
        pad_w, pad_h = self.size[0] - self._frame_size[0], self.size[1] - self._frame_size[1]
        if pad_w or pad_h:
            image = cv2.copyMakeBorder(image, 0, pad_h, 0, pad_w, cv2.BORDER_REPLICATE)
        with uninterrupted():  # a signal waits for the frame to be muxed
            self._sink.write(image)
        self.frames_written += 1

    def close(self) -> None:
        """Finish the file (flushes the encoder: every frame written is in the file)."""
        if self._sink is not None:
            sink, self._sink = self._sink, None
            with uninterrupted():  # the index is written whole, or the file plays nothing
                sink.close()

    def __enter__(self) -> AnnotatedVideoWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
