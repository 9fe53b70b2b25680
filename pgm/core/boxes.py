"""Box conventions.

Inside the toolkit a box is ``(cx, cy, w, h)`` in 0-based continuous pixel
coordinates: pixel ``(row i, column j)`` covers ``[j, j+1) x [i, i+1)``, so a box with
top-left corner ``(x, y)`` and size ``(w, h)`` covers columns ``[x, x+w)`` and rows
``[y, y+h)``, and its centre is ``(x + w/2, y + h/2)``.
Files keep their own conventions: MOTChallenge and OTB store top-left ``x, y, w, h``
in 1-based (MATLAB) pixel coordinates; readers and writers convert at the boundary.
All functions are vectorised over a leading axis: ``(..., 4) -> (..., 4)``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["xywh_to_cxcywh", "cxcywh_to_xywh", "iou_xywh", "centre_xywh", "BOX_LABELS",
           "box_columns"]

#: the labels of a box variable's columns (centre, width, height)
BOX_LABELS = ("cx", "cy", "w", "h")


def box_columns(labels, what: str | None = None) -> list[int] | None:
    """Columns of ``cx, cy, w, h`` in a variable's ``labels``; ``None`` if it is not a
    box, or a ``ValueError`` starting with ``what`` when ``what`` is given."""
    if labels is not None and all(b in labels for b in BOX_LABELS):
        return [list(labels).index(b) for b in BOX_LABELS]
    if what is None:
        return None
    raise ValueError(f"{what} must have the labels cx, cy, w, h (a box), got {labels}")


def xywh_to_cxcywh(b: np.ndarray) -> np.ndarray:
    """Top-left ``(x, y, w, h)`` to centre ``(cx, cy, w, h)``."""
    b = np.asarray(b, dtype=float)
    out = b.copy()
    out[..., 0] = b[..., 0] + b[..., 2] / 2.0
    out[..., 1] = b[..., 1] + b[..., 3] / 2.0
    return out


def cxcywh_to_xywh(b: np.ndarray) -> np.ndarray:
    """Centre ``(cx, cy, w, h)`` to top-left ``(x, y, w, h)``."""
    b = np.asarray(b, dtype=float)
    out = b.copy()
    out[..., 0] = b[..., 0] - b[..., 2] / 2.0
    out[..., 1] = b[..., 1] - b[..., 3] / 2.0
    return out


def centre_xywh(b: np.ndarray) -> np.ndarray:
    """Centres ``(..., 2)`` of top-left boxes."""
    b = np.asarray(b, dtype=float)
    return b[..., :2] + b[..., 2:4] / 2.0


def iou_xywh(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over union of top-left boxes, elementwise over the leading axes."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    x1 = np.maximum(a[..., 0], b[..., 0])
    y1 = np.maximum(a[..., 1], b[..., 1])
    x2 = np.minimum(a[..., 0] + a[..., 2], b[..., 0] + b[..., 2])
    y2 = np.minimum(a[..., 1] + a[..., 3], b[..., 1] + b[..., 3])
    inter = np.clip(x2 - x1, 0, None) * np.clip(y2 - y1, 0, None)
    union = a[..., 2] * a[..., 3] + b[..., 2] * b[..., 3] - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(union > 0, inter / union, 0.0)
    return np.clip(out, 0.0, 1.0)  # rounding can push identical boxes to 1 + 1e-14
