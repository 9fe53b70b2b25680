"""The detections of one frame and the source that yields them, frame by frame: the types
every detector builds on (:mod:`pgm.observation.detections` for the toolkit's detectors
and their spec strings, :mod:`pgm.observation.hog` for OpenCV's HOG people detector)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.errors import InputError

__all__ = ["Detections", "DetectionSource"]


# --------------------------------------------------------------------------- container


def _readonly(a: np.ndarray) -> np.ndarray:
    """``a`` made read-only; a writeable array is copied first (the caller keeps its own)."""
    if a.flags.writeable:
        a = a.copy()
        a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Detections:
    """The detections of one frame.

    Attributes
    ----------
    boxes : ndarray of float, shape (M, 4)
        Top-left ``(x, y, w, h)`` in 0-based pixel coordinates, ``w, h > 0``
        (read-only). ``M`` may be 0: the shape is then ``(0, 4)``.
    scores : ndarray of float, shape (M,)
        One score per box, in the source's own units (see the module docstring).
    """

    boxes: np.ndarray
    scores: np.ndarray

    def __post_init__(self) -> None:
        boxes = np.asarray(self.boxes, dtype=float).reshape(-1, 4)
        scores = np.asarray(self.scores, dtype=float).reshape(-1)
        if scores.shape[0] != boxes.shape[0]:
            raise ValueError(f"{boxes.shape[0]} boxes but {scores.shape[0]} scores")
        if not np.all(np.isfinite(scores)):
            raise InputError("detection scores must be finite (a NaN or infinite score is "
                             "never read as 1)")
        object.__setattr__(self, "boxes", _readonly(boxes))
        object.__setattr__(self, "scores", _readonly(scores))

    @classmethod
    def empty(cls) -> Detections:
        """No detection: ``boxes`` of shape ``(0, 4)``, ``scores`` of shape ``(0,)``."""
        return cls(np.zeros((0, 4)), np.zeros(0))

    def __len__(self) -> int:
        return int(self.boxes.shape[0])

    @property
    def foot_points(self) -> np.ndarray:
        """Bottom-centre points ``(x + w/2, y + h)``, shape ``(M, 2)``: where a
        pedestrian touches the ground, the usual point measurement."""
        b = self.boxes
        return np.stack([b[:, 0] + b[:, 2] / 2.0, b[:, 1] + b[:, 3]], axis=1)

    @property
    def centres(self) -> np.ndarray:
        """Box centres ``(x + w/2, y + h/2)``, shape ``(M, 2)``."""
        b = self.boxes
        return b[:, :2] + b[:, 2:4] / 2.0

    def select(self, keep: Any) -> Detections:
        """The detections picked by a boolean mask or an index array."""
        return Detections(self.boxes[keep], self.scores[keep])

    def __repr__(self) -> str:
        return f"Detections(M={len(self)})"


# --------------------------------------------------------------------------- sources


class DetectionSource(ABC):
    """Something that turns one frame into :class:`Detections`.

    Call it once per frame, in frame order: ``dets = source(frame_number, image)``.
    ``frame_number`` is 1-based (as yielded by :meth:`pgm.io.video.FrameSource.frames`);
    file-based sources ignore ``image`` (``None`` is accepted), image-based ones need it.

    Attributes
    ----------
    name : str
        Short description, e.g. ``'public'``, ``'public:30'``, ``'mog2'``.
    """

    name: str = "detections"

    @abstractmethod
    def __call__(self, frame_number: int, image: np.ndarray | None) -> Detections:
        """This frame's detections."""

    def reset(self) -> None:  # noqa: B027 - optional: stateless sources keep it empty
        """Forget any state carried between frames (a no-op for stateless sources)."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r})"
