"""Writing tracks in the standard formats: MOTChallenge result rows
(:class:`MotWriter`, as a run goes) and OTB ``groundtruth_rect.txt`` files
(:func:`write_otb_groundtruth`). The readers are in :mod:`pgm.io.annotations`."""

from __future__ import annotations

from pathlib import Path
from typing import IO

import numpy as np

from pgm.core.errors import InputError

__all__ = ["MotWriter", "format_numbers", "write_otb_groundtruth"]


def format_numbers(values: np.ndarray, decimals: int = 3) -> list[str]:
    """Numbers with up to ``decimals`` decimals, trailing zeros dropped (``71.0`` -> ``71``)."""
    out = []
    for v in np.round(np.asarray(values, dtype=float), decimals).reshape(-1).tolist():
        s = f"{v:.{decimals}f}".rstrip("0").rstrip(".")
        out.append("0" if s in ("-0", "") else s)
    return out


def write_otb_groundtruth(path: str | Path, boxes_xywh0: np.ndarray, decimals: int = 6) -> Path:
    """Write an OTB ``groundtruth_rect.txt``: one ``x,y,w,h`` line per frame (1-based
    top-left), ``NaN,NaN,NaN,NaN`` for a row of NaN (the object is not in the image)."""
    path = Path(path)
    boxes = np.asarray(boxes_xywh0, dtype=float).reshape(-1, 4)
    lines = []
    for b in boxes:
        if not np.all(np.isfinite(b)):
            lines.append("NaN,NaN,NaN,NaN")
        else:
            lines.append(",".join(format_numbers(b + [1.0, 1.0, 0.0, 0.0], decimals)))
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(lines) + "\n")
    return path


class MotWriter:
    """Write MOTChallenge result rows ``frame,id,x,y,w,h,conf,-1,-1,-1``.

    Boxes are given 0-based top-left and written 1-based (``x + 1, y + 1``), numbers
    with up to 3 decimals. The file is created (parent folders too) and truncated on
    construction (a symbolic link at ``path`` is replaced, not followed), and flushed
    after each :meth:`write`, so an interrupted run keeps every frame it finished. Use
    as a context manager or call :meth:`close`.

    Parameters
    ----------
    path : str or Path
        Output file.
    decimals : int
        Decimals written (3 for tracker output; ground truth keeps more).

    Examples
    --------
    >>> with MotWriter(tmp / "tracks.txt") as w:           # doctest: +SKIP
    ...     w.write(1, [3], [[10.0, 20.0, 30.0, 60.0]], [0.9])
    """

    def __init__(self, path: str | Path, decimals: int = 3) -> None:
        self.path = Path(path)
        self.decimals = int(decimals)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            if self.path.is_symlink():  # replaced, never followed (its target is kept)
                self.path.unlink()
            self._fh: IO[str] | None = open(self.path, "w", encoding="utf-8", newline="\n")
        except OSError as exc:
            raise InputError(f"cannot write {self.path}: {' '.join(str(exc).split())}"
                             ) from None
        self.rows_written = 0

    def write(self, frame: int, ids: np.ndarray, boxes_xywh0: np.ndarray,
              confs: np.ndarray | float | None = None) -> None:
        """Append the boxes of one frame.

        Parameters
        ----------
        frame : int
            1-based frame number.
        ids : array of int, shape (n,)
            Track identities.
        boxes_xywh0 : array, shape (n, 4)
            Top-left ``(x, y, w, h)``, 0-based internal coordinates.
        confs : array, shape (n,), or float, optional
            Confidence per box (default 1).
        """
        if self._fh is None:
            raise InputError(f"MotWriter for {self.path} is closed")
        ids_a = np.asarray(ids).reshape(-1)
        boxes = np.asarray(boxes_xywh0, dtype=float).reshape(-1, 4)
        n = boxes.shape[0]
        conf = np.asarray(1.0 if confs is None else confs, dtype=float)
        conf = np.full(n, float(conf)) if conf.ndim == 0 else conf.reshape(-1)
        if int(frame) != frame or frame < 1:
            raise InputError(f"frame must be an integer >= 1 (got {frame!r}) for {self.path}")
        if ids_a.shape[0] != n or conf.shape[0] != n:
            raise InputError(f"{ids_a.shape[0]} ids, {n} boxes and {conf.shape[0]} confidences"
                             f" for frame {frame} of {self.path}")
        if n == 0:
            return
        if not np.all(np.isfinite(boxes)) or not np.all(np.isfinite(conf)):
            raise InputError(f"non-finite box or confidence in frame {frame} of {self.path}")
        out = boxes.copy()
        out[:, :2] += 1.0
        cols = [format_numbers(out[:, j], self.decimals) for j in range(4)] + \
            [format_numbers(conf, self.decimals)]
        ids_i = ids_a.astype(np.int64).tolist()
        f = int(frame)
        text = "".join(f"{f},{i},{x},{y},{w},{h},{c},-1,-1,-1\n"
                       for i, x, y, w, h, c in zip(ids_i, *cols, strict=True))
        self._fh.write(text)
        self._fh.flush()
        self.rows_written += n

    def write_rows(self, frames: np.ndarray, ids: np.ndarray, boxes_xywh0: np.ndarray,
                   confs: np.ndarray | None = None) -> None:
        """Append many rows at once, frame by frame in the order given (a whole table)."""
        frames = np.asarray(frames).reshape(-1)
        ids = np.asarray(ids).reshape(-1)
        boxes = np.asarray(boxes_xywh0, dtype=float).reshape(-1, 4)
        conf = np.ones(len(frames)) if confs is None else np.asarray(confs, float).reshape(-1)
        if not len(frames) == len(ids) == len(boxes) == len(conf):
            raise InputError(f"{len(frames)} frames, {len(ids)} ids, {len(boxes)} boxes and "
                             f"{len(conf)} confidences for {self.path}")
        cut = np.flatnonzero(np.diff(frames) != 0) + 1
        for lo, hi in zip(np.r_[0, cut], np.r_[cut, len(frames)], strict=True):
            if hi > lo:
                self.write(frames[lo], ids[lo:hi], boxes[lo:hi], conf[lo:hi])

    def close(self) -> None:
        """Close the file (idempotent)."""
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def __enter__(self) -> MotWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
