"""Appearance at the resolution it needs: each box of a frame scored, and learned from, on
the frame shrunk by a power of two that leaves it a bounded number of pixels, all boxes of
a cue at once.

A colour histogram of a 200-pixel-tall person does not need its 20 000 pixels: a few
thousand samples of its colours describe it as well. :func:`box_levels` gives each box its
*level* ``k``, the largest (at most :data:`MAX_LEVEL`) at which the box, shrunk ``2**k``
times a side, keeps at least ``box_pixels`` pixels (:data:`BOX_PIXELS`), so that every box
is read from between ``box_pixels`` and four times as many pixels where the frame allows
(a box smaller than that keeps every pixel it has). The constant is in the box's own
units, so it carries across resolutions and across the boxes of one frame: a tall person
near a 1080p camera is read at level 3, a small one far away at level 0, the same pixels
either way.

:func:`appearance_matrix` scores every track's models of one cue against every box, and
:func:`learn_all` teaches many models their boxes, in one call per cue:

* a cue class with ``log_likelihood_matrix(models, x, ctx, levels)`` (and ``learn_many(
  models, ctx, values, levels)``) reads each box at its level itself, in one pass (the
  colour histogram: each box's pixels gathered on its own lattice of the frame's pixels,
  histograms computed once, one matrix product with the templates);
* any other cue is given, per level present, the frame shrunk by averaging
  (:func:`pyramid_level`, OpenCV's ``INTER_AREA``, computed once per frame and cached in
  its :class:`~pgm.core.frame.FrameContext`) and its boxes in that frame's pixels, and
  asked model by model (``log_likelihood``, ``learn``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from pgm.core.frame import FrameContext

__all__ = ["BOX_PIXELS", "MAX_LEVEL", "appearance_matrix", "box_levels", "learn_all",
           "pyramid_level", "working_frames"]

#: the fewest pixels a box is read from where it has them: each box is read from between
#: this many and four times as many (chosen so that the multi-target default's tracks on
#: every shared MOT sequence equal those of reading every pixel; half of it changes them)
BOX_PIXELS = 1024
#: the deepest level used (a box shrunk at most 8 times a side)
MAX_LEVEL = 3


def box_levels(boxes: np.ndarray, box_pixels: float = BOX_PIXELS,
               max_level: int = MAX_LEVEL) -> np.ndarray:
    """Each box's level ``(M,)`` intp: the largest ``k <= max_level`` at which its area
    ``w h / 4**k`` is at least ``box_pixels`` (0 for a box smaller than that, and for
    every box when ``box_pixels`` is 0)."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    if not len(b) or box_pixels <= 0:
        return np.zeros(len(b), dtype=np.intp)
    ratio = np.abs(b[:, 2] * b[:, 3]) / float(box_pixels)
    ratio = np.where(np.isfinite(ratio), np.maximum(ratio, 1.0), 1.0)
    level = np.floor(np.log(ratio) / np.log(4.0) + 1e-9)
    return np.minimum(level, max_level).astype(np.intp)


def pyramid_level(ctx: FrameContext, level: int) -> FrameContext:
    """The frame halved ``level`` times, each pixel the mean of the 2x2 below it
    (``INTER_AREA``), as a :class:`FrameContext` of the same index (no detections, no
    camera motion), each level computed once per frame from the one below and cached in
    ``ctx``; level 0 is ``ctx`` itself."""
    if level <= 0 or ctx.image is None:
        return ctx

    def make() -> FrameContext:
        import cv2  # the modelling core needs OpenCV only here

        below = pyramid_level(ctx, level - 1).image
        h, w = below.shape[:2]
        size = (max(1, w // 2), max(1, h // 2))
        return FrameContext(ctx.index, cv2.resize(below, size, interpolation=cv2.INTER_AREA))

    return ctx.cached(("pyramid", int(level)), make)


def working_frames(ctx: FrameContext, boxes: np.ndarray, levels: np.ndarray
                   ) -> list[tuple[FrameContext, np.ndarray, np.ndarray]]:
    """The boxes grouped by level: ``(the frame at that level, the indices of its boxes,
    those boxes (cx, cy, w, h) in that frame's pixels)`` per level present (one group, the
    frame itself, without an image)."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    if ctx.image is None:
        return [(ctx, np.arange(len(b)), b)]
    h, w = ctx.image.shape[:2]
    out = []
    for level in np.unique(levels):
        idx = np.flatnonzero(levels == level)
        small = pyramid_level(ctx, int(level))
        hs, ws = small.image.shape[:2]
        out.append((small, idx, b[idx] * np.array([ws / w, hs / h, ws / w, hs / h])))
    return out


def appearance_matrix(models: Sequence[Any], boxes: np.ndarray, ctx: FrameContext,
                      box_pixels: float = BOX_PIXELS) -> np.ndarray:
    """``(K, M)`` log-likelihoods of ``M`` boxes ``(cx, cy, w, h)`` (the models' states:
    their ``box_indices`` are the first four) under each of ``K`` models of one cue, each
    box read at its :func:`box_levels` level (see the module's docstring)."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    if not len(models) or not len(b):
        return np.zeros((len(models), len(b)))
    levels = box_levels(b, box_pixels)
    batch = getattr(type(models[0]), "log_likelihood_matrix", None)
    if batch is not None:
        return np.asarray(batch(models, b, ctx, levels), dtype=float).reshape(len(models),
                                                                            len(b))
    out = np.zeros((len(models), len(b)))
    for frame, idx, x in working_frames(ctx, b, levels):
        for i, m in enumerate(models):
            out[i, idx] = np.asarray(m.log_likelihood(x, frame), dtype=float).reshape(len(idx))
    return out


def learn_all(models: Sequence[Any], ctx: FrameContext, boxes: np.ndarray,
              box_pixels: float = BOX_PIXELS) -> None:
    """Each ``models[i]`` learns from frame ``ctx`` at the box ``boxes[i]`` ``(cx, cy, w,
    h)``, read at its :func:`box_levels` level as :func:`appearance_matrix` reads it."""
    b = np.asarray(boxes, dtype=float).reshape(-1, 4)
    if not len(models):
        return
    levels = box_levels(b, box_pixels)
    many = getattr(type(models[0]), "learn_many", None)
    if many is not None:
        many(models, ctx, b, levels)
        return
    for frame, idx, x in working_frames(ctx, b, levels):
        for i, v in zip(idx, x, strict=True):
            models[i].learn(frame, v)
