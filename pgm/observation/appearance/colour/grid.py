"""Kernel-weighted box histograms on a regular grid of sample points (Epanechnikov kernel)."""

from __future__ import annotations

import numpy as np

from pgm.observation.appearance.colour.cache import _FrameBins
from pgm.observation.appearance.colour.integral import _ROI_MARGIN, _SCRATCH, _clip

__all__ = []



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


