"""What a run draws on each frame of its annotated video."""

from __future__ import annotations

import numpy as np

from pgm.core.graph import FactorGraph
from pgm.inference.engine import Engine, StepRecord
from pgm.plotting.annotate import annotate

__all__ = ["annotated_frame", "xy_columns", "Trails", "frame_caption"]


def xy_columns(graph: FactorGraph, variable: str) -> list[int]:
    """Columns of ``variable`` that hold an image position (by its labels)."""
    labels = graph.variables[variable].labels or ()
    for pair in (("cx", "cy"), ("px", "py"), ("x", "y")):
        if all(name in labels for name in pair):
            return [labels.index(pair[0]), labels.index(pair[1])]
    return [0, 1]


class Trails:
    """Each identity's last ``length`` box centres, for :func:`~pgm.plotting.annotate.
    annotate`'s ``trails`` (0: none). An identity not reported for ``length`` frames is
    forgotten."""

    def __init__(self, length: int = 0):
        if isinstance(length, bool) or int(length) != length or length < 0:
            raise ValueError(f"trails must be a number of frames >= 0, got {length!r}")
        self.length = int(length)
        self._points: dict[int, list[tuple[int, np.ndarray]]] = {}
        self._frame = 0

    def update(self, ids, boxes) -> dict[int, np.ndarray] | None:
        """Add this frame's top-left ``x, y, w, h`` boxes; the trails to draw now."""
        if self.length == 0:
            return None
        self._frame += 1
        for i, b in zip(ids, np.asarray(boxes, dtype=float).reshape(-1, 4), strict=True):
            self._points.setdefault(int(i), []).append((self._frame, b[:2] + b[2:] / 2))
        for i in list(self._points):
            kept = [p for p in self._points[i] if p[0] > self._frame - self.length]
            if kept:
                self._points[i] = kept
            else:
                del self._points[i]
        return {i: np.array([c for _, c in pts]) for i, pts in self._points.items()}


def frame_caption(model: str, frame: int, words: str = "") -> str:
    """The video's header in plain words: the model, the frame and what it shows."""
    return "  ".join(part for part in (model, f"frame {frame}", words) if part)


def annotated_frame(engine: Engine, record: StepRecord, image: np.ndarray, box: np.ndarray,
                     gt_box: np.ndarray | None, show_particles: bool, score: float | None = None,
                     trails: Trails | None = None) -> np.ndarray:
    """One frame of a single-object run's video: the box (its trail), the ground truth,
    a legend, and a header with the model, the frame and the calibrated confidence
    (``score``, where the model declares one); particles, message particles and the
    effective sample sizes only with ``show_particles``."""
    particles = weights = parts = messages = None
    names = engine.graph.output
    words = "" if score is None else f"confidence {score:.2f}"
    if show_particles:
        particles = {n: record.beliefs[n].x[:, xy_columns(engine.graph, n)] for n in names}
        weights = {n: record.beliefs[n].weights for n in names}
        messages = {f"{s}->{d}": m.x for (s, d), m in record.messages.items()}
        words += "  ESS " + "/".join(f"{v:.0f}" for v in record.ess.values())
    if len(names) > 1:
        parts = {n: record.estimates[n] for n in names}
    return annotate(image, boxes=box[None], ids=[1],
                    gt_boxes=None if gt_box is None else gt_box[None], particles=particles,
                    particle_weights=weights, messages=messages, part_boxes=parts,
                    text=frame_caption(engine.graph.name, record.frame, words.strip()),
                    trails=None if trails is None else trails.update([1], box[None]),
                    legend=True)
