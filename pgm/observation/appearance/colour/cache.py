"""The per-frame colour-bin cache: a region is quantised once per frame and layout, lazily."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

from pgm.observation.appearance.colour.quantize import _bin_count, _check_image, _quantize_bgr

__all__ = []

_CALL_PIXELS = 5000           # fixed cost of one region quantisation, in pixels


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


