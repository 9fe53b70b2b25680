"""Writing tracks in the standard formats: MOTChallenge result rows
(:class:`MotWriter`, as a run goes) and OTB ``groundtruth_rect.txt`` files
(:func:`write_otb_groundtruth`). The readers are in :mod:`pgm.io.annotations`."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import IO

import numpy as np

from pgm.core.errors import InputError

__all__ = ["MotWriter", "format_numbers", "write_otb_groundtruth"]


def format_numbers(values: np.ndarray, decimals: int = 3) -> list[str]:
    """Numbers with up to ``decimals`` decimals, trailing zeros dropped (``71.0`` -> ``71``)."""
    out = []
    for v in np.round(np.asarray(values, dtype=float), decimals).reshape(-1).tolist():
        s = f"{v:.{decimals}f}"
        s = s.rstrip("0").rstrip(".") if "." in s else s  # an integer keeps its zeros
        out.append("0" if s == "-0" else s)
    return out


#: a number's trailing zeros after its decimal point, and then a point left bare, and a
#: negative zero: what :func:`format_numbers` drops, found in a whole block of rows at once
_TRAILING_ZEROS = re.compile(r"(\.\d*?)0+(?=[,\n])")
_BARE_POINT = re.compile(r"\.(?=[,\n])")
_NEGATIVE_ZERO = re.compile(r"(?<=,)-0(?=[,\n])")


def _mot_rows(frame: int, ids: list[int], values: np.ndarray, decimals: int) -> str:
    """Rows ``frame,id,x,y,w,h,conf,-1,-1,-1`` of ``values`` ``(n, 5)`` (1-based
    ``x, y, w, h, conf``), each number as :func:`format_numbers` writes it: formatted in
    one pass over the rows and trimmed by three substitutions over the block (the same
    text, tested; :meth:`MotWriter.write` of 25 rows 95 µs against 125 number by
    number)."""
    row = f"{int(frame)},%d" + f",%.{decimals}f" * 5 + ",-1,-1,-1\n"
    text = "".join([row % (i, *v) for i, v in
                    zip(ids, np.round(values, decimals).tolist(), strict=True)])
    text = _BARE_POINT.sub("", _TRAILING_ZEROS.sub(r"\1", text))
    return _NEGATIVE_ZERO.sub("0", text) if "-0" in text else text


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
        #: whether every row so far came at a frame no earlier than the rows before it (a
        #: tracker that reports a frame late: a gap filled, a track's tentative frames)
        self.in_frame_order = True
        self._last_frame = 0

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
        values = np.column_stack([boxes, conf])
        values[:, :2] += 1.0
        self._fh.write(_mot_rows(frame, ids_a.astype(np.int64).tolist(), values,
                                 self.decimals))
        self.in_frame_order &= int(frame) >= self._last_frame
        self._last_frame = max(self._last_frame, int(frame))
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

    def sort_by_frame(self) -> None:
        """After :meth:`close`: the file's rows put in frame order where some came late
        (a stable sort: a frame's rows keep the order they were written in), replacing the
        file in one step; nothing to do when they came in order. A run that finishes
        calls it; an interrupted run's file keeps the rows in the order they were
        reported."""
        if self._fh is not None:
            raise InputError(f"MotWriter for {self.path}: close it before sorting its rows")
        if self.in_frame_order:
            return
        sorting = self.path.with_name(self.path.name + ".sorting")
        try:
            lines = self.path.read_text(encoding="utf-8").splitlines(keepends=True)
            frames = np.array([int(line[:line.index(",")]) for line in lines], dtype=np.int64)
            with open(sorting, "w", encoding="utf-8", newline="\n") as fh:
                fh.write("".join([lines[i] for i in np.argsort(frames, kind="stable")]))
            os.replace(sorting, self.path)
        except OSError as exc:  # the rows as written are kept
            raise InputError(f"cannot put {self.path} in frame order: "
                             f"{' '.join(str(exc).split())}") from None
        self.in_frame_order = True

    def close(self) -> None:
        """Close the file (idempotent)."""
        if self._fh is not None:
            self._fh.close()
            self._fh = None

    def __enter__(self) -> MotWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
