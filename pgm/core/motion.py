"""Moving a variable's states through the camera's image motion.

When the camera moves, a target that stands still in the world moves in the image. A
transition factor predicts in image coordinates, so before it runs the engine maps
every particle's past states through the camera's motion since the previous frame —
an affine map ``p ↦ M p + t`` (:attr:`pgm.core.frame.FrameContext.camera_motion`) —
read off the variable's labels:

* positions (``cx, cy``, ``px, py`` or ``x, y``) ``↦ M p + t``;
* velocities (``vx, vy``) ``↦ M v``;
* sizes (``w, h``) ``↦ s · size`` with ``s = sqrt(|det M|)`` (the map's scale);
* a log-height (``log_h``) ``↦ log_h + log s``; anything else is unchanged.

A variable whose labels name no position is left alone.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np

__all__ = ["warp_states", "motion_scale", "POSITION_PAIRS", "linear_state_warp"]

#: label pairs read as an image position, in order of preference
POSITION_PAIRS = (("cx", "cy"), ("px", "py"), ("x", "y"))


def _index(labels: Sequence[str], name: str) -> int | None:
    return labels.index(name) if name in labels else None


def motion_scale(affine: np.ndarray) -> float:
    """The scale ``sqrt(|det M|)`` of an image motion ``[M | t]``."""
    (a, b), (c, d) = np.asarray(affine, dtype=float)[:, :2].tolist()
    return math.sqrt(abs(a * d - b * c))


def warp_states(x: np.ndarray, labels: Sequence[str] | None,
                affine: np.ndarray | None) -> np.ndarray:
    """States ``x`` ``(N, d)`` moved through the image motion ``affine`` ``(2, 3)``.

    Returns ``x`` itself when there is nothing to do (no motion, or no position
    labels), else a new array.
    """
    if affine is None or not labels:
        return x
    labels = list(labels)
    pos = next(((labels.index(a), labels.index(b)) for a, b in POSITION_PAIRS
                if a in labels and b in labels), None)
    if pos is None:
        return x
    A = np.asarray(affine, dtype=float)
    M, t = A[:, :2], A[:, 2]
    out = np.array(x, dtype=float, copy=True)
    i, j = pos
    out[:, [i, j]] = x[:, [i, j]] @ M.T + t
    vx, vy = _index(labels, "vx"), _index(labels, "vy")
    if vx is not None and vy is not None:
        out[:, [vx, vy]] = x[:, [vx, vy]] @ M.T
    s = motion_scale(A)
    for name in ("w", "h"):
        k = _index(labels, name)
        if k is not None:
            out[:, k] = x[:, k] * s
    k = _index(labels, "log_h")
    if k is not None and s > 0:
        out[:, k] = x[:, k] + np.log(s)
    return out


def linear_state_warp(labels: Sequence[str], affine: np.ndarray | None, sizes: str = "scale"
                      ) -> tuple[np.ndarray, np.ndarray] | None:
    """The image motion ``affine`` as a linear map ``x ↦ T x + c`` of a box state (a
    Gaussian's mean moves so, its covariance to ``T P Tᵀ``: camera-motion compensation of
    a Kalman tracker), read off the labels: corner pairs ``x1, y1`` / ``x2, y2``, centres
    ``cx, cy``, and positions ``x, y`` ``↦ M p + t``; their rates (``v`` + label) ``↦ M v``;
    sizes ``w, h`` (and their rates) ``↦ s ·``; an area ``s`` (and its rate) ``↦ s² ·``,
    with ``s = sqrt(|det M|)``; anything else is unchanged. None when there is no motion
    or no position in the labels.

    ``sizes="keep"``: only the box's centre and its rate move (``M c + t``, ``M v``); its
    width and height and their rates stay as they are — BoT-SORT's compensation of its
    centre-and-size state. A corner state keeps its size so too: the map acts on the
    corners' mean and difference (``T = J⁻¹ B J`` with ``J`` the corners' change to
    centre and size)."""
    if sizes not in ("scale", "keep"):
        raise ValueError(f"sizes must be 'scale' or 'keep', got {sizes!r}")
    if affine is None or not labels:
        return None
    A = np.ascontiguousarray(affine, dtype=float)
    if A.shape != (2, 3):
        raise ValueError(f"an image motion is a (2, 3) array [M | t], got shape {A.shape}")
    return _linear_state_warp(tuple(labels), A.tobytes(), sizes)


@functools.lru_cache(maxsize=64)
def _linear_state_warp(labels: tuple[str, ...], affine: bytes, sizes: str
                       ) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`linear_state_warp` of one frame's motion (kept: a frame's motion moves every
    track's state, its last observations and the recovery round's boxes by the same map;
    the arrays are read-only)."""
    out = _state_warp(list(labels), np.frombuffer(affine).reshape(2, 3), sizes)
    if out is not None:
        for a in out:
            a.setflags(write=False)
    return out


def _state_warp(labels: list[str], A: np.ndarray, sizes: str
                ) -> tuple[np.ndarray, np.ndarray] | None:
    M, t = A[:, :2], A[:, 2]
    d = len(labels)
    T, c = np.eye(d), np.zeros(d)
    moved = False
    if sizes == "keep" and all(k in labels for k in ("x1", "y1", "x2", "y2")):
        # corners: centre (x1 + x2) / 2 moves through the motion, the size x2 - x1 does not
        for prefix in ("", "v"):
            names = [prefix + k for k in ("x1", "y1", "x2", "y2")]
            if not all(k in labels for k in names):
                continue
            idx = [labels.index(k) for k in names]
            J = np.array([[0.5, 0, 0.5, 0], [0, 0.5, 0, 0.5], [-1, 0, 1, 0], [0, -1, 0, 1]])
            B = np.eye(4)
            B[:2, :2] = M
            T[np.ix_(idx, idx)] = np.linalg.solve(J, B @ J)
            if not prefix:
                c[idx] = np.linalg.solve(J, np.r_[t, 0.0, 0.0])
                moved = True
        pairs = (("px", "py"), ("x", "y"))
    else:
        pairs = (("x1", "y1"), ("x2", "y2"), ("cx", "cy"), ("px", "py"), ("x", "y"))
    for a, b in pairs:
        if a in labels and b in labels:
            i, j = labels.index(a), labels.index(b)
            T[np.ix_([i, j], [i, j])] = M
            c[[i, j]] = t
            moved = True
            if f"v{a}" in labels and f"v{b}" in labels:
                vi, vj = labels.index(f"v{a}"), labels.index(f"v{b}")
                T[np.ix_([vi, vj], [vi, vj])] = M
    if not moved:
        return None
    if sizes == "keep":
        return T, c
    scale = motion_scale(A)
    for name, power in (("w", 1), ("h", 1), ("s", 2)):
        for label in (name, f"v{name}"):
            if label in labels:
                k = labels.index(label)
                T[k, k] = scale ** power
    return T, c
