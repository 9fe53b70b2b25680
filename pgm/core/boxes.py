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

import functools

import numpy as np

__all__ = ["bounding_box", "place_parts", "xywh_to_cxcywh", "cxcywh_to_xywh", "iou_xywh",
           "iou_matrix", "box_corners", "iou_corners", "centre_xywh", "BOX_LABELS",
           "box_columns", "BOX_CODINGS", "box_coding", "box_code_columns", "encode_boxes",
           "decode_boxes", "state_boxes", "mean_box_size"]

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


#: how a state's box columns may code a box, by their labels: centre and size; corners
#: (``x1, y1`` top-left, ``x2, y2`` bottom-right: the ``trackers`` package's SORT state);
#: centre, area ``s = w h`` and aspect ``r = w / h`` (the SORT paper's state)
BOX_CODINGS: dict[str, tuple[str, str, str, str]] = {
    "cxcywh": BOX_LABELS, "xyxy": ("x1", "y1", "x2", "y2"), "xysr": ("cx", "cy", "s", "r")}


def box_coding(labels) -> str | None:
    """The :data:`BOX_CODINGS` name a variable's ``labels`` hold (``None``: not a box)."""
    if labels is None:
        return None
    return box_code_columns(tuple(labels))[0]


@functools.lru_cache(maxsize=256)
def box_code_columns(labels: tuple) -> tuple[str | None, list[int] | None]:
    """The coding of ``labels`` (a tuple) and the columns of its four box components
    (``(None, None)``: not a box); cached."""
    for name, cols in BOX_CODINGS.items():
        if all(c in labels for c in cols):
            return name, [labels.index(c) for c in cols]
    return None, None


def encode_boxes(b: np.ndarray, coding: str) -> np.ndarray:
    """Centre boxes ``(..., 4)`` in the coding ``coding`` (:data:`BOX_CODINGS`)."""
    b = np.asarray(b, dtype=float)
    if coding == "cxcywh":
        return b.copy()
    out = np.empty(b.shape)
    if coding == "xyxy":
        half = b[..., 2:4] / 2.0
        out[..., 0:2] = b[..., 0:2] - half
        out[..., 2:4] = b[..., 0:2] + half
        return out
    if coding == "xysr":
        out[..., 0:2] = b[..., 0:2]
        out[..., 2] = b[..., 2] * b[..., 3]
        out[..., 3] = b[..., 2] / b[..., 3]
        return out
    raise ValueError(f"unknown box coding {coding!r} (known: {sorted(BOX_CODINGS)})")


def decode_boxes(z: np.ndarray, coding: str) -> np.ndarray:
    """Inverse of :func:`encode_boxes`: coded boxes ``(..., 4)`` to centre boxes (an
    ``xysr`` box of non-positive area or aspect decodes to NaN)."""
    z = np.asarray(z, dtype=float)
    if coding == "cxcywh":
        return z.copy()
    out = np.empty(z.shape)
    if coding == "xyxy":
        out[..., 0:2] = (z[..., 0:2] + z[..., 2:4]) / 2.0
        out[..., 2:4] = z[..., 2:4] - z[..., 0:2]
        return out
    if coding == "xysr":
        sr = z[..., 2] * z[..., 3]
        w = np.sqrt(np.where(sr > 0, sr, np.nan))
        out[..., 0:2] = z[..., 0:2]
        out[..., 2] = w
        out[..., 3] = z[..., 2] / w
        return out
    raise ValueError(f"unknown box coding {coding!r} (known: {sorted(BOX_CODINGS)})")


def state_boxes(labels, x: np.ndarray, what: str | None = None) -> np.ndarray:
    """Centre boxes ``(..., 4)`` of states ``x`` ``(..., d)`` whose columns are labelled
    ``labels`` in any of the :data:`BOX_CODINGS` (a ``ValueError`` starting with ``what``
    when they code no box)."""
    coding, cols = box_code_columns(tuple(labels)) if labels is not None else (None, None)
    if coding is None:
        raise ValueError(f"{what or 'a state'} must code a box (labels {BOX_CODINGS}), got "
                         f"{labels}")
    return decode_boxes(np.asarray(x, dtype=float)[..., cols], coding)


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


def mean_box_size(b: np.ndarray) -> float:
    """Geometric mean of ``sqrt(w h)`` over centre boxes ``(N, 4)`` ``(cx, cy, w, h)``:
    the typical size of a particle cloud's boxes (a log-scale step is symmetric in it)."""
    b = np.asarray(b, dtype=float)
    return float(np.exp(np.mean(0.5 * np.log(np.maximum(b[:, 2] * b[:, 3], 1e-12)))))


