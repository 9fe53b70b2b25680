"""The correlation filter's building blocks: window features, the filter's closed form
and ridge, and reading a response map (peak-to-sidelobe ratio, its peaks)."""

from __future__ import annotations

from typing import NamedTuple

import cv2
import numpy as np
import scipy.fft as sfft

__all__ = ["window_features", "patch_features", "chroma_frame", "CHROMA_UNIT",
           "peak_to_sidelobe", "response_peaks", "Scan", "filter_of", "ridge", "MAX_DETECT_PX"]


def peak_to_sidelobe(response: np.ndarray, radius: int) -> float:
    """Peak-to-sidelobe ratio of a response map [#bolme2010]: ``(max − μ) / σ`` of the
    cells outside the ``(2 radius + 1)²`` square around the peak (``σ`` floored at
    ``1e-12`` of the peak's magnitude, so a flat side lobe gives a large, finite ratio)."""
    r = np.asarray(response, dtype=float)
    iy, ix = np.unravel_index(int(np.argmax(r)), r.shape)
    side = np.ones(r.shape, dtype=bool)
    side[max(iy - radius, 0):iy + radius + 1, max(ix - radius, 0):ix + radius + 1] = False
    if not side.any():
        raise ValueError(f"the response map {r.shape} has no side lobe outside radius {radius}")
    lobe = r[side]
    peak = float(r[iy, ix])
    return float((peak - lobe.mean()) / max(float(lobe.std()), 1e-12 * max(abs(peak), 1e-300)))


#: widest region scanned for re-detection (:meth:`CorrelationFilterLikelihood.detect`), in
#: template pixels per side: a larger frame is scanned in a window of this side around
#: the last estimate
MAX_DETECT_PX = 1024


class Scan(NamedTuple):
    """A whole-frame scan (:meth:`CorrelationFilterLikelihood.detect`)."""

    centres: np.ndarray  #: (m, 2) peak centres, image pixels
    values: np.ndarray  #: (m,) relative responses
    z: np.ndarray  #: (m,) standard scores within the scanned map
    independent: float  #: independent values in the map (for a max-of-noise threshold)


