"""Draw on a frame: boxes, identities, particles and message particles.

:func:`annotate` draws on one image and is what a notebook or a tutorial calls to look
at frame ``t``; :class:`pgm.io.annotated_video.AnnotatedVideoWriter` writes the frames.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from pgm.core.boxes import cxcywh_to_xywh

__all__ = ["annotate", "colour_for_id", "drawing_scale"]

#: frame height (px) at which text and markers are drawn at their base sizes
BASE_HEIGHT = 480
_FONT = cv2.FONT_HERSHEY_SIMPLEX

_PALETTE = [(56, 56, 255), (151, 157, 255), (31, 112, 255), (29, 178, 255), (49, 210, 207),
            (10, 249, 72), (23, 204, 146), (134, 219, 61), (52, 147, 26), (187, 212, 0),
            (168, 153, 44), (255, 194, 0), (147, 69, 52), (255, 115, 100), (236, 24, 0),
            (255, 56, 132), (133, 0, 82), (255, 56, 203), (200, 149, 255), (199, 55, 255)]


def colour_for_id(track_id: int) -> tuple[int, int, int]:
    """A stable BGR colour for an identity."""
    return _PALETTE[int(track_id) % len(_PALETTE)]


def drawing_scale(image: np.ndarray) -> float:
    """How much larger than at :data:`BASE_HEIGHT` text and markers are drawn on
    ``image``: its shorter side over 480 px, at least 1 (never smaller than at VGA), so a
    caption is as tall a share of a 1920×1080 frame as of a 640×480 one."""
    h, w = image.shape[:2]
    return max(1.0, min(h, w) / BASE_HEIGHT)


def _px(value: float, scale: float) -> int:
    """A base size (px) at ``scale``, at least 1."""
    return max(1, int(round(value * scale)))


def _draw_text(img, text: str, origin: tuple[int, int], colour, scale: float,
               font_scale: float = 0.5, plate=(0, 0, 0)) -> None:
    """``text`` with its baseline-left corner at ``origin``, on a filled ``plate`` of the
    size ``cv2.getTextSize`` gives for the very font scale and thickness the text is
    drawn with (one measurement for both), so it reads on any background."""
    fs, th = font_scale * scale, _px(1, scale)
    (tw, t_h), base = cv2.getTextSize(text, _FONT, fs, th)
    pad = _px(2, scale)
    x, y = origin
    if plate is not None:
        cv2.rectangle(img, (x - pad, y - t_h - pad), (x + tw + pad, y + base + pad), plate,
                      -1)
    cv2.putText(img, text, (x, y), _FONT, fs, colour, th, cv2.LINE_AA)


def _draw_box(img, xywh, colour, thickness, scale, label=None):
    x, y, w, h = (float(v) for v in xywh)
    p1 = (int(round(x)), int(round(y)))
    p2 = (int(round(x + w)), int(round(y + h)))
    cv2.rectangle(img, p1, p2, colour, _px(thickness, scale), lineType=cv2.LINE_AA)
    if label:
        (_, t_h), _ = cv2.getTextSize(label, _FONT, 0.45 * scale, _px(1, scale))
        _draw_text(img, label, (p1[0], max(t_h + _px(2, scale), p1[1] - _px(4, scale))),
                   colour, scale, font_scale=0.45, plate=None)


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
        A caption (frame number, ESS, ...), white on a black plate at the top left.

    Text, line widths and markers grow with the frame (:func:`drawing_scale`): a
    1920×1080 frame gets them 2.25 times as large as a 640×480 one.
    """
    img = np.ascontiguousarray(image.copy())
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    scale = drawing_scale(img)
    for k, (name, pts) in enumerate((particles or {}).items()):
        pts = np.asarray(pts, dtype=float)
        w = None if particle_weights is None else particle_weights.get(name)
        sizes = np.ones(len(pts), dtype=int)
        if w is not None and len(w) == len(pts) and np.max(w) > 0:
            sizes = 1 + np.round(2 * np.asarray(w) / np.max(w)).astype(int)
        colour = colour_for_id(k + 3)
        for (cx, cy), s in zip(pts[:, :2], sizes, strict=True):
            cv2.circle(img, (int(round(cx)), int(round(cy))), _px(s, scale), colour, -1)
    for k, (_name, pts) in enumerate((messages or {}).items()):
        colour = colour_for_id(k + 11)
        for cx, cy in np.asarray(pts, dtype=float)[:, :2]:
            cv2.drawMarker(img, (int(round(cx)), int(round(cy))), colour, cv2.MARKER_CROSS,
                           _px(5, scale), _px(1, scale))
    for k, (name, box) in enumerate((part_boxes or {}).items()):
        _draw_box(img, cxcywh_to_xywh(np.asarray(box, dtype=float)[:4]), colour_for_id(k + 6),
                  1, scale, name)
    if gt_boxes is not None:
        for b in np.asarray(gt_boxes, dtype=float).reshape(-1, 4):
            _draw_box(img, b, (255, 255, 255), 1, scale)
    if boxes is not None:
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        ids = list(ids) if ids is not None else list(range(1, len(boxes) + 1))
        for b, i in zip(boxes, ids, strict=True):
            _draw_box(img, b, colour_for_id(i), 2, scale, str(i))
    if text:
        (_, t_h), _ = cv2.getTextSize(text, _FONT, 0.5 * scale, _px(1, scale))
        margin = _px(6, scale)
        _draw_text(img, text, (margin, margin + t_h), (255, 255, 255), scale)
    return img
