"""Histograms of a few boxes from their own pixels only: the boxes' pixels gathered and
quantised, nothing else of the frame read (detections: a few disjoint boxes over a large
frame, where the integral histograms of :mod:`~.integral` would quantise their union),
each box on its own lattice of the frame's pixels."""

from __future__ import annotations

import numpy as np

from pgm.observation.appearance.colour.integral import _bounds
from pgm.observation.appearance.colour.quantize import _quantize_bgr

__all__ = []

_ROW = 8      # gathered pixels are quantised as an image this many pixels wide


def _gathered_histograms(image: np.ndarray, canon: tuple[str, int, int, int], n_bins: int,
                         b: np.ndarray, levels: np.ndarray | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
    """``(hist (N, n_bins), in_frac (N,))`` of validated boxes ``b`` on ``image`` (BGR).

    Box ``i`` is read on the lattice of every ``s = 2**levels[i]``-th pixel of every
    ``s``-th row (``levels`` None: every pixel), exactly the pixels
    :func:`~.integral.box_histograms` counts of the box ``b[i] / s`` on ``image[::s,
    ::s]``. The boxes' lattice pixels are gathered by one index (no loop over boxes),
    quantised together and counted by one ``np.bincount``: the cost is the pixels read,
    not the boxes' union."""
    height, width = image.shape[:2]
    n = len(b)
    if levels is None:
        step = np.ones(n, dtype=np.intp)
        ints, inside, in_frac = _bounds(b, height, width)
    else:
        step = np.left_shift(1, np.asarray(levels, dtype=np.intp))
        ints, inside, in_frac = _bounds(b / step[:, None], -(-height // step),
                                        -(-width // step))
    hist = np.zeros((n, n_bins))
    total = int(inside.sum())
    if total == 0:
        return hist, in_frac
    w = ints[1, 0] - ints[0, 0]
    start = np.cumsum(inside) - inside
    box = np.repeat(np.arange(n), inside)
    local = np.arange(total) - start[box]
    wb, sb = w[box], step[box]
    rows = (ints[0, 1][box] + local // wb) * sb
    cols = (ints[0, 0][box] + local % wb) * sb
    if image.flags.c_contiguous:
        pixels = np.take(image.reshape(height * width, -1), rows * width + cols, axis=0)
    else:
        pixels = image[rows, cols]
    pixels = pixels.reshape(total, -1)
    pad = -total % _ROW
    if pad:
        pixels = np.concatenate([pixels, np.repeat(pixels[-1:], pad, axis=0)])
    bins = _quantize_bgr(pixels.reshape(-1, _ROW, pixels.shape[1]), canon).reshape(-1)[:total]
    counts = np.bincount(box * n_bins + bins, minlength=n * n_bins)
    hist[:] = counts.reshape(n, n_bins)
    hist /= np.maximum(inside, 1)[:, None]
    return hist, in_frac
