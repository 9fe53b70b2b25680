"""Per-box colour histograms from integral images over the boxes' union (step 2), and the
template-support Bhattacharyya coefficient (step 3)."""

from __future__ import annotations

import math
import threading
from typing import Any

import cv2
import numpy as np

from pgm.core.errors import InputError
from pgm.observation.appearance.colour.cache import _FrameBins
from pgm.observation.appearance.colour.quantize import _MAX_BINS, _check_count

__all__ = ['box_histograms', 'pixel_bounds']

_CN = 4                       # bins per cv2.integral group (4-channel fast path)
_BLOCK_BYTES = 2 << 20        # int32 integral bytes per block (kept cache-resident)
_ONEHOT_BYTES = 16 << 20      # above this the one-hot cube is built block by block
_COMPRESS_BIAS = 1.0          # compressed grid when its modelled cost < this x dense's
_ROI_MARGIN = 4               # pixels added around a region quantised for boxes


def _check_boxes(boxes: Any) -> np.ndarray:
    b = np.asarray(boxes, dtype=float)
    if b.ndim != 2 or b.shape[1] != 4:
        raise InputError(f"boxes must have shape (N, 4) (cx, cy, w, h), got {b.shape}")
    if not (np.isfinite(b).all() and (b[:, 2:] > 0).all()):
        if not np.all(np.isfinite(b)):
            raise InputError("boxes must be finite (a box has a NaN or infinite coordinate)")
        bad = np.flatnonzero(~(b[:, 2:] > 0).all(axis=1))
        raise InputError(f"boxes must have w > 0 and h > 0: {bad.size} of {len(b)} boxes "
                         f"(cx, cy, w, h) do not, e.g. {np.round(b[bad[0]], 3).tolist()} (a "
                         f"model's particles whose size drifted through zero: give the size "
                         f"no additive noise, or a log-scale step)")
    return b


def _check_bins(bins: Any, n_bins: Any) -> tuple[np.ndarray, int]:
    bins = np.asarray(bins)
    if bins.ndim != 2 or bins.size == 0 or bins.dtype.kind != "u":
        raise InputError(f"bins must be a non-empty (H, W) unsigned integer image, "
                         f"got shape {bins.shape} dtype {bins.dtype}")
    n = _check_count("n_bins", n_bins, _MAX_BINS)
    return bins, n


def _clip(x: np.ndarray, lo, hi) -> np.ndarray:
    """``np.clip`` without its Python-level overhead (~5 µs a call)."""
    return np.minimum(np.maximum(x, lo), hi)


def _bounds(b: np.ndarray, height: int, width: int):
    """Integer pixel bounds of validated boxes, clipped to the image, and more.

    Returns ``ints`` ``(2, 2, N)`` intp, ``[[x0, y0], [x1, y1]]`` clipped to ``[0, W]``
    / ``[0, H]`` (a box covers ``bins[y0:y1, x0:x1]``), the in-image pixel count
    ``inside`` and ``in_frac`` (``height`` and ``width`` may be arrays ``(N,)``: each
    box's own image size). About 17 numpy calls for x and y together (numpy's
    per-call overhead dominates at tracker sizes, N of 10-100).
    """
    t = b.T
    half = t[2:] / 2.0
    lohi = np.empty((2, 2, len(b)))
    np.subtract(t[:2], half, out=lohi[0])
    np.add(t[:2], half, out=lohi[1])
    lohi += 0.5
    np.floor(lohi, out=lohi)                               # [[x0, y0], [x1, y1]]
    np.maximum(lohi[1], lohi[0] + 1.0, out=lohi[1])        # at least one pixel
    limit = (np.array([[width], [height]]) if np.ndim(width) == 0
             else np.stack([width, height]))                # (2, 1), or per box (2, N)
    ints = np.minimum(np.maximum(lohi, 0.0), limit).astype(np.intp)
    ext = ints[1] - ints[0]
    inside = ext[0] * ext[1]
    span = lohi[1] - lohi[0]
    total = np.maximum(span[0] * span[1], 1.0)
    return ints, inside, inside / total                    # 0 <= inside <= total


