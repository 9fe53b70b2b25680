"""The correlation filter's learned context (``context_rate``): which cells of its window
move with the object, learned from the object's motion on a still camera, and the check
that drops it for good once the camera moves (:class:`~pgm.observation.appearance.
correlation.CorrelationFilterLikelihood`)."""

from __future__ import annotations

import cv2
import numpy as np
import scipy.fft as sfft

from pgm.core.frame import FrameContext

__all__ = ["LearnedContext"]


class LearnedContext:
    """The learned context and the still-camera check of
    :class:`~pgm.observation.appearance.correlation.CorrelationFilterLikelihood` (a mixin:
    it reads and sets that class's attributes)."""

    def _check_camera(self, frame: FrameContext) -> None:
        """Once per frame, before the frame's response is read (and at the latest in
        :meth:`update`): on a moving camera the background moves in the image, and "did
        this cell stay where it was?" no longer tells it from the object, so the context
        is dropped for good."""
        if (self._camera is not None and frame.index != self._checked_index
                and self._camera_moved(frame)):
            self.context = self._camera = self._first_frames = self._mask_cache = None
            self.camera_moved_at = frame.index

    def _camera_moved(self, frame: FrameContext) -> bool:
        """Is the camera moving? The still-camera check's verdict (``auto``: 16 of the
        last 20 frames moved by a pixel or more); until it can have one (the first 20
        frames), each frame is checked on its own and one that moved is enough."""
        self._checked_index = frame.index
        image = frame.image
        if self._camera(image) is not None:
            return True
        if self._first_frames is None:
            return False
        w, h = image.shape[1], image.shape[0]
        a = self._first_frames(image)
        self._checked += 1
        if self._checked >= self._camera.window:
            self._first_frames = None
        return a is not None and self._camera.corner_shift(a, w, h) >= self._camera.min_shift

    def _learn_context(self, frame: FrameContext, feats: np.ndarray, centre, scale: float,
                       angle: float, obj: np.ndarray) -> None:
        """Which cells of the window move with the object (the class docstring,
        ``context_rate``): compared with the last learned frame's window, does a cell's
        content now sit at the object's new place or where the window was? ``obj`` is
        this frame's response of the filter's box cells alone at the estimate, whose
        peak places the object when the estimate did not move."""
        seen, c0, s0, a0 = self._last_seen
        step = self.ref_size * s0 / np.array(self.shape, float)  # image px per cell
        here = np.asarray(centre, float)
        if np.hypot(*((here - c0) / step)) >= 1.0:
            new = feats  # the estimate followed the object
        else:  # the estimate stayed: the box's own cells place the object in the window
            th, tw = obj.shape
            iy, ix = np.unravel_index(int(np.argmax(obj)), obj.shape)
            d = np.array([ix - (tw - 1) / 2, iy - (th - 1) / 2]) + (here - c0) / step
            if np.hypot(*d) < 1.0:
                return  # no move seen: the two places cannot be told apart
            c, s = np.cos(a0), np.sin(a0)
            off = np.array([c * d[0] * step[0] - s * d[1] * step[1],
                            s * d[0] * step[0] + c * d[1] * step[1]])
            new = self._features(frame, c0 + off, s0, a0)
        still = self._features(frame, c0, s0, a0)  # this frame where the window was
        moved = cv2.boxFilter(np.sum((new - seen) ** 2, axis=0), -1, (3, 3))
        stayed = cv2.boxFilter(np.sum((still - seen) ** 2, axis=0), -1, (3, 3))
        typical = float(np.median(np.minimum(moved, stayed))) + 1e-12
        odds = np.clip((stayed - moved) / typical, -4.0, 4.0)
        if float(odds[self.box_cells].mean()) <= 0.0:
            return  # the box's own content does not bear the move out
        r = self.context_rate
        self.context = (1 - r) * self.context + r / (1.0 + np.exp(-odds))
        self.context[self.box_cells] = 1.0  # the box is the object's, by definition
        self._mask_cache = None
        self._last_seen = (feats, here.copy(), scale, angle)

    def _object_response(self, xf: np.ndarray) -> np.ndarray:
        """The response map of the filter's cells over the object's box alone, on the
        window of spectrum ``xf`` (the context's cells left out)."""
        hf = self._weighted_filter(self.box_cells)
        return sfft.irfft2(np.sum(hf * xf, axis=0), s=self.hann.shape)

    def _centre_max(self, r: np.ndarray) -> float:
        """The best response within a tenth of the target of the window centre (where the
        estimate sits; it is a particle mean, not the peak)."""
        th, tw = r.shape
        rad = max(1, int(round(0.1 * self.target_px)))
        cy, cx = (th - 1) / 2, (tw - 1) / 2
        y0, y1 = int(np.floor(cy)) - rad, int(np.ceil(cy)) + rad + 1
        x0, x1 = int(np.floor(cx)) - rad, int(np.ceil(cx)) + rad + 1
        return float(r[max(y0, 0):y1, max(x0, 0):x1].max())
