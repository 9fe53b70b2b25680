"""What a run draws on each frame of its annotated video."""

from __future__ import annotations

import numpy as np

from pgm.core.graph import FactorGraph
from pgm.inference.engine import Engine, StepRecord
from pgm.plotting.annotate import annotate

__all__ = ["annotated_frame", "xy_columns"]


def xy_columns(graph: FactorGraph, variable: str) -> list[int]:
    """Columns of ``variable`` that hold an image position (by its labels)."""
    labels = graph.variables[variable].labels or ()
    for pair in (("cx", "cy"), ("px", "py"), ("x", "y")):
        if all(name in labels for name in pair):
            return [labels.index(pair[0]), labels.index(pair[1])]
    return [0, 1]


def annotated_frame(engine: Engine, record: StepRecord, image: np.ndarray, box: np.ndarray,
                     gt_box: np.ndarray | None, show_particles: bool) -> np.ndarray:
    particles = weights = parts = messages = None
    names = engine.graph.output
    if show_particles:
        particles = {n: record.beliefs[n].x[:, xy_columns(engine.graph, n)] for n in names}
        weights = {n: record.beliefs[n].weights for n in names}
        messages = {f"{s}->{d}": m.x for (s, d), m in record.messages.items()}
    if len(names) > 1:
        parts = {n: record.estimates[n] for n in names}
    ess = "ESS " + "/".join(f"{v:.0f}" for v in record.ess.values())
    return annotate(image, boxes=box[None], ids=[1],
                    gt_boxes=None if gt_box is None else gt_box[None], particles=particles,
                    particle_weights=weights, messages=messages, part_boxes=parts,
                    text=f"{engine.graph.name} frame {record.frame} {ess}")