def centre_xywh(b: np.ndarray) -> np.ndarray:
    """Centres ``(..., 2)`` of top-left boxes."""
    b = np.asarray(b, dtype=float)
    return b[..., :2] + b[..., 2:4] / 2.0


def _overlap(lo_a: np.ndarray, hi_a: np.ndarray, area_a: np.ndarray, lo_b: np.ndarray,
             hi_b: np.ndarray, area_b: np.ndarray) -> np.ndarray:
    """The one IoU of the package: boxes given by their low and high corners ``(..., 2)``
    and areas, broadcasting over the leading axes; 0 where the union is not positive or
    not finite, at most 1 (rounding can push identical boxes to 1 + 1e-14)."""
    wh = np.minimum(hi_a, hi_b) - np.maximum(lo_a, lo_b)
    np.maximum(wh, 0.0, out=wh)
    inter = wh[..., 0] * wh[..., 1]
    union = area_a + area_b - inter
    ok = union > 0  # False for NaN too
    if np.all(ok):
        out = np.minimum(inter / union, 1.0)
        if np.isfinite(out).all():
            return out
    with np.errstate(invalid="ignore", divide="ignore"):
        out = inter / np.where(ok, union, 1.0)
    return np.where(ok & np.isfinite(out), np.clip(out, 0.0, 1.0), 0.0)


def bounding_box(boxes: list[np.ndarray]) -> np.ndarray:
    """Bounding box ``(..., 4)`` (cx, cy, w, h) of several boxes of the same shape."""
    if len(boxes) == 1:
        return boxes[0]
    b = np.stack(boxes)
    x0 = (b[..., 0] - b[..., 2] / 2).min(0)
    x1 = (b[..., 0] + b[..., 2] / 2).max(0)
    y0 = (b[..., 1] - b[..., 3] / 2).min(0)
    y1 = (b[..., 1] + b[..., 3] / 2).max(0)
    return np.stack([(x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0], axis=-1)


def place_parts(box: np.ndarray, reference: np.ndarray, parts: dict[str, np.ndarray]
                ) -> dict[str, dict[str, float]]:
    """Each part's box ``{"cx", "cy", "w", "h"}`` for a target whose box is ``box``, placed
    as the ``parts`` (name → (cx, cy, w, h)) are placed in ``reference``: offsets and
    sizes scale with the target's width and height."""
    sw, sh = box[2] / reference[2], box[3] / reference[3]
    return {v: {"cx": box[0] + (p[0] - reference[0]) * sw,
                "cy": box[1] + (p[1] - reference[1]) * sh,
                "w": p[2] * sw, "h": p[3] * sh} for v, p in parts.items()}


def iou_xywh(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Intersection over union of top-left boxes, elementwise over the leading axes."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    with np.errstate(invalid="ignore"):  # infinite boxes: NaN corners, IoU 0
        return _overlap(a[..., :2], a[..., :2] + a[..., 2:4], a[..., 2] * a[..., 3],
                        b[..., :2], b[..., :2] + b[..., 2:4], b[..., 2] * b[..., 3])


def iou_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(K, M)`` IoU of centre boxes ``a`` ``(K, 4)`` and ``b`` ``(M, 4)`` (0 where a box is
    not finite or has no area).

    >>> iou_matrix(np.array([[5.0, 5.0, 10.0, 10.0]]), np.array([[10.0, 5.0, 10.0, 10.0]]))
    array([[0.33333333]])
    """
    return iou_corners(box_corners(a), box_corners(b))


def box_corners(b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre boxes ``(N, 4)`` as :func:`iou_corners` reads them: low corners ``(N, 2)``,
    high corners ``(N, 2)`` and areas ``(N,)`` (computed once for boxes compared more than
    once)."""
    h = b[:, 2:] * 0.5
    return b[:, :2] - h, b[:, :2] + h, b[:, 2] * b[:, 3]


def iou_corners(a: tuple[np.ndarray, np.ndarray, np.ndarray],
                b: tuple[np.ndarray, np.ndarray, np.ndarray]) -> np.ndarray:
    """:func:`iou_matrix` ``(K, M)`` of two sets of boxes given by :func:`box_corners`."""
    return _overlap(a[0][:, None], a[1][:, None], a[2][:, None], b[0][None], b[1][None],
                    b[2][None])
