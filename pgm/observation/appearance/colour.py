"""Colour-histogram likelihood: quantisation, per-box histograms, Bhattacharyya.

This is the hot path of every colour tracker (``SPEC.md`` §1): score N candidate
boxes of one frame against a template histogram ``q``. It is one vectorised
computation, with no Python loop over boxes:

1. **Quantise only what is scored, once per frame** (:func:`quantize_colour`): one
   ``cv2.cvtColor`` to 8-bit HSV, then per-channel bit shifts (power-of-two bin
   counts), one ``cv2.convertScaleAbs`` (hue) or lookup tables, combined with
   saturating ``cv2`` adds and a ``cv2.min``; a region whose three channels are equal
   (greyscale video delivered as BGR) skips ``cvtColor``: its hue and saturation are
   0 and its value is the grey level. :class:`ColourHistogramScorer` quantises
   *lazily*: only the union rectangle of the boxes it scores (clipped to the image,
   plus a ``_ROI_MARGIN`` of 4 px), into a full-size bin buffer cached in the
   :class:`~pgm.core.frame.FrameContext` under ``("colour-bins", layout, n_h, n_s, n_v)``
   (a ``_FrameBins``: the buffer plus the rectangle quantised so far). Every factor
   that shares a layout shares it: a request inside the rectangle costs nothing,
   otherwise only the strips that grow it to the bounding rectangle are quantised,
   and the first request of a frame also covers the previous frame's requests (so
   the three band factors of one face cost one quantisation call per frame).
   :meth:`ColourHistogramScorer.bins` still returns the whole frame (quantising what
   is left). Measured on FaceOcc1 (352x288, greyscale) / PETS (768x576): the full
   frame costs 0.3 / 1.3 ms, the union of 30 boxes around the face / a person about
   0.08 / 0.1-0.2 ms.
2. **Integral histograms over the union rectangle only** (:func:`box_histograms`):
   the boxes are rounded to integer pixel bounds and clipped to the image; the
   union bounding rectangle of the clipped boxes is cropped, turned into a uint8
   one-hot cube laid out *bin-major in groups of four bins* (``(G, h, w, 4)``), and
   integrated by one ``cv2.integral`` call per block of groups (the groups are
   stacked vertically: a rectangle sum inside one group never reads another
   group's rows, so stacking is exact). The four corners of every box are then
   gathered with one ``np.take`` per block: ``4 N`` rows of four int32 per group.
   Blocks are sized so that a block's integral (about 2 MiB) stays in cache between
   ``cv2.integral`` and the gather (this matters for 256-bin layouts), and the
   temporaries live in per-thread scratch buffers reused between calls (fresh
   multi-MB allocations cost page faults on every call: 4.5 instead of 1.5 µs per box).
   With few boxes the integral is taken on the *compressed grid* of the boxes'
   distinct corner coordinates instead (cells between consecutive distinct ``x``
   and ``y`` corners, found by marks and a running sum, no sort): one 3-D
   ``cv2.calcHist`` of (bin slot, cell row, cell column) uint8 images counts every
   (bin, cell), then one ``cv2.integral`` over far fewer cells than pixels and one
   gather of the corners. About 60 numpy/cv2 calls per ``rho`` in all whatever N: at
   tracker sizes (N = 10-100) numpy's per-call overhead, not pixels, dominates.
   ``"auto"`` picks dense or compressed by a cost model fitted to measurements
   (:func:`_counts`): compressed for the 10-100 boxes of a tracker around one
   object, dense for hundreds of spread boxes. Both are exact (bit-identical counts).
3. **Only the template's bins** (:meth:`ColourHistogramScorer.rho`): the
   Bhattacharyya coefficient ``sum_u sqrt(p_u q_u)`` needs ``p_u`` only where
   ``q_u > 0``, and the normaliser of ``p`` is the box's in-image pixel count, known
   without counting. So the integral cube is built for the template's support only
   (typically 30-90 of 256 HSV bins, at most 16 of 80 "perez" bins on a greyscale
   frame). This is exact, not an approximation.

Measured alternatives (integral cube for the union, 162x196 px, of 1000 boxes 40x80
with centres N(point, 20 px) on a 768x576 PETS frame, one thread, ms; all 256 HSV
bins / the template's 86): ``np.cumsum`` over an int32 one-hot cube 63 / 22, over a
uint16 cube 46 / 16 (numpy's accumulate is not vectorised along either axis);
``np.add`` row-then-column loops in uint16 7.3 / 3.0; ``cv2.integral`` pixel-major
with B channels 32 / 3.3 (at most 128 channels per call); ``cv2.integral`` on
single-bin planes 3.4 / 1.0; on bin-major groups of four (used) 2.7 / 0.8. Gathers
from bin-major groups of four beat single-bin planes 2x; an unblocked 256-bin cube
is 2.5x slower at N = 1000 (cache misses in the gather). See
``benchmarks/likelihood.py --alternatives``.

Box rounding: a box ``(cx, cy, w, h)`` covers pixel columns
``[x0, x1) = [floor(cx - w/2 + 1/2), floor(cx + w/2 + 1/2))`` (round half up), with
``x1 = max(x1, x0 + 1)`` so that a valid box always covers at least one pixel
column; rows likewise. The in-image fraction ``in_frac`` is the number of those
pixels inside the image over their total number; the histogram is normalised over
the in-image pixels only (``SPEC.md`` §1: pixels outside the image are absent).
"""

