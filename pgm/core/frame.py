"""What the engine hands to likelihood factors for one frame.

A :class:`FrameContext` carries the image (and, for multi-target models, the
measurements) of one frame plus a cache, so that per-frame work — colour
quantisation, integral images, gradients — is computed once per frame and shared by
every factor that scores that frame::

    bins = ctx.cached(("hsv-bins", "perez", 16, 4, 16), lambda: quantize(ctx.image))
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import Any

import numpy as np

__all__ = ["FrameContext"]


class FrameContext:
    """One frame's evidence.

    Parameters
    ----------
    index : int
        Frame number, 1-based, in the source's order.
    image : ndarray, shape (H, W, 3), uint8, BGR, or None
        The frame (greyscale sources are delivered as three equal channels).
    measurements : ndarray, shape (M, k), or dict, optional
        Point measurements (for set-valued variables), or per-variable measurements.
    detections : object, optional
        Detector output for the frame (``pgm.observation.detections.Detections``: boxes, scores,
        foot points); measurement factors read their points from it when
        ``measurements`` is not given, and track layers take box sizes from it.
    camera_motion : ndarray, shape (2, 3), optional
        The camera's image motion since the previous frame: the affine map ``[M | t]``
        taking a pixel of the previous frame to this one (``None``: a still camera).
        Transition rules move every target's past states through it before predicting
        (:func:`pgm.core.motion.warp_states`).
    """

    __slots__ = ("index", "image", "measurements", "detections", "camera_motion", "_cache")

    def __init__(self, index: int, image: np.ndarray | None = None,
                 measurements: np.ndarray | None = None, detections=None,
                 camera_motion: np.ndarray | None = None):
        self.index = int(index)
        self.image = image
        self.measurements = measurements
        self.detections = detections
        if camera_motion is not None:
            camera_motion = np.asarray(camera_motion, dtype=float)
            if camera_motion.shape != (2, 3) or not np.all(np.isfinite(camera_motion)):
                raise ValueError(f"frame {self.index}: camera_motion must be a finite 2x3 "
                                 f"affine matrix, got shape {camera_motion.shape}")
        self.camera_motion = camera_motion
        self._cache: dict[Hashable, Any] = {}

    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)`` of the image."""
        if self.image is None:
            raise ValueError(f"frame {self.index} has no image")
        return int(self.image.shape[0]), int(self.image.shape[1])

    def cached(self, key: Hashable, compute: Callable[[], Any]) -> Any:
        """Return ``compute()``, computed at most once per frame for ``key``."""
        try:
            return self._cache[key]
        except KeyError:
            value = compute()
            self._cache[key] = value
            return value

    def __repr__(self) -> str:
        shape = None if self.image is None else self.image.shape
        return f"FrameContext(index={self.index}, image={shape})"
