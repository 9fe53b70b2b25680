"""Annotated video output: an MP4 written frame by frame.

:class:`AnnotatedVideoWriter` writes an MP4 (``mp4v``) as frames come, so an interrupted
run keeps the frames written so far; :func:`pgm.plotting.annotate.annotate` draws them.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from pgm.core.errors import InputError

__all__ = ["AnnotatedVideoWriter"]


class AnnotatedVideoWriter:
    """Write frames to an MP4 file as they come (opened on the first frame).

    Use as a context manager; every :meth:`write` is one frame.
    """

    def __init__(self, path: str | Path, fps: float = 25.0):
        self.path = Path(path)
        self.fps = float(fps) if fps and np.isfinite(fps) and fps > 0 else 25.0
        self._writer: cv2.VideoWriter | None = None
        self._size: tuple[int, int] | None = None
        self.frames_written = 0

    def write(self, image: np.ndarray) -> None:
        """Append one BGR frame (all frames must have the first frame's size)."""
        h, w = image.shape[:2]
        if self._writer is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            if self.path.is_symlink():  # replaced, never followed
                self.path.unlink()
            self._writer = cv2.VideoWriter(str(self.path), cv2.VideoWriter_fourcc(*"mp4v"),
                                           self.fps, (w, h))
            if not self._writer.isOpened():
                raise InputError(f"cannot open video writer for {self.path}")
            self._size = (w, h)
        elif (w, h) != self._size:
            image = cv2.resize(image, self._size)
        self._writer.write(np.ascontiguousarray(image))
        self.frames_written += 1

    def close(self) -> None:
        """Finish the file."""
        if self._writer is not None:
            self._writer.release()
            self._writer = None

    def __enter__(self) -> AnnotatedVideoWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