from __future__ import annotations

import math
import threading
from typing import Any

import cv2
import numpy as np

from pgm.core.errors import InputError
from pgm.core.frame import FrameContext

__all__ = ["quantize_colour", "colour_bin_count", "box_histograms", "bhattacharyya",
           "pixel_bounds", "ColourHistogramScorer", "LAYOUTS", "KERNELS"]

LAYOUTS = ("perez", "hsv", "rgb")
KERNELS = ("uniform", "epanechnikov", "grid-uniform")

# Pérez et al.: a pixel is chromatic when saturation > 0.1 and value > 0.2
# (OpenCV 8-bit HSV: S >= 26, V >= 52).
_S_MIN = 26
_V_MIN = 52

_CN = 4                       # bins per cv2.integral group (4-channel fast path)
_BLOCK_BYTES = 2 << 20        # int32 integral bytes per block (kept cache-resident)
_ONEHOT_BYTES = 16 << 20      # above this the one-hot cube is built block by block
_COMPRESS_BIAS = 1.0          # compressed grid when its modelled cost < this x dense's
_ROI_MARGIN = 4               # pixels added around a region quantised for boxes
_CALL_PIXELS = 5000           # fixed cost of one region quantisation, in pixels
_MAX_BINS = 1 << 16


# --------------------------------------------------------------------------------------
# quantisation


