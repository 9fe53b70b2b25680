"""What a run of :func:`pgm.app.runner.track` or :func:`~pgm.app.runner.track_multi`
gives back, and how a single-object run reads its box, score and first box
(re-exported by :mod:`pgm.app.runner`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pgm.core.errors import InputError
from pgm.core.graph import FactorGraph
from pgm.core.readout import readout
from pgm.evaluation.calibration import confidence_outcomes, reliability
from pgm.inference.record import StepRecord
from pgm.io.annotations import SingleTrack

__all__ = ["TrackResult", "MultiTrackResult", "output_box", "output_target",
           "init_box_from_gt", "confidence_metrics"]


@dataclass
class TrackResult:
    """What :func:`track` produced.

    Attributes
    ----------
    frames : ndarray (T,)
        1-based frame numbers processed.
    boxes : ndarray (T, 4)
        Estimated top-left ``x, y, w, h`` (0-based) per frame.
    metrics : dict or None
        OTB metrics against the ground truth, when given.
    inference_seconds : float
        Time spent in ``engine.step`` and estimating the camera's motion (decoding,
        drawing and writing excluded).
    out_dir : Path or None
    records : list of StepRecord
        Kept only with ``keep_records=True``.
    scores : ndarray (T,)
        The model's calibrated confidence per frame (the probability that the box
        overlaps the truth by half; :func:`pgm.core.readout.confidence`), 1 for a model
        that declares none.
    wall_seconds : float
        The run end to end: from reading the first frame to the last row and video frame
        written (decoding, camera motion, drawing and encoding included).
    """

    frames: np.ndarray
    boxes: np.ndarray
    metrics: dict[str, Any] | None
    inference_seconds: float
    out_dir: Path | None = None
    records: list[StepRecord] = field(default_factory=list)
    scores: np.ndarray | None = None
    wall_seconds: float = 0.0

    @property
    def fps(self) -> float:
        """Frames per second of inference."""
        return len(self.frames) / self.inference_seconds if self.inference_seconds > 0 else 0.0

    @property
    def end_to_end_fps(self) -> float:
        """Frames per second end to end (:attr:`wall_seconds`): what a user waits."""
        return len(self.frames) / self.wall_seconds if self.wall_seconds > 0 else 0.0


def output_box(graph: FactorGraph, record: StepRecord) -> np.ndarray:
    """The object's top-left ``(x, y, w, h)`` in one step record, from the graph's readout
    (:mod:`pgm.core.readout`; the model config decides what its estimates mean)."""
    return output_target(graph, record)[0]


def output_target(graph: FactorGraph, record: StepRecord) -> tuple[np.ndarray, float]:
    """The object's top-left ``(x, y, w, h)`` and its score (the model's calibrated
    confidence, 1 where it declares none) in one step record."""
    targets = readout(graph, record)
    if len(targets) != 1:
        raise ValueError(f"model {graph.name!r} reported {len(targets)} targets; a "
                         f"single-object run needs exactly one")
    return targets.boxes[0], float(targets.scores[0])


def init_box_from_gt(gt: SingleTrack, first_frame: int = 1) -> np.ndarray:
    """The ground-truth box of ``first_frame`` as ``(cx, cy, w, h)``."""
    hit = np.flatnonzero(gt.frames == first_frame)
    if hit.size == 0:
        raise InputError(f"ground truth has no box for frame {first_frame}: give --init")
    x, y, w, h = gt.boxes[hit[0]]
    return np.array([x + w / 2, y + h / 2, w, h])


def confidence_metrics(metrics: dict[str, Any], frames: np.ndarray,
                       scores: np.ndarray) -> dict[str, Any]:
    """The per-frame confidence and its calibration on the scored frames (outcome: IoU
    at least 0.5), for ``metrics.json``."""
    c, hit = confidence_outcomes(frames, scores, metrics["frames"], metrics["ious"])
    out: dict[str, Any] = {"frames": frames.tolist(), "values": scores.tolist()}
    if c.size:
        out["calibration"] = reliability(c, hit)
    return out


@dataclass
class MultiTrackResult:
    """What :func:`track_multi` produced: the result table, metrics and timings."""

    table: Any
    metrics: dict[str, Any] | None
    inference_seconds: float
    detector_seconds: float
    n_frames: int
    out_dir: Path | None = None
    noise_sigma: list[float] = field(default_factory=list)
    wall_seconds: float = 0.0

    @property
    def fps(self) -> float:
        """Frames per second of inference: ``engine.step`` and the camera's motion
        (detection and decoding excluded)."""
        return self.n_frames / self.inference_seconds if self.inference_seconds > 0 else 0.0

    @property
    def end_to_end_fps(self) -> float:
        """Frames per second end to end: from reading the first frame to the last row and
        video frame written (decoding, detection, drawing and encoding included)."""
        return self.n_frames / self.wall_seconds if self.wall_seconds > 0 else 0.0
