"""Colour quantisation of a frame region into histogram bins (step 1 of
:mod:`pgm.observation.appearance.colour`).

References
----------
.. [#perez2002] P. Pérez, C. Hue, J. Vermaak and M. Gangnet, "Color-based probabilistic
   tracking", Proc. ECCV 2002, LNCS 2350, 661–675. doi:10.1007/3-540-47969-4_44
.. [#zhang2015] M.-J. Zhang and B.-S. Kang, "Particle filter tracking method using graphical
   model", Journal of Computers (Computer Society of the R.O.C.), 2015 (accepted March 2015;
   venue inferred from the article's layout; volume, pages and DOI not confirmed).
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from pgm.core.errors import InputError

__all__ = ['quantize_colour', 'colour_bin_count', 'LAYOUTS']

LAYOUTS = ("perez", "hsv", "rgb")

# Pérez et al. [#perez2002]: a pixel is chromatic when saturation > 0.1 and value > 0.2
# (OpenCV 8-bit HSV: S >= 26, V >= 52).
_S_MIN = 26
_V_MIN = 52
_MAX_BINS = 1 << 16
_MIN_SIDE = 8  # regions narrower than this are padded before OpenCV sees them


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
        ``"perez"`` (default; the layout of Pérez et al. [#perez2002]): OpenCV 8-bit
        HSV; pixels with ``S >= 26`` and ``V >= 52`` go to ``n_h * n_s`` hue-saturation
        bins ``(H * n_h // 180) * n_s + S * n_s // 256`` (so the lowest saturation bin
        holds S in [26, 64) with the defaults), every other pixel to one of ``n_v``
        value-only bins ``n_h*n_s + V * n_v // 256``. Greyscale frames therefore
        keep an ``n_v``-bin intensity histogram.
        ``"hsv"``: plain ``n_h x n_s x n_v`` bins, ``((h * n_s) + s) * n_v + v``
        (16 x 4 x 4 = 256 by default, as in [#zhang2015]; a greyscale frame collapses
        onto the ``n_v`` bins of hue 0, saturation 0).
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
    h, w = img.shape[:2]
    if h < _MIN_SIDE or w < _MIN_SIDE:
        # OpenCV's Python bindings read a (k, 1) or (1, 1) array next to a number as a
        # Scalar pair of the wrong size (a 1x1 or 4x1 box failed in ``cv2.compare``);
        # quantise an edge-padded copy instead and crop (pixels are binned independently)
        pad = ((0, max(_MIN_SIDE - h, 0)), (0, max(_MIN_SIDE - w, 0)), (0, 0))
        return np.ascontiguousarray(_quantize_bgr(np.pad(img, pad, mode="edge"),
                                                  canon)[:h, :w])
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