def _pixel_bounds(b: np.ndarray, height: int, width: int):
    """Integer pixel bounds, clipped to the image, and the in-image fraction.

    Returns ``xa, xb, ya, yb`` (intp, clipped to ``[0, W]`` / ``[0, H]``, so that a
    box covers ``bins[ya:yb, xa:xb]``), the in-image pixel count and ``in_frac``.
    """
    ints, inside, in_frac = _bounds(b, height, width)
    return ints[0, 0], ints[1, 0], ints[0, 1], ints[1, 1], inside, in_frac


def pixel_bounds(boxes: np.ndarray, height: int, width: int):
    """Integer pixel bounds ``x0, x1, y0, y1`` (half-open, clipped) of boxes
    ``(cx, cy, w, h)``: the pixels the colour histograms count, for any factor that
    sums over boxes with its own integral image."""
    return _pixel_bounds(np.asarray(boxes, dtype=float).reshape(-1, 4), height, width)[:4]


def _union_of(ints: np.ndarray, inside: np.ndarray):
    """``(x0, x1, y0, y1)`` bounding rectangle of the non-empty boxes (None if there
    are none) and whether every box is non-empty."""
    nonempty = inside > 0
    if len(nonempty) and nonempty.all():
        lo = ints[0].min(axis=1)
        hi = ints[1].max(axis=1)
        return (int(lo[0]), int(hi[0]), int(lo[1]), int(hi[1])), True
    if not nonempty.any():
        return None, False
    ne = ints[:, :, nonempty]
    lo = ne[0].min(axis=1)
    hi = ne[1].max(axis=1)
    return (int(lo[0]), int(hi[0]), int(lo[1]), int(hi[1])), False


