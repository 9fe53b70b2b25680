"""Trajectories for a GPDM: ground-truth tracks and box differences in box heights per
second (see :mod:`pgm.dynamics.gpdm`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.boxes import xywh_to_cxcywh

from .gpdm_model import _float_in, _int_at_least

# --------------------------------------------------------------------------- data


@dataclass(frozen=True)
class Trajectory:
    """One target's boxes in consecutive frames.

    Attributes
    ----------
    boxes : ndarray, shape (T, 4)
        ``(cx, cy, w, h)`` per frame, 0-based pixels.
    frames : ndarray of int, shape (T,)
        Consecutive frame numbers.
    fps : float
        Frame rate of the sequence.
    target : int
        Identity in the source.
    source : str
        Where it came from (e.g. the sequence name).
    """

    boxes: np.ndarray
    frames: np.ndarray
    fps: float
    target: int = -1
    source: str = ""

    def __post_init__(self) -> None:
        b = np.array(self.boxes, dtype=float)
        if b.ndim != 2 or b.shape[1] != 4 or b.shape[0] < 1:
            raise ValueError(f"Trajectory boxes must have shape (T, 4), got {b.shape}")
        if not np.all(np.isfinite(b)) or np.any(b[:, 2:] <= 0):
            raise ValueError("Trajectory boxes must be finite with positive width and height")
        f = np.array(self.frames, dtype=np.int64).reshape(-1)
        if f.shape[0] != b.shape[0]:
            raise ValueError(f"Trajectory has {b.shape[0]} boxes but {f.shape[0]} frames")
        if np.any(np.diff(f) != 1):
            raise ValueError("Trajectory frames must be consecutive")
        object.__setattr__(self, "boxes", b)
        object.__setattr__(self, "frames", f)
        object.__setattr__(self, "fps", _float_in("fps", self.fps, 0.0, 1e4))

    def __len__(self) -> int:
        return int(self.boxes.shape[0])


def gt_trajectories(table: Any, *, fps: float, min_length: int = 10, source: str = ""
                    ) -> list[Trajectory]:
    """Per-person trajectories of consecutive frames from a MOTChallenge ground truth.

    Parameters
    ----------
    table : MotTable
        ``pgm.io.annotations.load_mot(path, kind='gt')`` (read by attribute:
        ``frames``, ``ids``, ``boxes`` top-left ``(x, y, w, h)`` and ``scored``; rows not
        scored — MOT15 flag-0 ignore regions, MOT16 non-pedestrian classes and
        ``consider`` = 0 — are dropped, so a person's track is cut where its rows are).
    fps : float
        The sequence's frame rate (``seqinfo.ini``), kept on each trajectory.
    min_length : int
        Keep runs of at least this many consecutive frames (≥ 2).
    source : str
        Stored on each trajectory.

    Returns
    -------
    list of Trajectory
        Sorted by identity, then first frame; a person with a gap gives several.
    """
    min_length = _int_at_least("min_length", min_length, 2)
    fps = _float_in("fps", fps, 0.0, 1e4)
    frames = np.asarray(table.frames, dtype=np.int64).reshape(-1)
    ids = np.asarray(table.ids, dtype=np.int64).reshape(-1)
    boxes = np.asarray(table.boxes, dtype=float).reshape(-1, 4)
    scored = getattr(table, "scored", None)
    if scored is None:
        ignore = getattr(table, "ignore", None)
        scored = np.ones(frames.shape[0], bool) if ignore is None else ~np.asarray(ignore)
    keep = np.asarray(scored, dtype=bool).reshape(-1)
    frames, ids, boxes = frames[keep], ids[keep], boxes[keep]
    order = np.lexsort((frames, ids))
    frames, ids, boxes = frames[order], ids[order], boxes[order]
    same_id = ids[1:] == ids[:-1]
    if np.any(same_id & (frames[1:] == frames[:-1])):
        i = int(np.flatnonzero(same_id & (frames[1:] == frames[:-1]))[0])
        raise ValueError(f"identity {int(ids[i])} has two boxes in frame {int(frames[i])}"
                         + (f" of {source}" if source else ""))
    cuts = np.flatnonzero(~same_id | (frames[1:] - frames[:-1] != 1)) + 1
    starts = np.concatenate([[0], cuts])
    stops = np.concatenate([cuts, [frames.shape[0]]])
    cxcywh = xywh_to_cxcywh(boxes)
    return [Trajectory(cxcywh[a:b], frames[a:b], fps, int(ids[a]), source)
            for a, b in zip(starts, stops, strict=True) if b - a >= min_length]


def box_differences(boxes: np.ndarray, fps: float) -> np.ndarray:
    """Observations ``(Δcx, Δtop, Δh)`` in box heights per second, shape ``(T − 1, 3)``.

    ``y_t = (cx_t − cx_{t−1}, top_t − top_{t−1}, h_t − h_{t−1}) / h_{t−1} · fps`` for
    ``(cx, cy, w, h)`` boxes of consecutive frames (``top = cy − h/2``). Inverse of
    :func:`apply_differences`.
    """
    b = np.asarray(boxes, dtype=float)
    if b.ndim != 2 or b.shape[1] != 4:
        raise ValueError(f"boxes must have shape (T, 4), got {b.shape}")
    h = b[:, 3]
    top = b[:, 1] - h / 2.0
    d = np.stack([np.diff(b[:, 0]), np.diff(top), np.diff(h)], axis=1)
    return d / h[:-1, None] * float(fps)


def apply_differences(boxes: np.ndarray, y: np.ndarray, fps: float) -> np.ndarray:
    """Boxes ``(..., 4)`` moved by observations ``y`` ``(..., 3)`` in heights per second.

    The width keeps the box's aspect ratio; the height stays positive (at least 1 % of
    the previous height).
    """
    b = np.asarray(boxes, dtype=float)
    y = np.asarray(y, dtype=float)
    h = b[..., 3]
    step = y * (h / float(fps))[..., None]
    new_h = np.maximum(h + step[..., 2], 0.01 * h)
    top = b[..., 1] - h / 2.0 + step[..., 1]
    out = np.empty(np.broadcast_shapes(b.shape, y.shape[:-1] + (4,)))
    out[..., 0] = b[..., 0] + step[..., 0]
    out[..., 1] = top + new_h / 2.0
    out[..., 2] = b[..., 2] * (new_h / h)
    out[..., 3] = new_h
    return out
