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


def _draw_box(img, xywh, colour, thickness, scale, label=None, taken=None):
    """A box, and its ``label`` at the first of four places around its corners (above
    or inside the top-left corner, below or inside the bottom-left one) whose text does
    not overlap a label in ``taken`` (a list of placed ``(x0, y0, x1, y1)``, extended)."""
    x, y, w, h = (float(v) for v in xywh)
    p1 = (int(round(x)), int(round(y)))
    p2 = (int(round(x + w)), int(round(y + h)))
    cv2.rectangle(img, p1, p2, colour, _px(thickness, scale), lineType=cv2.LINE_AA)
    if not label:
        return
    fs, th = 0.45 * scale, _px(1, scale)
    (t_w, t_h), base = cv2.getTextSize(label, _FONT, fs, th)
    gap = _px(4, scale)
    img_h, img_w = img.shape[:2]
    places = [(p1[0], p1[1] - gap), (p1[0] + gap, p1[1] + t_h + gap),
              (p1[0], p2[1] + t_h + gap), (p1[0] + gap, p2[1] - base - gap)]
    rects = []
    for px, py in places:
        px = int(min(max(px, 0), max(img_w - t_w, 0)))
        py = int(min(max(py, t_h), max(img_h - base, t_h)))
        rects.append((px, py, (px, py - t_h, px + t_w, py + base)))
    taken = [] if taken is None else taken

    def free(r):
        return all(r[2] <= q[0] or q[2] <= r[0] or r[3] <= q[1] or q[3] <= r[1] for q in taken)

    px, py, rect = next((c for c in rects if free(c[2])), rects[0])
    taken.append(rect)
    _draw_text(img, label, (px, py), colour, scale, font_scale=0.45, plate=(0, 0, 0))


#: colour of the ground truth's boxes (thin) and of its ignored regions (dashed)
GT_COLOUR = (255, 255, 255)
IGNORE_COLOUR = (150, 150, 150)


def _dashed_box(img, xywh, colour, scale) -> None:
    """A thin dashed rectangle (an ignored region: neither a target nor a miss)."""
    x, y, w, h = (float(v) for v in xywh)
    corners = np.array([(x, y), (x + w, y), (x + w, y + h), (x, y + h), (x, y)])
    dash = 6.0 * scale
    for a, b in zip(corners[:-1], corners[1:], strict=True):
        length = float(np.abs(b - a).max())
        for t0 in np.arange(0.0, length, 2 * dash):  # a dash, then as long a gap
            p0 = a + (b - a) * t0 / length
            p1 = a + (b - a) * min(t0 + dash, length) / length
            cv2.line(img, tuple(np.round(p0).astype(int).tolist()),
                     tuple(np.round(p1).astype(int).tolist()), colour, _px(1, scale),
                     cv2.LINE_AA)


#: what a pixel under the legend keeps of its brightness
LEGEND_SHADE = 0.35


def _legend(img, entries: list[tuple[str, tuple[int, int, int], str]], scale) -> None:
    """A legend at the bottom left: one line per ``(text, colour, style)``, ``style``
    ``"solid"``, ``"thin"`` or ``"dashed"``."""
    fs, th = 0.45 * scale, _px(1, scale)
    sizes = [cv2.getTextSize(t, _FONT, fs, th) for t, _, _ in entries]
    line_h = max(s[0][1] + s[1] for s in sizes) + _px(6, scale)
    swatch = _px(22, scale)
    width = swatch + _px(8, scale) + max(s[0][0] for s in sizes) + _px(8, scale)
    h_img = img.shape[0]
    x0, y0 = _px(6, scale), h_img - _px(6, scale) - line_h * len(entries)
    # a dark see-through plate: the words read, and what lies under the legend still shows
    plate = img[max(y0 - _px(3, scale), 0):h_img - _px(3, scale) + 1,
                max(x0 - _px(3, scale), 0):x0 + width + 1]
    plate[:] = (plate * LEGEND_SHADE).astype(np.uint8)
    for k, ((text, colour, style), (_, base)) in enumerate(zip(entries, sizes, strict=True)):
        yc = y0 + k * line_h + line_h // 2
        if style == "dashed":
            _dashed_box(img, (x0, yc - 1, swatch, 2), colour, scale)
        else:
            cv2.line(img, (x0, yc), (x0 + swatch, yc), colour,
                     _px(2 if style == "solid" else 1, scale), cv2.LINE_AA)
        cv2.putText(img, text, (x0 + swatch + _px(8, scale), yc + line_h // 2 - base - 2),
                    _FONT, fs, (255, 255, 255), th, cv2.LINE_AA)


def annotate(image: np.ndarray, *, boxes: Sequence | np.ndarray | None = None,
             ids: Sequence[int] | None = None, gt_boxes: np.ndarray | None = None,
             particles: dict[str, np.ndarray] | None = None,
             particle_weights: dict[str, np.ndarray] | None = None,
             messages: dict[str, np.ndarray] | None = None,
             part_boxes: dict[str, np.ndarray] | None = None,
             text: str | None = None, ignore_boxes: np.ndarray | None = None,
             trails: dict[int, np.ndarray] | None = None,
             legend: bool = False) -> np.ndarray:
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
    ignore_boxes : (I, 4), optional
        The ground truth's ignored regions (neither targets nor misses), drawn thin,
        dashed, in grey.
    trails : dict identity → (k, 2), optional
        Each identity's last centres, oldest first, drawn as a line in its colour.
    legend : bool
        A legend at the bottom left of what the frame shows (tracks; ground truth and
        ignored regions where given).

    Identity labels are placed where they overlap no other label (above or inside a
    box's top-left corner, or at its bottom-left one).

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
    if ignore_boxes is not None:
        for b in np.asarray(ignore_boxes, dtype=float).reshape(-1, 4):
            _dashed_box(img, b, IGNORE_COLOUR, scale)
    if gt_boxes is not None:
        for b in np.asarray(gt_boxes, dtype=float).reshape(-1, 4):
            _draw_box(img, b, GT_COLOUR, 1, scale)
    for i, pts in (trails or {}).items():
        pts = np.asarray(pts, dtype=float).reshape(-1, 2)
        if len(pts) > 1:
            cv2.polylines(img, [np.round(pts).astype(np.int32).reshape(-1, 1, 2)], False,
                          colour_for_id(i), _px(1, scale), cv2.LINE_AA)
    if boxes is not None:
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        ids = list(ids) if ids is not None else list(range(1, len(boxes) + 1))
        taken: list = []
        for b, i in zip(boxes, ids, strict=True):
            _draw_box(img, b, colour_for_id(i), 2, scale, str(i), taken)
    if legend:
        entries = [("tracks (colour and number: identity)", colour_for_id(1), "solid")]
        if gt_boxes is not None:
            entries.append(("ground truth", GT_COLOUR, "thin"))
        if ignore_boxes is not None:
            entries.append(("ignored region (not scored)", IGNORE_COLOUR, "dashed"))
        _legend(img, entries, scale)
    if text:
        (_, t_h), _ = cv2.getTextSize(text, _FONT, 0.5 * scale, _px(1, scale))
        margin = _px(6, scale)
        _draw_text(img, text, (margin, margin + t_h), (255, 255, 255), scale)
    return img
