"""Loop-based reference implementations of vectorised kernels (tests and benchmarks only).

Each function here is the plain, obviously-correct version of a fast kernel in the
package; the tests compare the two (GPflow's ``tests/.../reference.py`` habit).
"""

from __future__ import annotations

import numpy as np

from pgm.observation.appearance.colour.integral import _check_boxes


def reference_box_histograms(bins: np.ndarray, n_bins: int,
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
