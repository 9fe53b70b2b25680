"""Histograms of a few boxes from their own pixels only: the boxes' pixels gathered and
quantised, nothing else of the frame read (detections: a few disjoint boxes over a large
frame, where the integral histograms of :mod:`~.integral` would quantise their union),
each box on its own lattice of the frame's pixels."""

from __future__ import annotations

import numpy as np

from pgm.observation.appearance.colour.integral import _bounds
from pgm.observation.appearance.colour.quantize import _MIN_SIDE, _quantize_bgr

__all__ = []

#: gathered pixels are quantised as an image up to this many pixels wide (and at least
#: ``_MIN_SIDE`` rows tall where there are enough): OpenCV's colour conversion pays per row,
#: so 8-pixel rows cost 2.4 times as much as 1024-pixel ones for the same 18 000 pixels
_ROW = 1024


def _lattice_indices(ints: np.ndarray, inside: np.ndarray, step: np.ndarray, width: int
                     ) -> np.ndarray:
    """Flat frame indices ``(inside.sum(),)`` of each box's lattice pixels, box by box,
    row by row: box ``i`` covers lattice rows ``ints[0, 1, i]:ints[1, 1, i]`` and columns
    ``ints[0, 0, i]:ints[1, 0, i]`` of the frame's every ``step[i]``-th pixel.

    Built as the running sum of the steps between consecutive pixels (``step`` within a
    row, a jump at each row's start), so the per-pixel work is one ``repeat`` and one
    ``cumsum``; the rest is per row (a box has tens of rows, hundreds of pixels)."""
    w = ints[1, 0] - ints[0, 0]
    h = np.where(inside > 0, ints[1, 1] - ints[0, 1], 0)
    row_box = np.repeat(np.arange(len(h)), h)
    row = np.arange(len(row_box)) - (np.cumsum(h) - h)[row_box]
    s, wr = step[row_box], w[row_box]
    first = ((ints[0, 1][row_box] + row) * width + ints[0, 0][row_box]) * s
    last = first + (wr - 1) * s
    delta = np.repeat(s, wr)
    starts = np.cumsum(wr) - wr
    delta[starts] = first
    delta[starts[1:]] -= last[:-1]
    return np.cumsum(delta)


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
    flat = _lattice_indices(ints, inside, step, width)
    box = np.repeat(np.arange(n), inside)
    if image.flags.c_contiguous:
        pixels = np.take(image.reshape(height * width, -1), flat, axis=0)
    else:
        pixels = image[flat // width, flat % width]
    pixels = pixels.reshape(total, -1)
    row = min(_ROW, max(_MIN_SIDE, -(-total // _MIN_SIDE)))
    pad = -total % row
    if pad:
        pixels = np.concatenate([pixels, np.repeat(pixels[-1:], pad, axis=0)])
    bins = _quantize_bgr(pixels.reshape(-1, row, pixels.shape[1]), canon).reshape(-1)[:total]
    counts = np.bincount(box * n_bins + bins, minlength=n * n_bins)
    hist[:] = counts.reshape(n, n_bins)
    hist /= np.maximum(inside, 1)[:, None]
    return hist, in_frac
