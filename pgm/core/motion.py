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

from collections.abc import Sequence

import numpy as np

__all__ = ["warp_states", "motion_scale", "POSITION_PAIRS", "linear_state_warp"]

#: label pairs read as an image position, in order of preference
POSITION_PAIRS = (("cx", "cy"), ("px", "py"), ("x", "y"))


def _index(labels: Sequence[str], name: str) -> int | None:
    return labels.index(name) if name in labels else None


def motion_scale(affine: np.ndarray) -> float:
    """The scale ``sqrt(|det M|)`` of an image motion ``[M | t]``."""
    return float(np.sqrt(abs(np.linalg.det(np.asarray(affine, dtype=float)[:, :2]))))


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


def linear_state_warp(labels: Sequence[str], affine: np.ndarray | None
                      ) -> tuple[np.ndarray, np.ndarray] | None:
    """The image motion ``affine`` as a linear map ``x ↦ T x + c`` of a box state (a
    Gaussian's mean moves so, its covariance to ``T P Tᵀ``: camera-motion compensation of
    a Kalman tracker), read off the labels: corner pairs ``x1, y1`` / ``x2, y2``, centres
    ``cx, cy``, and positions ``x, y`` ``↦ M p + t``; their rates (``v`` + label) ``↦ M v``;
    sizes ``w, h`` (and their rates) ``↦ s ·``; an area ``s`` (and its rate) ``↦ s² ·``,
    with ``s = sqrt(|det M|)``; anything else is unchanged. None when there is no motion
    or no position in the labels."""
    if affine is None or not labels:
        return None
    labels = list(labels)
    A = np.asarray(affine, dtype=float)
    M, t = A[:, :2], A[:, 2]
    d = len(labels)
    T, c = np.eye(d), np.zeros(d)
    moved = False
    for a, b in (("x1", "y1"), ("x2", "y2"), ("cx", "cy"), ("px", "py"), ("x", "y")):
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
    scale = motion_scale(A)
    for name, power in (("w", 1), ("h", 1), ("s", 2)):
        for label in (name, f"v{name}"):
            if label in labels:
                k = labels.index(label)
                T[k, k] = scale ** power
    return T, c

