"""A rendered synthetic sequence: frames, exact ground truth, detections, and writers to
the OTB and MOTChallenge layouts (through :mod:`pgm.io`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numpy as np

from pgm.core.errors import InputError
from pgm.core.rng import as_generator
from pgm.io.track_files import MotWriter, write_otb_groundtruth
from pgm.io.video import write_image_sequence, write_seqinfo
from pgm.synthetic._checks import _nonneg

__all__ = ["SyntheticSequence", "ObjectTruth", "SceneGeometry"]


class SceneGeometry(Protocol):
    """What a sequence reads of the scene that rendered it
    (:class:`pgm.synthetic.scene.Scene`; a protocol here, so that this module sits below
    the scene's and neither imports the other's)."""

    width: int
    height: int

    def _check_obj(self, obj_index: int) -> None: ...

    def band_visibility(self, obj_index: int, frame: int, n_bands: int) -> np.ndarray: ...


@dataclass(eq=False)
class ObjectTruth:
    """Ground truth of one object over the frames where it is in the image.

    ``frames`` (K,) 1-based frame numbers where the object exists and its box overlaps
    the image; ``boxes`` (K, 4) top-left ``(x, y, w, h)`` 0-based (not clipped to the
    image); ``visibility`` (K,) visible fraction of the box; ``id`` the 1-based MOT id.
    """

    id: int
    frames: np.ndarray
    boxes: np.ndarray
    visibility: np.ndarray




@dataclass(eq=False)
class SyntheticSequence:
    """Rendered frames with exact ground truth.

    Attributes
    ----------
    frames : list of ndarray (H, W, 3) uint8 BGR
        ``frames[f - 1]`` is frame ``f``.
    gt : list of ObjectTruth
        One per scene object, in scene order (``gt[k].id == k + 1``).
    visibility : ndarray (n_objects, n_frames)
        Visible fraction of each object's box (0 where absent).
    fps : float
    scene : SceneGeometry
        The scene that rendered it (a :class:`pgm.synthetic.scene.Scene`): the geometry, for
        :meth:`band_visibility` and friends.
    name : str
    """

    frames: list[np.ndarray]
    gt: list[ObjectTruth]
    visibility: np.ndarray
    fps: float
    scene: SceneGeometry
    name: str = "synthetic"
    _band_cache: dict[tuple[int, int], np.ndarray] = field(default_factory=dict, repr=False,
                                                           init=False)

    def __len__(self) -> int:
        return len(self.frames)

    @property
    def n_frames(self) -> int:
        return len(self.frames)

    @property
    def n_objects(self) -> int:
        return len(self.gt)

    @property
    def width(self) -> int:
        return self.scene.width

    @property
    def height(self) -> int:
        return self.scene.height

    def box(self, obj_index: int, frame: int) -> np.ndarray | None:
        """Ground-truth top-left box of an object at a 1-based frame, or None."""
        self.scene._check_obj(obj_index)
        t = self.gt[int(obj_index)]
        hit = np.flatnonzero(t.frames == frame)
        return t.boxes[hit[0]].copy() if hit.size else None

    def boxes_at(self, frame: int) -> tuple[np.ndarray, np.ndarray]:
        """``(ids (M,), boxes (M, 4))`` of the objects in the image at ``frame``."""
        ids, boxes = [], []
        for t in self.gt:
            hit = np.flatnonzero(t.frames == frame)
            if hit.size:
                ids.append(t.id)
                boxes.append(t.boxes[hit[0]])
        return np.array(ids, dtype=int), np.array(boxes, dtype=float).reshape(-1, 4)

    def band_visibility(self, obj_index: int, n_bands: int) -> np.ndarray:
        """Visible fraction ``(n_frames, n_bands)`` of each horizontal band (top first)
        of an object's box per frame (zeros where the object is absent)."""
        key = (int(obj_index), int(n_bands))
        if key not in self._band_cache:
            self._band_cache[key] = np.stack([
                self.scene.band_visibility(obj_index, f, n_bands)
                for f in range(1, self.n_frames + 1)])
        return self._band_cache[key].copy()

    def detections(self, rng: np.random.Generator | int, *, p_detect: float = 0.9,
                   sigma: float = 2.0, clutter_rate: float = 1.0,
                   min_visibility: float = 0.3) -> np.ndarray:
        """Noisy detections ``(N, 7)``: ``frame, x, y, w, h, score, id`` (0-based boxes;
        ``id`` is the true object id or -1 for clutter), sorted by frame.

        Each object whose visible fraction is at least ``min_visibility`` is detected
        with probability ``p_detect``; its box gets independent Gaussian noise of
        standard deviation ``sigma`` pixels on x, y, w, h (w, h kept >= 2) and a score
        in [0.5, 1). Each frame also gets Poisson(``clutter_rate``) clutter boxes, placed
        uniformly inside the image with sizes like the objects', scores in [0, 0.6).
        """
        rng = as_generator(rng)
        if not 0.0 <= p_detect <= 1.0:
            raise InputError(f"p_detect must be in [0, 1], got {p_detect!r}")
        sigma = _nonneg("sigma", sigma)
        clutter_rate = _nonneg("clutter_rate", clutter_rate)
        sizes = np.concatenate([t.boxes[:, 2:] for t in self.gt])
        if sizes.size == 0:
            sizes = np.array([[0.1 * self.width, 0.2 * self.height]])
        rows: list[list[float]] = []
        for f in range(1, self.n_frames + 1):
            ids, boxes = self.boxes_at(f)
            for i, b in zip(ids, boxes, strict=True):
                if self.visibility[i - 1, f - 1] < min_visibility:
                    continue
                if rng.random() >= p_detect:
                    continue
                nb = b + sigma * rng.standard_normal(4)
                nb[2:] = np.maximum(nb[2:], 2.0)
                rows.append([f, *nb, rng.uniform(0.5, 1.0), i])
            for _ in range(int(rng.poisson(clutter_rate))):
                w, h = sizes[rng.integers(len(sizes))] * rng.uniform(0.8, 1.2)
                w, h = min(w, self.width), min(h, self.height)
                x = rng.uniform(0.0, self.width - w)
                y = rng.uniform(0.0, self.height - h)
                rows.append([f, x, y, w, h, rng.uniform(0.0, 0.6), -1])
        return np.array(rows, dtype=float).reshape(-1, 7)

    def write_otb(self, folder: str | Path, obj_index: int = 0) -> Path:
        """Write an OTB layout: ``img/%04d.png`` and ``groundtruth_rect.txt`` (one
        ``x,y,w,h`` line per frame, 1-based top-left; ``NaN,NaN,NaN,NaN`` where the
        object is not in the image). Returns the folder."""
        self.scene._check_obj(obj_index)
        folder = Path(folder)
        write_image_sequence(folder / "img", self.frames, "{:04d}.png")
        boxes = [self.box(obj_index, f) for f in range(1, self.n_frames + 1)]
        write_otb_groundtruth(folder / "groundtruth_rect.txt",
                              np.array([np.full(4, np.nan) if b is None else b for b in boxes]))
        return folder

    def write_mot(self, folder: str | Path, rng: np.random.Generator | int = 0, *,
                  p_detect: float = 0.9, sigma: float = 2.0, clutter_rate: float = 1.0,
                  min_visibility: float = 0.3) -> Path:
        """Write a MOTChallenge layout: ``seqinfo.ini``, ``img1/%06d.png``,
        ``gt/gt.txt`` (``frame,id,x,y,w,h,1,-1,-1,-1``, 1-based, every frame an object
        is in the image) and ``det/det.txt`` (``frame,-1,x,y,w,h,score,-1,-1,-1``) from
        :meth:`detections` with ``rng``. Returns the folder."""
        folder = Path(folder)
        dets = self.detections(rng, p_detect=p_detect, sigma=sigma,
                               clutter_rate=clutter_rate, min_visibility=min_visibility)
        write_seqinfo(folder, name=self.name, fps=self.fps, length=self.n_frames,
                      width=self.width, height=self.height)
        write_image_sequence(folder / "img1", self.frames)
        gt_rows = sorted(((int(f), t.id, b) for t in self.gt
                          for f, b in zip(t.frames, t.boxes, strict=True)),
                         key=lambda r: (r[0], r[1]))
        with MotWriter(folder / "gt" / "gt.txt", decimals=6) as w:
            w.write_rows(np.array([r[0] for r in gt_rows], dtype=int),
                         np.array([r[1] for r in gt_rows], dtype=int),
                         np.array([r[2] for r in gt_rows]).reshape(-1, 4))
        with MotWriter(folder / "det" / "det.txt", decimals=6) as w:
            w.write_rows(dets[:, 0].astype(int), np.full(len(dets), -1), dets[:, 1:5],
                         dets[:, 5])
        return folder


