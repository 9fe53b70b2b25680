"""Draw on a frame: boxes, identities, particles and message particles.

:func:`annotate` draws on one image and is what a notebook or a tutorial calls to look
at frame ``t``; :class:`pgm.io.annotated_video.AnnotatedVideoWriter` writes the frames.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from pgm.core.boxes import cxcywh_to_xywh

__all__ = ["annotate", "colour_for_id"]

_PALETTE = [(56, 56, 255), (151, 157, 255), (31, 112, 255), (29, 178, 255), (49, 210, 207),
            (10, 249, 72), (23, 204, 146), (134, 219, 61), (52, 147, 26), (187, 212, 0),
            (168, 153, 44), (255, 194, 0), (147, 69, 52), (255, 115, 100), (236, 24, 0),
            (255, 56, 132), (133, 0, 82), (255, 56, 203), (200, 149, 255), (199, 55, 255)]


def colour_for_id(track_id: int) -> tuple[int, int, int]:
    """A stable BGR colour for an identity."""
    return _PALETTE[int(track_id) % len(_PALETTE)]


def _draw_box(img, xywh, colour, thickness=2, label=None):
    x, y, w, h = (float(v) for v in xywh)
    p1 = (int(round(x)), int(round(y)))
    p2 = (int(round(x + w)), int(round(y + h)))
    cv2.rectangle(img, p1, p2, colour, thickness, lineType=cv2.LINE_AA)
    if label:
        cv2.putText(img, label, (p1[0], max(10, p1[1] - 4)), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                    colour, 1, cv2.LINE_AA)


def annotate(image: np.ndarray, *, boxes: Sequence | np.ndarray | None = None,
             ids: Sequence[int] | None = None, gt_boxes: np.ndarray | None = None,
             particles: dict[str, np.ndarray] | None = None,
             particle_weights: dict[str, np.ndarray] | None = None,
             messages: dict[str, np.ndarray] | None = None,
             part_boxes: dict[str, np.ndarray] | None = None,
             text: str | None = None) -> np.ndarray:
    """Return a copy of ``image`` with the run's state drawn on it.

    Parameters
    ----------
    boxes : (K, 4) top-left ``x, y, w, h``
        Estimated object boxes, coloured by identity (``ids``).
    gt_boxes : (G, 4), optional
        Ground truth, drawn thin in white.
    particles : dict name → (N, ≥2) ``(cx, cy, ...)``
        Particle centres, drawn as dots whose size follows ``particle_weights``.
    messages : dict name → (M, ≥2)
        Message particles (particle BP), drawn as small crosses.
    part_boxes : dict name → (4,) ``(cx, cy, w, h)``
        Per-part estimates, drawn thin.
    text : str
        A caption (frame number, ESS, ...).
    """
    img = np.ascontiguousarray(image.copy())
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    for k, (name, pts) in enumerate((particles or {}).items()):
        pts = np.asarray(pts, dtype=float)
        w = None if particle_weights is None else particle_weights.get(name)
        sizes = np.ones(len(pts), dtype=int)
        if w is not None and len(w) == len(pts) and np.max(w) > 0:
            sizes = 1 + np.round(2 * np.asarray(w) / np.max(w)).astype(int)
        colour = colour_for_id(k + 3)
        for (cx, cy), s in zip(pts[:, :2], sizes, strict=True):
            cv2.circle(img, (int(round(cx)), int(round(cy))), int(s), colour, -1)
    for k, (_name, pts) in enumerate((messages or {}).items()):
        colour = colour_for_id(k + 11)
        for cx, cy in np.asarray(pts, dtype=float)[:, :2]:
            cv2.drawMarker(img, (int(round(cx)), int(round(cy))), colour, cv2.MARKER_CROSS, 5, 1)
    for k, (name, box) in enumerate((part_boxes or {}).items()):
        _draw_box(img, cxcywh_to_xywh(np.asarray(box, dtype=float)[:4]), colour_for_id(k + 6),
                  1, name)
    if gt_boxes is not None:
        for b in np.asarray(gt_boxes, dtype=float).reshape(-1, 4):
            _draw_box(img, b, (255, 255, 255), 1)
    if boxes is not None:
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        ids = list(ids) if ids is not None else list(range(1, len(boxes) + 1))
        for b, i in zip(boxes, ids, strict=True):
            _draw_box(img, b, colour_for_id(i), 2, str(i))
    if text:
        cv2.putText(img, text, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 3,
                    cv2.LINE_AA)
        cv2.putText(img, text, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1,
                    cv2.LINE_AA)
    return img