def _check_count(name: str, value: Any, hi: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise InputError(f"parameter {name!r} must be an integer, got {value!r}")
    if not 1 <= int(value) <= hi:
        raise InputError(f"parameter {name!r} must be in [1, {hi}], got {value!r}")
    return int(value)


def _resolve_layout(layout: str, n_h: int, n_s: int, n_v: int | None,
                    n_rgb: int) -> tuple[str, int, int, int]:
    """Canonical ``(layout, a, b, c)``: per-channel bin counts of the layout."""
    if layout not in LAYOUTS:
        raise InputError(f"unknown colour layout {layout!r}; expected one of {LAYOUTS}")
    if layout == "rgb":
        n = _check_count("n_rgb", n_rgb, 256)
        canon = ("rgb", n, n, n)
    else:
        if n_v is None:
            n_v = 16 if layout == "perez" else 4
        canon = (layout, _check_count("n_h", n_h, 180), _check_count("n_s", n_s, 256),
                 _check_count("n_v", n_v, 256))
    if _bin_count(canon) > _MAX_BINS:
        raise InputError(f"colour layout {canon} has {_bin_count(canon)} bins; at most "
                         f"{_MAX_BINS} are supported")
    return canon


def _bin_count(canon: tuple[str, int, int, int]) -> int:
    layout, a, b, c = canon
    return a * b + c if layout == "perez" else a * b * c


def colour_bin_count(layout: str = "perez", n_h: int = 16, n_s: int = 4,
                     n_v: int | None = None, *, n_rgb: int = 8) -> int:
    """Number of bins of a layout: ``n_h*n_s + n_v`` ("perez"), ``n_h*n_s*n_v``
    ("hsv"), ``n_rgb**3`` ("rgb")."""
    return _bin_count(_resolve_layout(layout, n_h, n_s, n_v, n_rgb))


def _check_image(image: Any) -> np.ndarray:
    """The image as an array, validated (uint8, HxW or HxWx3, non-empty); no copy."""
    img = np.asarray(image)
    if img.dtype != np.uint8:
        raise InputError(f"image must be uint8, got dtype {img.dtype}")
    if img.ndim == 2:
        if img.size == 0:
            raise InputError(f"image is empty: shape {img.shape}")
        return img
    if img.ndim != 3 or img.shape[2] != 3 or img.size == 0:
        raise InputError(f"image must be HxWx3 (BGR) or HxW uint8, got shape {img.shape}")
    return img


def _as_bgr(image: Any) -> np.ndarray:
    img = _check_image(image)
    if img.ndim == 2:
        return cv2.cvtColor(np.ascontiguousarray(img), cv2.COLOR_GRAY2BGR)
    return np.ascontiguousarray(img)


def _lut(values: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(values, dtype=np.uint8)


_BIN8_PLANS: dict[tuple[int, int, int], tuple] = {}


def _bin8_plan(n: int, full: int, mult: int) -> tuple:
    """How :func:`_bin8` computes ``floor(x * n / full) * mult``: ``("shift", r, l)``,
    ``("scale", alpha, beta, l)`` or ``("lut", table)``; cached per argument triple.

    ``"scale"`` is one ``cv2.convertScaleAbs`` (3x faster than ``cv2.LUT``):
    ``round(x n / full - 1/2 + 1/(2 full))`` equals ``floor(x n / full)`` because the
    fractional part of ``x n / full`` is a multiple of ``1/full``, so the shifted value
    is never within ``1/(2 full)`` of a rounding boundary (float32 errors are below
    ``1e-4``). The plan is verified on every ``x`` in ``[0, full)`` (the channel's
    range: OpenCV's 8-bit hue is below 180) and falls back to a table otherwise.
    """
    key = (n, full, mult)
    plan = _BIN8_PLANS.get(key)
    if plan is not None:
        return plan
    pow2_mult = mult & (mult - 1) == 0
    if full == 256 and 256 % n == 0 and pow2_mult:
        plan = ("shift", (256 // n).bit_length() - 1, mult.bit_length() - 1)
    else:
        k = np.arange(256)
        exact = np.minimum(k * n // full, n - 1) * mult
        plan = ("lut", _lut(exact))
        if pow2_mult:
            alpha, beta = n / full, -0.5 + 0.5 / full
            got = cv2.convertScaleAbs(k.astype(np.uint8).reshape(1, 256), alpha=alpha,
                                      beta=beta).astype(np.int64)[0] << (mult.bit_length() - 1)
            if np.array_equal(got[:full], exact[:full]):
                plan = ("scale", alpha, beta, mult.bit_length() - 1)
    _BIN8_PLANS[key] = plan
    return plan


def _bin8(x: np.ndarray, n: int, full: int, mult: int = 1) -> np.ndarray:
    """``floor(x * n / full) * mult`` of a uint8 channel with values in ``[0, full)``,
    as uint8 (must fit).

    A shift pair when ``full = 256`` and ``n``, ``mult`` are powers of two (~10x
    faster than ``cv2.LUT``), a ``cv2.convertScaleAbs`` and a shift when ``mult`` is a
    power of two (~3x faster; see :func:`_bin8_plan`), a lookup table otherwise.
    """
    plan = _bin8_plan(n, full, mult)
    if plan[0] == "lut":
        return cv2.LUT(x, plan[1])
    if plan[0] == "shift":
        out = np.right_shift(x, plan[1])
    else:
        out = cv2.convertScaleAbs(x, alpha=plan[1], beta=plan[2])
    if plan[-1]:
        np.left_shift(out, plan[-1], out=out)
    return out


def quantize_colour(image_bgr: np.ndarray, layout: str = "perez", n_h: int = 16,
                    n_s: int = 4, n_v: int | None = None, *,
                    n_rgb: int = 8) -> tuple[np.ndarray, int]:
    """Quantise an image into colour bins.

    Parameters
    ----------
    image_bgr : ndarray, (H, W, 3) uint8 BGR, or (H, W) uint8 greyscale
    layout : {"perez", "hsv", "rgb"}
        ``"perez"`` (default, ``SPEC.md`` §1): OpenCV 8-bit HSV; pixels with
        ``S >= 26`` and ``V >= 52`` go to ``n_h * n_s`` hue-saturation bins
        ``(H * n_h // 180) * n_s + S * n_s // 256`` (so the lowest saturation bin
        holds S in [26, 64) with the defaults), every other pixel to one of ``n_v``
        value-only bins ``n_h*n_s + V * n_v // 256``. Greyscale frames therefore
        keep an ``n_v``-bin intensity histogram.
        ``"hsv"``: plain ``n_h x n_s x n_v`` bins, ``((h * n_s) + s) * n_v + v``
        (16 x 4 x 4 = 256 by default; a greyscale frame collapses onto the ``n_v``
        bins of hue 0, saturation 0).
        ``"rgb"``: ``n_rgb`` bins per channel, ``(r * n + g) * n + b``.
    n_h, n_s, n_v : int
        Bins of hue, saturation and value. ``n_v=None`` means 16 for "perez" and 4
        for "hsv".
    n_rgb : int
        Bins per channel of the "rgb" layout (default 8: 512 bins).

    Returns
    -------
    bins : ndarray (H, W), uint8 when ``n_bins <= 256`` else uint16
    n_bins : int

    Notes
    -----
    One ``cv2.cvtColor`` and ``cv2.split``, then per-channel lookup tables (or bit
    shifts for power-of-two bin counts) combined with saturating ``cv2.add``: in
    "perez" the chromatic code is pushed to 255 where ``S < 26`` or ``V < 52``
    (``cv2.compare`` gives 255 there) and a ``cv2.min`` with the value bin, always
    larger than any chromatic code, picks the right one. Layouts with more than 255
    (perez) or 256 bins go through numpy in uint16.
    """
    canon = _resolve_layout(layout, n_h, n_s, n_v, n_rgb)
    return _quantize_bgr(_as_bgr(image_bgr), canon), _bin_count(canon)


def _grey_channel(img: np.ndarray) -> np.ndarray | None:
    """The image's one channel when its three channels are equal (a greyscale frame
    delivered as BGR), else None.

    Such a pixel has ``H = S = 0`` and ``V`` = its level in OpenCV's 8-bit HSV, so
    its bin needs no ``cvtColor`` (half of a region's quantisation cost). The first
    row is checked first, so colour frames pay about 3 µs.
    """
    row = img[0]
    if not np.array_equal(row[:, :2], row[:, 1:]):
        return None
    b, g, r = cv2.split(np.ascontiguousarray(img))
    if cv2.countNonZero(cv2.bitwise_or(cv2.absdiff(b, g), cv2.absdiff(g, r))):
        return None
    return b


def _quantize_bgr(img: np.ndarray, canon: tuple[str, int, int, int]) -> np.ndarray:
    """Bins of a validated (h, w, 3) uint8 BGR image, which may be a strided view
    (a region of a frame: ``cv2.cvtColor`` reads views in place)."""
    lay, a, b, c = canon
    n_bins = _bin_count(canon)
    k = np.arange(256)
    if lay == "rgb":
        ch = cv2.split(np.ascontiguousarray(img))  # B, G, R (split copies views slowly)
        if n_bins <= 256:
            return cv2.add(cv2.add(_bin8(ch[2], a, 256, a * a), _bin8(ch[1], a, 256, a)),
                           _bin8(ch[0], a, 256))
        cb16 = (k * a // 256).astype(np.uint16)
        out = cb16[ch[2]] * np.uint16(a * a)
        out += cb16[ch[1]] * np.uint16(a)
        out += cb16[ch[0]]
        return out

    if n_bins <= (255 if lay == "perez" else 256):
        grey = _grey_channel(img)
        if grey is not None:                       # OpenCV: H = S = 0, V = the grey level
            value = _bin8(grey, c, 256)
            return cv2.add(value, a * b) if lay == "perez" else value
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)     # H in [0, 180), S, V in [0, 256)
    H, S, V = cv2.split(hsv)
    if lay == "perez":
        n_chrom = a * b
        if n_bins <= 255:
            chrom = cv2.add(cv2.add(_bin8(H, a, 180, b), _bin8(S, b, 256)),
                            cv2.bitwise_or(cv2.compare(S, _S_MIN, cv2.CMP_LT),
                                           cv2.compare(V, _V_MIN, cv2.CMP_LT)))
            value = cv2.add(_bin8(V, c, 256), n_chrom)
            return cv2.min(chrom, value)
        hb = np.minimum(k * a // 180, a - 1)
        hs = (hb * b).astype(np.uint16)[H] + (k * b // 256).astype(np.uint16)[S]
        val = (n_chrom + k * c // 256).astype(np.uint16)[V]
        out = np.where((S >= _S_MIN) & (V >= _V_MIN), hs, val)
        return out.astype(np.uint8 if n_bins <= 256 else np.uint16)
    # plain hsv
    if n_bins <= 256:
        return cv2.add(cv2.add(_bin8(H, a, 180, b * c), _bin8(S, b, 256, c)),
                       _bin8(V, c, 256))
    hb = np.minimum(k * a // 180, a - 1)
    out = (hb * b * c).astype(np.uint16)[H]
    out += (k * b // 256 * c).astype(np.uint16)[S]
    out += (k * c // 256).astype(np.uint16)[V]
    return out


# --------------------------------------------------------------------------------------
# boxes


def _check_boxes(boxes: Any) -> np.ndarray:
    b = np.asarray(boxes, dtype=float)
    if b.ndim != 2 or b.shape[1] != 4:
        raise InputError(f"boxes must have shape (N, 4) (cx, cy, w, h), got {b.shape}")
    if not (np.isfinite(b).all() and (b[:, 2:] > 0).all()):
        if not np.all(np.isfinite(b)):
            raise InputError("boxes must be finite (a box has a NaN or infinite coordinate)")
        raise InputError("boxes must have w > 0 and h > 0")
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
    ``inside`` and ``in_frac``. About 17 numpy calls for x and y together (numpy's
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
    ints = np.minimum(np.maximum(lohi, 0.0), np.array([[width], [height]])).astype(np.intp)
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


# --------------------------------------------------------------------------------------
# lazy per-frame quantisation


class _FrameBins:
    """One frame's bin image for one layout, quantised lazily, region by region.

    This is what :class:`ColourHistogramScorer` caches in the
    :class:`~pgm.core.frame.FrameContext` under ``("colour-bins", layout, a, b, c)``.
    ``bins`` is a full-size ``(H, W)`` buffer of which only the rectangle ``rect`` =
    ``(x0, x1, y0, y1)`` holds bins (the rest is uninitialised memory).
    :meth:`ensure` grows ``rect`` to cover a requested rectangle: a request inside it
    costs nothing; otherwise the bounding rectangle of both becomes the new ``rect``
    and only the strips it adds are quantised (up to four ``_quantize_bgr`` calls; one
    call over the whole new rectangle when re-quantising the old one is cheaper than
    the extra calls, a call costing about ``_CALL_PIXELS`` pixels). Quantisation is
    per pixel, so any region's bins equal those of :func:`quantize_colour` of the
    whole frame, bit for bit.

    ``requested`` (a list ``[x0, x1, y0, y1]``) is the bounding rectangle of every
    request on this frame, margins included. A scorer hands the previous frame's list
    to the next frame's object as ``hint``: the first request of the frame then
    quantises, in one call, the bounding rectangle of the request and the hint (when
    that is not much larger than both), so that factors which score different parts
    of one object (the bands of a face) cost one quantisation call per frame, not one
    per factor plus strips. ``pixels`` and ``regions`` count the pixels and calls
    quantised so far.
    """

    __slots__ = ("image", "canon", "bins", "rect", "requested", "hint", "pixels",
                 "regions")

    def __init__(self, image: Any, canon: tuple[str, int, int, int],
                 hint: list[int] | None = None):
        self.image = _check_image(image)
        self.canon = canon
        dtype = np.uint8 if _bin_count(canon) <= 256 else np.uint16
        height, width = self.image.shape[:2]
        self.bins = np.empty((height, width), dtype=dtype)
        self.rect = (0, 0, 0, 0)
        self.requested = [width, 0, height, 0]
        self.hint = hint
        self.pixels = 0
        self.regions = 0

    def ensure(self, x0: int, x1: int, y0: int, y1: int, margin: int = 0) -> np.ndarray:
        """``bins`` with at least ``[y0:y1, x0:x1]`` (clipped to the image) quantised;
        when it must grow, the request is widened by ``margin`` pixels first (so that
        slightly larger requests later cost nothing)."""
        height, width = self.bins.shape
        x0, x1 = max(x0, 0), min(x1, width)
        y0, y1 = max(y0, 0), min(y1, height)
        if x0 >= x1 or y0 >= y1:
            return self.bins
        x0m, x1m = max(x0 - margin, 0), min(x1 + margin, width)
        y0m, y1m = max(y0 - margin, 0), min(y1 + margin, height)
        req = self.requested
        req[:] = min(req[0], x0m), max(req[1], x1m), min(req[2], y0m), max(req[3], y1m)
        rx0, rx1, ry0, ry1 = self.rect
        if rx0 <= x0 and x1 <= rx1 and ry0 <= y0 and y1 <= ry1:
            return self.bins
        x0, x1, y0, y1 = x0m, x1m, y0m, y1m
        if rx0 >= rx1:                                   # nothing quantised yet
            if self.hint is not None:
                x0, x1, y0, y1 = self._with_hint(x0, x1, y0, y1)
            self._fill(x0, x1, y0, y1)
            self.rect = (x0, x1, y0, y1)
            return self.bins
        new = (min(rx0, x0), max(rx1, x1), min(ry0, y0), max(ry1, y1))
        nx0, nx1, ny0, ny1 = new
        strips = [s for s in ((nx0, nx1, ny0, ry0), (nx0, nx1, ry1, ny1),
                              (nx0, rx0, ry0, ry1), (rx1, nx1, ry0, ry1))
                  if s[0] < s[1] and s[2] < s[3]]
        if (rx1 - rx0) * (ry1 - ry0) <= _CALL_PIXELS * (len(strips) - 1):
            strips = [new]
        for s in strips:
            self._fill(*s)
        self.rect = new
        return self.bins

    def _with_hint(self, x0: int, x1: int, y0: int, y1: int) -> tuple[int, int, int, int]:
        """The request grown to the hint's rectangle (clipped to the image) when their
        bounding rectangle is at most 1.5 times their two areas together."""
        height, width = self.bins.shape
        hx0, hx1, hy0, hy1 = self.hint
        self.hint = None
        hx0, hx1, hy0, hy1 = max(hx0, 0), min(hx1, width), max(hy0, 0), min(hy1, height)
        if hx0 >= hx1 or hy0 >= hy1:
            return x0, x1, y0, y1
        bx0, bx1, by0, by1 = min(x0, hx0), max(x1, hx1), min(y0, hy0), max(y1, hy1)
        if (bx1 - bx0) * (by1 - by0) > 1.5 * ((x1 - x0) * (y1 - y0)
                                              + (hx1 - hx0) * (hy1 - hy0)):
            return x0, x1, y0, y1
        return bx0, bx1, by0, by1

    def full(self) -> np.ndarray:
        """``bins`` with the whole frame quantised."""
        height, width = self.bins.shape
        return self.ensure(0, width, 0, height)

    def _fill(self, x0: int, x1: int, y0: int, y1: int) -> None:
        roi = self.image[y0:y1, x0:x1]
        if roi.ndim == 2:
            roi = cv2.cvtColor(roi, cv2.COLOR_GRAY2BGR)
        self.bins[y0:y1, x0:x1] = _quantize_bgr(roi, self.canon)
        self.pixels += (x1 - x0) * (y1 - y0)
        self.regions += 1


# --------------------------------------------------------------------------------------
# kernel-weighted histograms (grid approximation)


def _grid_points(kernel: str, grid: int):
    """Lattice of a grid kernel: row/column indices of the kept samples, the
    relative positions ``u`` in (-1/2, 1/2) and the weights of the kept samples."""
    u = (np.arange(grid) + 0.5) / grid - 0.5
    kk, ll = np.divmod(np.arange(grid * grid), grid)       # row k, column l
    if kernel == "epanechnikov":
        wgt = 1.0 - (2.0 * u[kk]) ** 2 - (2.0 * u[ll]) ** 2
    else:
        wgt = np.ones(grid * grid)
    keep = wgt > 0
    return kk[keep], ll[keep], u, wgt[keep]


def _grid_histograms(bins: np.ndarray, n_bins: int, b: np.ndarray, kernel: str,
                     grid: int, frame: _FrameBins | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Kernel-weighted histograms from a fixed ``grid x grid`` sample of every box.

    Sample ``(k, l)`` sits at ``(cx + w u_l, cy + h u_k)`` with
    ``u_k = (k + 1/2)/grid - 1/2`` and reads the pixel that contains it. Epanechnikov
    weight ``1 - r^2`` with ``r^2 = (2 u_l)^2 + (2 u_k)^2`` (samples with r >= 1 are
    dropped). Samples outside the image are absent; ``in_frac`` is the in-image
    share of the kernel mass. One ``np.take`` and one ``np.bincount`` over all
    N x samples; no loop over boxes. With ``frame`` (``bins`` is then ``frame.bins``)
    only the rectangle of the pixels sampled is quantised.
    """
    height, width = bins.shape
    n = len(b)
    kk, ll, u, wgt = _grid_points(kernel, grid)
    cols = np.floor(b[:, 0:1] + b[:, 2:3] * u[None, :])     # (N, grid), separable
    rows = np.floor(b[:, 1:2] + b[:, 3:4] * u[None, :])
    in_c = (cols >= 0) & (cols < width)
    in_r = (rows >= 0) & (rows < height)
    ci = _clip(cols, 0, width - 1).astype(np.intp)
    ri = _clip(rows, 0, height - 1).astype(np.intp)
    if frame is not None and n:
        frame.ensure(int(ci.min()), int(ci.max()) + 1, int(ri.min()), int(ri.max()) + 1,
                     margin=_ROI_MARGIN)
    ri *= width
    m = len(kk)
    ws = _SCRATCH                                           # see _Scratch: no faults
    pix = ws.get("grid-pix", (n, m), np.intp)
    np.take(ri, kk, axis=1, out=pix, mode="clip")
    pix += np.take(ci, ll, axis=1)                          # (N, M) pixel indices
    sampled = ws.get("grid-bins", (n, m), bins.dtype)
    np.take(bins.reshape(-1), pix, out=sampled, mode="clip")
    key = pix                                               # reuse: bin + box offset
    np.add(sampled, (np.arange(n) * n_bins)[:, None], out=key)
    all_in = bool(in_c.all() and in_r.all())
    inside = None if all_in else np.take(in_r, kk, axis=1) & np.take(in_c, ll, axis=1)
    if kernel == "epanechnikov":
        wmat = ws.get("grid-w", (n, m), np.float64)
        if all_in:
            wmat[:] = wgt
        else:
            np.multiply(inside, wgt, out=wmat)
        hist = np.bincount(key.reshape(-1), weights=wmat.reshape(-1),
                           minlength=n * n_bins)
        mass = np.full(n, wgt.sum()) if all_in else wmat.sum(axis=1)
        total = wgt.sum()
    else:
        if not all_in:
            key[~inside] = n * n_bins                      # dump slot
        hist = np.bincount(key.reshape(-1), minlength=n * n_bins + 1)[:n * n_bins]
        hist = hist.astype(np.float64)
        mass = (np.full(n, float(m)) if all_in
                else inside.sum(axis=1).astype(np.float64))
        total = float(m)
    hist = hist.astype(np.float64, copy=False).reshape(n, n_bins)
    hist /= np.maximum(mass, np.finfo(float).tiny)[:, None]
    return hist, mass / total


# --------------------------------------------------------------------------------------
# similarity and the scorer


def bhattacharyya(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Bhattacharyya coefficient ``sum_u sqrt(p_u q_u)`` of each row of ``p``.

    ``p`` is ``(N, B)`` (or ``(B,)``, giving a scalar array), ``q`` is ``(B,)``; both
    are expected to be normalised, non-negative histograms.
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    if q.ndim != 1 or p.shape[-1:] != q.shape or p.ndim > 2:
        raise InputError(f"bhattacharyya: p must be (N, B) and q (B,), got {p.shape} "
                         f"and {q.shape}")
    if np.any(p < 0) or np.any(q < 0) or not (np.all(np.isfinite(p))
                                              and np.all(np.isfinite(q))):
        raise InputError("bhattacharyya: histograms must be finite and non-negative")
    return np.sqrt(p) @ np.sqrt(q)


class ColourHistogramScorer:
    """Colour-histogram likelihood of candidate boxes (``SPEC.md`` §1).

    ``rho(ctx, boxes)`` is the Bhattacharyya coefficient between each box's
    histogram and the template ``q``, multiplied by the box's in-image fraction, so
    that a box mostly off the image cannot win on a sliver and a box wholly outside
    scores 0. The log-likelihood is then ``-lam * (1 - rho)``.

    Parameters
    ----------
    layout, n_h, n_s, n_v, n_rgb
        Bin layout; see :func:`quantize_colour`.
    kernel : {"uniform", "epanechnikov", "grid-uniform"}
        ``"uniform"`` (default): every pixel of the box counts once; exact, by
        integral histograms. ``"epanechnikov"``: Nummiaro et al.'s kernel
        ``k(r) = 1 - r^2``, ``r`` the normalised elliptical radius in the box;
        integral histograms cannot weight pixels, so this is a *grid approximation*:
        a fixed ``grid x grid`` lattice of sample points in every box (the points
        with ``r < 1``), each reading the pixel that contains it. ``"grid-uniform"``:
        the same lattice with unit weights (an approximation of "uniform").
    grid : int
        Lattice size of the grid kernels (default 16: 256 samples, 200 inside the
        Epanechnikov ellipse).
    q : array (B,), optional
        Template histogram; normally set by :meth:`template`.
    """

    def __init__(self, layout: str = "perez", n_h: int = 16, n_s: int = 4,
                 n_v: int | None = None, kernel: str = "uniform", *, grid: int = 16,
                 n_rgb: int = 8, q: np.ndarray | None = None):
        self._canon = _resolve_layout(layout, n_h, n_s, n_v, n_rgb)
        if kernel not in KERNELS:
            raise InputError(f"unknown kernel {kernel!r}; expected one of {KERNELS}")
        self.kernel = kernel
        self.grid = _check_count("grid", grid, 4096)
        self.q: np.ndarray | None = None if q is None else self._check_q(q)
        self._templates: dict[tuple, _Template] = {}
        self._requested: list[int] | None = None   # see _FrameBins (hint)

    # parameters ----------------------------------------------------------------------
    @property
    def layout(self) -> str:
        return self._canon[0]

    @property
    def n_bins(self) -> int:
        return _bin_count(self._canon)

    @property
    def cache_key(self) -> tuple:
        """``FrameContext`` cache key of the frame's lazily quantised bins (a
        ``_FrameBins``: full-size buffer plus the rectangle quantised so far, shared
        by every scorer of the same layout)."""
        return ("colour-bins",) + self._canon

    def __repr__(self) -> str:
        lay, a, b, c = self._canon
        return (f"ColourHistogramScorer(layout={lay!r}, bins=({a}, {b}, {c}), "
                f"kernel={self.kernel!r})")

    # frames --------------------------------------------------------------------------
    @staticmethod
    def _ctx(image_or_ctx: Any) -> FrameContext:
        if isinstance(image_or_ctx, FrameContext):
            return image_or_ctx
        return FrameContext(0, image_or_ctx)

    def _frame(self, image_or_ctx: Any) -> _FrameBins:
        """The frame's lazily quantised bins (cached in the context)."""
        ctx = self._ctx(image_or_ctx)
        if ctx.image is None:
            raise InputError(f"frame {ctx.index} has no image")
        frame = ctx.cached(self.cache_key,
                           lambda: _FrameBins(ctx.image, self._canon, self._requested))
        self._requested = frame.requested        # this frame's requests: next one's hint
        return frame

    def bins(self, image_or_ctx: Any) -> np.ndarray:
        """The frame's whole bin image, quantised once per frame (cached in the
        context; regions already quantised for boxes are not quantised again)."""
        return self._frame(image_or_ctx).full()

    def _check_q(self, q: Any) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if q.shape != (self.n_bins,):
            raise InputError(f"template must have shape ({self.n_bins},), got {q.shape}")
        if not np.all(np.isfinite(q)) or np.any(q < 0) or q.sum() <= 0:
            raise InputError("template must be finite, non-negative and not all zero")
        return q / q.sum()

    def _template_of(self, q: Any) -> _Template:
        """Prepared template of ``q`` (validated and normalised) or, for None, of the
        stored ``self.q`` (used as it is); cached by value, so a caller passing the same
        array every frame pays neither the checks nor the preparation again."""
        if q is None:
            if self.q is None:
                raise InputError("no template: call template() first or pass q")
            arr, raw = np.asarray(self.q), True
        else:
            arr, raw = np.asarray(q, dtype=float), False
        key = (raw, arr.dtype.str, arr.shape, arr.tobytes())
        t = self._templates.get(key)
        if t is None:
            t = _Template(np.array(arr) if raw else self._check_q(arr), self.n_bins)
            if len(self._templates) >= 8:
                self._templates.clear()
            self._templates[key] = t
        return t

    # scoring -------------------------------------------------------------------------
    def histograms(self, image_or_ctx: Any,
                   boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(hist (N, B), in_frac (N,))`` of the boxes under this scorer's kernel."""
        frame = self._frame(image_or_ctx)
        b = _check_boxes(boxes)
        if self.kernel == "uniform":
            return _histograms(frame.bins, self.n_bins, b, frame)
        return _grid_histograms(frame.bins, self.n_bins, b, self.kernel, self.grid, frame)

    def template(self, image_or_ctx: Any, box: np.ndarray) -> np.ndarray:
        """Histogram ``(B,)`` of one box ``(cx, cy, w, h)``; also stored as ``self.q``."""
        b = np.asarray(box, dtype=float)
        if b.shape == (4,):
            b = b[None, :]
        if b.shape != (1, 4):
            raise InputError(f"template box must have shape (4,), got {b.shape}")
        hist, in_frac = self.histograms(image_or_ctx, b)
        if in_frac[0] <= 0:
            raise InputError(f"template box {b[0].tolist()} lies wholly outside the image")
        self.q = hist[0] / hist[0].sum()
        return self.q.copy()

    def rho(self, image_or_ctx: Any, boxes: np.ndarray,
            q: np.ndarray | None = None) -> np.ndarray:
        """Bhattacharyya coefficient x in-image fraction, ``(N,)``, of each box.

        ``q`` defaults to the stored template (:meth:`template`). Only the boxes'
        union rectangle of the frame is quantised (once per frame and layout).
        """
        t = self._template_of(q)
        b = _check_boxes(boxes)
        frame = self._frame(image_or_ctx)
        if self.kernel == "uniform":
            return _rho_of_template(frame.bins, b, t, frame)
        hist, in_frac = _grid_histograms(frame.bins, self.n_bins, b, self.kernel,
                                         self.grid, frame)
        return (np.sqrt(hist) @ t.sqrt_q) * in_frac

    def rho_many(self, image_or_ctx: Any, boxes: np.ndarray, templates: np.ndarray,
                 owner: np.ndarray) -> np.ndarray:
        """:meth:`rho` of boxes scored against *several* templates in one pass.

        ``templates`` ``(K, B)``; box ``i`` is scored against ``templates[owner[i]]``.
        One integral-histogram pass over the union of the boxes counts the union of
        the templates' supports, so the factors of a part graph (one template per part,
        one frame) cost one call instead of one each. Equal to :meth:`rho` per box.
        """
        if self.kernel != "uniform":
            return np.concatenate([self.rho(image_or_ctx, boxes[owner == k], templates[k])
                                   for k in range(len(templates))])[np.argsort(
                                       np.argsort(owner, kind="stable"), kind="stable")]
        T = np.asarray(templates, dtype=float)
        key = ("many", T.shape, T.tobytes())
        prepared = self._templates.get(key)
        if prepared is None:
            qs = np.array([self._check_q(q) for q in T])
            t = _Template((qs > 0).any(axis=0).astype(float), self.n_bins)
            support = np.flatnonzero(t.slot_of_bin < t.k)
            prepared = (t, np.sqrt(qs[:, support]))
            if len(self._templates) >= 8:
                self._templates.clear()
            self._templates[key] = prepared
        t, sqrt_q = prepared
        b = _check_boxes(boxes)
        frame = self._frame(image_or_ctx)
        bins = frame.bins
        ints, inside, in_frac = _bounds(b, *bins.shape)
        union, all_nonempty = _union_of(ints, inside)
        if union is not None:
            frame.ensure(*union, margin=_ROI_MARGIN)
        counts = _counts(bins, ints, union, all_nonempty, t.slot_of_bin, t.k, slot8=t.slot8)
        root = np.sqrt(counts.astype(np.float64, copy=False))
        num = np.einsum("ij,ji->i", sqrt_q[np.asarray(owner)], root)  # counts are (k, N)
        return num / np.sqrt(np.maximum(inside, 1)) * in_frac

    def log_likelihood(self, image_or_ctx: Any, boxes: np.ndarray, lam: float = 20.0,
                       q: np.ndarray | None = None) -> np.ndarray:
        """``-lam * (1 - rho)`` (``SPEC.md`` §1, default ``lam = 20``)."""
        return -float(lam) * (1.0 - self.rho(image_or_ctx, boxes, q))


# --------------------------------------------------------------------------------------
# reference (tests and benchmarks only)


def _reference_box_histograms(bins: np.ndarray, n_bins: int,
                              boxes_cxcywh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Plain loop: ``np.bincount`` of each box's pixels; returns *unnormalised*
    integer counts ``(N, n_bins)`` int64 and ``in_frac``, for tests only."""
    bins = np.asarray(bins)
    b = _check_boxes(boxes_cxcywh)
    height, width = bins.shape
    counts = np.zeros((len(b), n_bins), dtype=np.int64)
    in_frac = np.zeros(len(b))
    for i, (cx, cy, w, h) in enumerate(b):
        x0 = int(np.floor(cx - w / 2 + 0.5))
        x1 = max(int(np.floor(cx + w / 2 + 0.5)), x0 + 1)
        y0 = int(np.floor(cy - h / 2 + 0.5))
        y1 = max(int(np.floor(cy + h / 2 + 0.5)), y0 + 1)
        roi = bins[max(y0, 0):max(min(y1, height), 0), max(x0, 0):max(min(x1, width), 0)]
        counts[i] = np.bincount(roi.ravel(), minlength=n_bins)
        in_frac[i] = roi.size / ((x1 - x0) * (y1 - y0))
    return counts, in_frac