def response_peaks(response: np.ndarray, radius: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``k`` highest local maxima of a map, at least ``radius`` cells apart (a
    maximum of its ``(2 radius + 1)²`` neighbourhood): rows and columns ``(m, 2)`` as
    ``(x, y)``, and their values ``(m,)``, highest first (``m <= k``)."""
    r = np.asarray(response, dtype=np.float32)
    size = 2 * int(radius) + 1
    dil = cv2.dilate(r, np.ones((size, size), np.uint8))
    ys, xs = np.nonzero(r >= dil)
    vals = r[ys, xs]
    keep: list[int] = []
    # the highest maxima first (ties in row order); most maps need only the first few, so
    # those at or above the 8k-th highest value are sorted first, all of them if needed
    top = 8 * k
    pools = ([np.flatnonzero(vals >= np.partition(vals, len(vals) - top)[len(vals) - top])]
             if len(vals) > top else []) + [None]
    for pool in pools:
        keep = []
        order = (np.argsort(-vals, kind="stable") if pool is None else
                 pool[np.argsort(-vals[pool], kind="stable")])
        for i in order:  # suppress plateaus: one maximum per neighbourhood
            if all(max(abs(xs[i] - xs[j]), abs(ys[i] - ys[j])) > radius for j in keep):
                keep.append(int(i))
                if len(keep) == k:
                    break
        if len(keep) == k:
            break
    idx = np.array(keep, dtype=np.intp)
    return np.stack([xs[idx], ys[idx]], axis=1).astype(float), vals[idx].astype(float)


def filter_of(gf: np.ndarray, xf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The filter ``(num, den)`` that one sample of spectrum ``xf`` ``(C, ...)`` alone
    gives for the label spectrum ``gf`` (MOSSE / DSST's closed form, any dimension):
    ``conj(G) · X_c`` and ``Σ_c |X_c|²``."""
    return np.conj(gf)[None] * xf, np.sum((xf * np.conj(xf)).real, axis=0)


def ridge(den: np.ndarray, reg: float) -> np.ndarray:
    """A filter's denominator plus its ridge: ``reg`` times its mean energy (and a floor,
    since a flat window has none)."""
    return den + (reg * float(den.mean()) + 1e-12)


def _fast_even(cells: float) -> int:
    """The window's side in cells: ``cells`` rounded to the nearest even number (at least
    8) whose half has no prime factor above 5 (the larger on a tie). The FFTs of every
    frame are of the window's size, and a side with a large prime factor costs several
    times a 5-smooth one (158 x 58 cells, 79 and 29 prime: 1.3–1.4 ms for the seven
    channels against 0.4–0.5 ms at 160 x 60); the window keeps its extent in the image,
    so its cells are finer or coarser than at the exact size by at most 6 % on a side of
    64 cells or more (the default's windows: ``target_px · (1 + padding)`` = 96 cells
    on the box's geometric mean), 9 % from 32, a seventh below."""
    half = max(4, int(round(cells / 2)))
    up = sfft.next_fast_len(half, real=True)  # 5-smooth for a real transform
    down = sfft.prev_fast_len(half, real=True)
    return 2 * (up if up - half <= half - down else down)


def _one_cloud(xy: np.ndarray, centre: np.ndarray, quarter: np.ndarray) -> bool:
    """Whether nine in ten points lie within ``quarter`` (per axis) of ``centre``."""
    return bool(np.mean(np.all(np.abs(xy - centre) <= quarter, axis=1)) >= 0.9)


def window_features(grey: np.ndarray, centre, size, out_shape, n_orient: int,
                    angle: float = 0.0, chroma: np.ndarray | None = None) -> np.ndarray:
    """Features ``(1 + n_orient, th, tw)`` of the window of ``size = (w, h)`` px centred
    on ``centre = (cx, cy)`` and turned by ``angle`` (radians, image axes: x right, y
    down), resampled to ``out_shape = (tw, th)`` (border replicated); with ``chroma``
    (:func:`chroma_frame`), its two channels follow (``(3 + n_orient, th, tw)``)."""
    tw, th = out_shape
    sx, sy = size[0] / tw, size[1] / th
    c, s = np.cos(angle), np.sin(angle)
    # pixel centre convention: output pixel (i, j) maps to
    # centre - 0.5 + R(angle) diag(sx, sy) (i + 0.5 - tw/2, j + 0.5 - th/2)
    a0, b0 = 0.5 - tw / 2, 0.5 - th / 2
    m = np.array([[c * sx, -s * sy, centre[0] - 0.5 + c * sx * a0 - s * sy * b0],
                  [s * sx, c * sy, centre[1] - 0.5 + s * sx * a0 + c * sy * b0]])
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    patch = cv2.warpAffine(grey, m, (tw, th), flags=flags, borderMode=cv2.BORDER_REPLICATE)
    feats = patch_features(patch, n_orient)
    if chroma is None:
        return feats
    ab = cv2.warpAffine(chroma, m, (tw, th), flags=flags, borderMode=cv2.BORDER_REPLICATE)
    return np.concatenate([feats, np.moveaxis(ab, -1, 0)], axis=0)


#: Lab chroma units per feature unit (:func:`chroma_frame`): a strongly coloured surface
#: (``a*`` or ``b*`` about ±40) reads about as far from grey as the grey channel's spread
CHROMA_UNIT = 80.0


def chroma_frame(image: np.ndarray) -> np.ndarray:
    """``(H, W, 2)`` ``float32`` chroma of a BGR ``image``: CIE Lab's ``a*`` and ``b*``
    over :data:`CHROMA_UNIT` (0 for grey; zeros for a grey image) — colour in
    perceptual units, the same on any video's exposure of the same surface."""
    if image.ndim != 3:
        return np.zeros(image.shape[:2] + (2,), np.float32)
    lab = cv2.cvtColor(np.asarray(image, np.float32) / 255.0, cv2.COLOR_BGR2LAB)
    return np.ascontiguousarray(lab[:, :, 1:] / CHROMA_UNIT, dtype=np.float32)


_PI32 = np.float32(np.pi)


def patch_features(patch: np.ndarray, n_orient: int) -> np.ndarray:
    """Features ``(1 + n_orient, h, w)`` of a grey ``float32`` patch: its grey level
    (contrast-normalised) and ``n_orient`` locally normalised gradient orientations."""
    th, tw = patch.shape
    gx = cv2.Sobel(patch, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(patch, cv2.CV_32F, 0, 1, ksize=3)
    mag = np.sqrt(gx * gx + gy * gy)
    # the angle modulo pi, as np.mod gives it (bit for bit) at a tenth of its cost
    t = np.arctan2(gy, gx)
    theta = np.where(t < 0, t + _PI32, np.where(t >= _PI32, t - _PI32, t))
    theta *= np.float32(n_orient / np.pi)  # [0, n_orient)
    feats = np.empty((1 + n_orient, th, tw), np.float32)
    energy = np.sqrt(np.maximum(cv2.boxFilter(mag * mag, -1, (5, 5)), 0)) + 1e-3 * 255
    w = np.empty_like(theta)
    for c in range(n_orient):  # soft (linear) binning on the circle of orientations
        np.subtract(theta, c, out=w)
        np.abs(w, out=w)
        if c == 0:  # the one bin the circle wraps onto (theta in [0, n_orient))
            np.minimum(w, n_orient - w, out=w)
        np.subtract(1, w, out=w)
        np.maximum(w, 0, out=w)
        w *= mag
        np.divide(cv2.boxFilter(w, -1, (3, 3)), energy, out=feats[1 + c])
    mean, std = float(patch.mean()), float(patch.std()) + 1e-3 * 255
    feats[0] = (patch - mean) / std * 0.5  # grey, contrast-normalised
    return feats