class _Scratch(threading.local):
    """Per-thread reusable buffers of the integral-histogram path.

    The path needs a few MB of temporaries per call; allocated afresh, glibc serves
    them with ``mmap`` and every call pays the page faults (measured: 4.5 instead of
    1.5 µs per box at N = 1000 in a fresh process). The buffers grow to the largest
    request seen and are kept for the thread's lifetime (bounded by
    ``_ONEHOT_BYTES`` + a few ``_BLOCK_BYTES`` plus O(N x bins) arrays).
    """

    def __init__(self) -> None:
        self.buffers: dict[str, np.ndarray] = {}
        self.ramp = np.zeros(0, dtype=np.intp)

    def get(self, name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
        dtype = np.dtype(dtype)
        nbytes = math.prod(shape) * dtype.itemsize
        buf = self.buffers.get(name)
        if buf is None or buf.nbytes < nbytes:
            buf = np.empty(max(nbytes, 64), dtype=np.uint8)
            self.buffers[name] = buf
        return buf[:nbytes].view(dtype).reshape(shape)

    def pixel_ramp(self, count: int) -> np.ndarray:
        """``arange(count) * _CN`` (cached)."""
        if len(self.ramp) < count:
            self.ramp = np.arange(0, max(count, 1 << 16) * _CN, _CN, dtype=np.intp)
        return self.ramp[:count]


_SCRATCH = _Scratch()


def _clear_scratch() -> None:
    """Drop this thread's scratch buffers (benchmarks measure peak memory from zero)."""
    _SCRATCH.buffers.clear()
    _SCRATCH.ramp = np.zeros(0, dtype=np.intp)


def _slot_lut8(slot_of_bin: np.ndarray, n_slots: int) -> np.ndarray | None:
    """uint8 table bin -> slot (255 for bins not counted; at least 256 entries), or
    None when there are more than 255 slots."""
    if n_slots > 255:
        return None
    lut = np.full(max(len(slot_of_bin), 256), 255, dtype=np.uint8)
    lut[:len(slot_of_bin)] = np.where(slot_of_bin < n_slots, slot_of_bin, 255)
    return lut


def _corner_counts(bins: np.ndarray, xa, xb, ya, yb, slot_of_bin: np.ndarray,
                   n_slots: int, method: str = "auto") -> np.ndarray:
    """Pixel counts ``(n_slots, N)`` of every box ``bins[ya:yb, xa:xb]`` (bounds
    clipped to the image), per selected bin: see :func:`_counts`."""
    ints = np.array([[xa, ya], [xb, yb]], dtype=np.intp)
    inside = (xb - xa).clip(0) * (yb - ya).clip(0)
    union, all_nonempty = _union_of(ints, inside)
    return _counts(bins, ints, union, all_nonempty, slot_of_bin, n_slots, method)


def _counts(bins: np.ndarray, ints: np.ndarray, union, all_nonempty: bool,
            slot_of_bin: np.ndarray, n_slots: int, method: str = "auto",
            slot8: np.ndarray | None = None) -> np.ndarray:
    """Pixel counts ``(n_slots, N)`` of every box, per selected bin: int32
    (``"dense"``) or integer-valued float64 (``"compressed"``), exact either way.

    ``ints`` are the boxes' bounds (:func:`_bounds`), ``union`` and
    ``all_nonempty`` from :func:`_union_of`; only the union rectangle of ``bins`` is
    read. ``slot_of_bin[u]`` is the row of bin ``u`` in the result, or ``n_slots``
    for a bin that is not counted (``slot8``: the same as a uint8 table, see
    :func:`_slot_lut8`; built when not given). Integral histogram over the union:
    ``"dense"`` at pixel resolution (see the module docstring), ``"compressed"`` on
    the grid of the boxes' distinct corner coordinates (cheaper when there are few
    boxes: fewer cells than pixels), ``"auto"`` picks by a cost model. The result may
    be a view of a per-thread scratch buffer: valid until the next call in the same
    thread.
    """
    n = ints.shape[2]
    if n_slots == 0 or union is None:
        return np.zeros((n_slots, n), dtype=np.int32)
    ux0, ux1, uy0, uy1 = union
    h, w = uy1 - uy0, ux1 - ux0
    crop = bins[uy0:uy1, ux0:ux1]
    # Bounds relative to the union (rows x, then y shifted by w + 1 to make marks
    # below). Empty boxes are clipped into the union too; clipping keeps them empty
    # and leaves every non-empty box unchanged.
    marks = ints - np.array([[ux0], [uy0 - w - 1]])
    if not all_nonempty:
        np.maximum(marks, np.array([[0], [w + 1]]), out=marks)
        np.minimum(marks, np.array([[w], [w + 1 + h]]), out=marks)
    if method == "dense":
        return _dense_union(crop, marks, w, slot_of_bin, n_slots)
    # Distinct corner coordinates: marks on [0, w] then on [0, h] (offset w + 1) and
    # their running count ``run``: ``run[x] - 1`` is the cell column of pixel column
    # x and the grid index of a corner coordinate x; rows likewise, less the x marks
    # (``n_x``).
    run = np.zeros(w + h + 2, dtype=np.intp)
    run[marks] = 1
    np.add.accumulate(run, out=run)
    n_x = int(run[w])
    nx, ny = n_x - 1, int(run[w + 1 + h]) - n_x - 1
    if method == "auto":
        # cost model, ns, fitted to 280 timings (one thread; unions of 1k-65k pixels,
        # 3-300 boxes, 4-86 slots): compressed 60 µs + 0.76 per union pixel + 1.56
        # per (slot, cell) + 7.5 per (slot, box); dense 71 µs + (3 + 0.29 n_slots)
        # per pixel + 2.7 per (slot, box)
        pixels = h * w
        compressed = 60e3 + 0.76 * pixels + n_slots * (1.56 * nx * ny + 7.5 * n)
        dense = 71e3 + (3.0 + 0.29 * n_slots) * pixels + 2.7 * n_slots * n
        if compressed >= _COMPRESS_BIAS * dense:
            return _dense_union(crop, marks, w, slot_of_bin, n_slots)
    grid = np.take(run, marks)          # [[ix0 + 1, iy0 + n_x + 1], [ix1 + 1, iy1 + ...]]
    col_cell = run[:w] - 1
    row_cell = run[w + 1:w + 1 + h] - (n_x + 1)
    if slot8 is None:
        slot8 = _slot_lut8(slot_of_bin, n_slots)
    if slot8 is None or nx > 256 or ny > 256:
        integ = _compressed_integral_bincount(crop, col_cell, row_cell, nx, ny,
                                              slot_of_bin, n_slots)
    else:
        integ = _compressed_integral(crop, col_cell, row_cell, nx, ny, slot8, n_slots)
    # corner (y_i, x_j) of slot s: integ[s * ny + iy_i, ix_j], flat index
    # s * ny * w1 + iy_i * w1 + ix_j; the extra n_x + 1 and 1 of ``grid`` are taken
    # off in the slot offsets
    w1 = nx + 1
    corner = (grid[:, 1] * w1)[:, None, :] + grid[None, :, 0]       # (y_i, x_j, N)
    step = ny * w1
    first = -(n_x + 1) * w1 - 1
    off = np.arange(first, first + n_slots * step, step)
    t = np.take(integ.reshape(-1), corner.reshape(1, 4, n) + off[:, None, None])
    return _CORNER_SIGNS @ t          # I(y1,x1) - I(y1,x0) - I(y0,x1) + I(y0,x0), exact


def _dense_union(crop: np.ndarray, marks: np.ndarray, w: int, slot_of_bin: np.ndarray,
                 n_slots: int) -> np.ndarray:
    """:func:`_dense_counts` of bounds given as ``marks`` (see :func:`_counts`)."""
    ya, yb = marks[:, 1] - (w + 1)
    return _dense_counts(crop, marks[0, 0], marks[1, 0], ya, yb, slot_of_bin, n_slots)


_CORNER_SIGNS = np.array([1.0, -1.0, -1.0, 1.0])   # corners (y0,x0) (y0,x1) (y1,x0) (y1,x1)


def _compressed_integral(crop: np.ndarray, col_cell, row_cell, nx: int, ny: int,
                         slot8: np.ndarray, n_slots: int) -> np.ndarray:
    """Integral ``(n_slots * ny + 1, nx + 1)`` float64 of the cell counts of every slot
    on the grid of distinct corner coordinates, the slot planes stacked vertically
    (a rectangle sum inside one slot's rows never reads another slot's rows).

    Three uint8 images (slot of the pixel's bin by ``cv2.LUT``, 255 for bins not
    counted; cell row; cell column, at most 256 cells a side) go through one 3-D
    ``cv2.calcHist`` (slot, cell row, cell column), whose float32 counts are exact
    integers, then one ``cv2.integral`` in float64.
    """
    h, w = crop.shape
    rows = np.empty((h, w), dtype=np.uint8)
    cols = np.empty((h, w), dtype=np.uint8)
    rows[...] = row_cell.astype(np.uint8)[:, None]
    cols[...] = col_cell.astype(np.uint8)
    slot = (cv2.LUT(crop, slot8[:256]) if crop.dtype == np.uint8
            else np.take(slot8, crop))
    hist = cv2.calcHist([slot, rows, cols], [0, 1, 2], None, [n_slots, ny, nx],
                        [0, n_slots, 0, ny, 0, nx])
    return cv2.integral(hist.reshape(n_slots * ny, nx), sdepth=cv2.CV_64F)


def _compressed_integral_bincount(crop: np.ndarray, col_cell, row_cell, nx: int,
                                  ny: int, slot_of_bin: np.ndarray,
                                  n_slots: int) -> np.ndarray:
    """:func:`_compressed_integral` for more than 255 slots or 256 cells a side: one
    ``np.bincount`` of (slot, cell) keys instead of ``cv2.calcHist``."""
    h, w = crop.shape
    plane = ny * nx
    key = np.take(slot_of_bin * plane, crop)            # dropped bins: plane n_slots
    key += (row_cell * nx)[:, None]
    key += col_cell
    cnt = np.bincount(key.reshape(-1), minlength=(n_slots + 1) * plane)
    cnt = cnt[:n_slots * plane].astype(np.float64)
    return cv2.integral(cnt.reshape(n_slots * ny, nx), sdepth=cv2.CV_64F)


def _dense_counts(crop: np.ndarray, xa, xb, ya, yb, slot_of_bin: np.ndarray,
                  n_slots: int) -> np.ndarray:
    """Pixel-resolution integral histogram (bin-major groups of four, blocked)."""
    n = len(xa)
    ws = _SCRATCH
    h, w = crop.shape
    cn = _CN
    n_groups = -(-n_slots // cn)
    plane = h * w * cn                              # one-hot bytes of one group
    # Linear one-hot index of every pixel: group plane, pixel, channel; bins that
    # are not counted go to a dump plane after the last group.
    slot = np.arange(n_slots + 1)
    off = np.where(slot < n_slots, (slot // cn) * plane + slot % cn, n_groups * plane)
    lin = ws.get("lin", (h, w), np.intp)
    np.take(off[slot_of_bin], crop, out=lin, mode="clip")
    lin += ws.pixel_ramp(h * w).reshape(h, w)
    lin = lin.reshape(-1)

    w1 = w + 1
    group_bytes = (h + 1) * w1 * cn * 4
    per_block = max(1, min(n_groups, _BLOCK_BYTES // group_bytes))
    corners = np.concatenate([yb * w1 + xb, ya * w1 + xb, yb * w1 + xa, ya * w1 + xa])
    gather = ws.get("gather", (per_block, 4 * n), np.intp)
    np.add(corners[None, :], (np.arange(per_block) * (h * w1))[:, None], out=gather)
    integral = ws.get("integral", (per_block * h + 1, w1, cn), np.int32)
    taken = ws.get("taken", (per_block, 4 * n, cn), np.int32)
    diff = ws.get("diff", (per_block, n, cn), np.int32)
    counts = ws.get("counts", (n_groups, cn, n), np.int32)
    whole = (n_groups + 1) * plane <= _ONEHOT_BYTES
    if whole:
        onehot = ws.get("onehot", ((n_groups + 1) * plane,), np.uint8)
        onehot.fill(0)
        onehot[lin] = 1
    else:
        # one-hot built block by block: pixels sorted by group (radix sort of small
        # integers), so each block scatters a contiguous run of them
        group = lin // plane
        order = np.argsort(group, kind="stable")
        lin = lin[order]
        starts = np.searchsorted(group[order], np.arange(n_groups + 1))
    for g0 in range(0, n_groups, per_block):        # blocks of bins, not boxes
        g1 = min(n_groups, g0 + per_block)
        nb = g1 - g0
        if whole:
            src = onehot[g0 * plane:g1 * plane]
        else:
            src = ws.get("onehot", (nb * plane,), np.uint8)
            src.fill(0)
            src[lin[starts[g0]:starts[g1]] - g0 * plane] = 1
        res = cv2.integral(src.reshape(nb * h, w, cn), integral[:nb * h + 1],
                           sdepth=cv2.CV_32S)
        t = taken[:nb]
        np.take(res.reshape(-1, cn), gather[:nb], axis=0, out=t, mode="clip")
        o = diff[:nb]
        np.subtract(t[:, :n], t[:, n:2 * n], out=o)
        o -= t[:, 2 * n:3 * n]
        o += t[:, 3 * n:]
        counts[g0:g1] = o.transpose(0, 2, 1)
    return counts.reshape(n_groups * cn, n)[:n_slots]


def box_histograms(bins: np.ndarray, n_bins: int,
                   boxes_cxcywh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Normalised colour histograms of N boxes, by one integral histogram.

    Parameters
    ----------
    bins : ndarray (H, W) unsigned int
        Output of :func:`quantize_colour`.
    n_bins : int
    boxes_cxcywh : ndarray (N, 4)
        ``(cx, cy, w, h)``, 0-based; rounded to integer pixel bounds as the module
        docstring says.

    Returns
    -------
    hist : ndarray (N, n_bins) float64
        Normalised over the box's in-image pixels; all-zero for a box wholly
        outside the image.
    in_frac : ndarray (N,) float64
        Fraction of the box's pixels that lie inside the image.
    """
    bins, n_bins = _check_bins(bins, n_bins)
    b = _check_boxes(boxes_cxcywh)
    if bins.size and int(bins.max()) >= n_bins:
        raise InputError(f"bins holds a bin index >= n_bins={n_bins}")
    return _histograms(bins, n_bins, b)


def _histograms(bins: np.ndarray, n_bins: int, b: np.ndarray,
                frame: _FrameBins | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`box_histograms` of validated boxes; with ``frame``, ``bins`` is
    ``frame.bins`` and the boxes' union is quantised first (and only it is read)."""
    ints, inside, in_frac = _bounds(b, *bins.shape)
    union, all_nonempty = _union_of(ints, inside)
    if frame is not None and union is not None:
        frame.ensure(*union, margin=_ROI_MARGIN)
    counts = _counts(bins, ints, union, all_nonempty, np.arange(n_bins), n_bins)
    hist = counts.T.astype(np.float64)
    np.divide(hist, np.maximum(inside, 1)[:, None], out=hist)
    return hist, in_frac


class _Template:
    """What :meth:`ColourHistogramScorer.rho` needs of a template ``q``, built once
    per distinct ``q``: its support (bins with ``q > 0``), the bin -> slot tables and
    ``sqrt(q)``."""

    __slots__ = ("q", "k", "slot_of_bin", "slot8", "sqrt_support", "sqrt_q")

    def __init__(self, q: np.ndarray, n_bins: int):
        self.q = q
        support = np.flatnonzero(q > 0)
        self.k = k = len(support)
        self.slot_of_bin = np.full(n_bins, k, dtype=np.intp)
        self.slot_of_bin[support] = np.arange(k)
        self.slot8 = _slot_lut8(self.slot_of_bin, k)
        self.sqrt_support = np.sqrt(q[support])
        self.sqrt_q = np.sqrt(q)


def _rho_of_template(bins: np.ndarray, b: np.ndarray, t: _Template,
                     frame: _FrameBins | None = None) -> np.ndarray:
    """``bhattacharyya(hist, q) * in_frac`` of validated boxes, counting only the
    bins where ``q > 0`` (exact: the others add nothing to ``sum sqrt(p q)``); with
    ``frame``, only the boxes' union is quantised (``bins`` is ``frame.bins``)."""
    ints, inside, in_frac = _bounds(b, *bins.shape)
    union, all_nonempty = _union_of(ints, inside)
    if frame is not None and union is not None:
        frame.ensure(*union, margin=_ROI_MARGIN)
    counts = _counts(bins, ints, union, all_nonempty, t.slot_of_bin, t.k, slot8=t.slot8)
    if counts.dtype == np.float64:                  # a fresh array: in place
        root = np.sqrt(counts, out=counts)
    else:
        root = np.sqrt(counts, out=_SCRATCH.get("root", counts.shape, np.float64))
    num = t.sqrt_support @ root
    rho = num / np.sqrt(np.maximum(inside, 1))
    return rho * in_frac


def _template_rho(bins: np.ndarray, n_bins: int, b: np.ndarray,
                  q: np.ndarray) -> np.ndarray:
    """:func:`_rho_of_template` of a full bin image and a template array."""
    return _rho_of_template(bins, b, _Template(q, n_bins))


