"""Readouts: what a tracker reports in one frame, read off the engine's step record.

A model config knows what its estimates mean — a part graph's object box is the mean
of the boxes its parts imply, a PHD filter's state is a foot point whose box size comes
from the associated detections. It says so by naming a *readout* in
``graph.meta["readout"]`` and registering the function under that name with
:func:`register_readout`. A saved graph stores only the name, so loading it stays a
lookup (as for factor types), and the runners in :mod:`pgm.app` never encode a model's
conventions.

A readout is ``fn(graph, record) -> Targets``; ``record`` is the engine's
:class:`~pgm.inference.StepRecord` (only its ``estimates`` are read by the readouts
here). Graphs that name none use ``"box"``: the first output variable's estimate is
``(cx, cy, w, h)``, one target with identity 1.

A single-object model may also declare a *calibrated confidence* in
``graph.meta["confidence"] = {"factor": NAME, "intercept": a, "slope": b,
"spread_slope": c}``: the named factor's ``confidence_feature`` ``r`` (a number it
computes about its last frame, e.g. the log peak-to-sidelobe ratio of the correlation
filter's response map at the estimate) and the posterior's spread ``s`` (:func:`posterior_spread`:
the particles' weighted centre standard deviation over the estimate's size) mapped
through the logistic ``1 / (1 + exp(-(a + b r + c log s)))``, fitted so that it is the
probability that the box overlaps the truth by at least half (see
``benchmarks/confidence.py``). The ``"box"`` readout reports it as the target's score.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.boxes import cxcywh_to_xywh

__all__ = ["Targets", "register_readout", "get_readout", "readout", "DEFAULT_READOUT",
           "cxcywh_target", "box_readout", "confidence", "check_confidence_spec",
           "posterior_spread"]

DEFAULT_READOUT = "box"


@dataclass(frozen=True)
class Targets:
    """Targets reported in one frame.

    Attributes
    ----------
    ids : ndarray, shape (K,)
        Identities (int).
    boxes : ndarray, shape (K, 4)
        Top-left ``x, y`` and size ``w, h`` in pixels (0-based).
    scores : ndarray, shape (K,)
        Confidence of each target (1 for a single-object tracker).
    text : str
        A short summary for annotated frames (e.g. the expected target count).
    frames : ndarray, shape (K,), optional
        The frame of each row, for rows of earlier frames (``filled``); None: this frame.
    filled : Targets, optional
        Rows of earlier frames the tracker reports now, each with its ``frames`` (a track
        found again after a short gap, :attr:`~pgm.core.plate.Lifecycle.fill_gaps`): a
        track file gets them as rows of those frames; what was drawn stays as it was.
    """

    ids: np.ndarray
    boxes: np.ndarray
    scores: np.ndarray
    text: str = ""
    frames: np.ndarray | None = None
    filled: Targets | None = None

    def __post_init__(self) -> None:
        ids = np.asarray(self.ids, dtype=np.int64).reshape(-1)
        boxes = np.asarray(self.boxes, dtype=float).reshape(-1, 4)
        scores = np.asarray(self.scores, dtype=float).reshape(-1)
        if not ids.shape[0] == boxes.shape[0] == scores.shape[0]:
            raise ValueError(f"Targets: {ids.shape[0]} ids, {boxes.shape[0]} boxes and "
                             f"{scores.shape[0]} scores")
        object.__setattr__(self, "ids", ids)
        object.__setattr__(self, "boxes", boxes)
        object.__setattr__(self, "scores", scores)
        if self.frames is not None:
            frames = np.asarray(self.frames, dtype=np.int64).reshape(-1)
            if frames.shape[0] != ids.shape[0]:
                raise ValueError(f"Targets: {ids.shape[0]} ids and {frames.shape[0]} frames")
            object.__setattr__(self, "frames", frames)

    def __len__(self) -> int:
        return int(self.ids.shape[0])

    def rows(self, frame: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Every row this report gives a track file, as arrays ``(frames, ids, boxes,
        scores)``: the targets of ``frame``, then the :attr:`filled` rows of earlier
        frames."""
        own = np.full(len(self), int(frame), dtype=np.int64)
        if self.filled is None or not len(self.filled):
            return own, self.ids, self.boxes, self.scores
        late = self.filled
        return (np.concatenate([own, late.frames]), np.concatenate([self.ids, late.ids]),
                np.concatenate([self.boxes, late.boxes]),
                np.concatenate([self.scores, late.scores]))


Readout = Callable[[Any, Any], Targets]
_READOUTS: dict[str, Readout] = {}


def register_readout(name: str) -> Callable[[Readout], Readout]:
    """Decorator registering a readout under ``name`` (what ``meta["readout"]`` names)."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"a readout name must be a non-empty string, got {name!r}")

    def deco(fn: Readout) -> Readout:
        other = _READOUTS.get(name)
        if other is not None and other.__module__ != fn.__module__:
            raise ValueError(f"readout {name!r} is registered twice ({other.__module__} and "
                             f"{fn.__module__})")
        _READOUTS[name] = fn
        return fn

    return deco


def get_readout(name: str) -> Readout:
    """The readout registered as ``name`` (the models are imported to find it if needed)."""
    if name not in _READOUTS:
        from pgm.core.factor import find_names

        find_names(lambda: name in _READOUTS)
    try:
        return _READOUTS[name]
    except KeyError:
        raise ValueError(f"unknown readout {name!r}: import the model module that registers "
                         f"it (known: {sorted(_READOUTS)})") from None


def readout(graph, record) -> Targets:
    """The targets ``graph``'s readout reports for one step record."""
    return get_readout(graph.meta.get("readout", DEFAULT_READOUT))(graph, record)


def cxcywh_target(box: Any, score: float = 1.0) -> Targets:
    """One target (identity 1) from a ``(cx, cy, w, h)`` box."""
    return Targets(np.array([1]), cxcywh_to_xywh(np.asarray(box, dtype=float)[:4])[None],
                   np.array([float(score)]))


_SPEC_KEYS = {"factor", "intercept", "slope", "spread_slope", "response_slope"}


def check_confidence_spec(spec: Any, factors: dict) -> dict:
    """Validate a ``meta["confidence"]`` declaration against the graph's factors."""
    if (not isinstance(spec, dict) or not {"factor", "intercept", "slope"} <= set(spec)
            or not set(spec) <= _SPEC_KEYS):
        raise ValueError(f"meta['confidence'] must have keys factor, intercept, slope (and "
                         f"optionally spread_slope, response_slope), got {spec!r}")
    if spec["factor"] not in factors:
        raise ValueError(f"meta['confidence'] names factor {spec['factor']!r}, which the graph "
                         f"does not have")
    for k in ("intercept", "slope", "spread_slope", "response_slope"):
        v = spec.get(k, 0.0)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
            raise ValueError(f"meta['confidence'][{k!r}] must be a finite number, got {v!r}")
    return spec


def posterior_spread(record, variable: str) -> float:
    """Weighted standard deviation of the particles' centres (columns 0 and 1, the box
    layout ``(cx, cy, w, h)``) over the estimate's size ``sqrt(w h)``."""
    belief = record.beliefs[variable]
    x, w = belief.x, belief.weights
    est = np.asarray(record.estimates[variable], dtype=float)
    c = w @ x[:, :2]
    var = float(w @ np.sum((x[:, :2] - c) ** 2, axis=1))
    return float(np.sqrt(var) / max(np.sqrt(abs(est[2] * est[3])), 1e-9))


def confidence(graph, record=None) -> float | None:
    """The graph's calibrated confidence for its last step, or None where it declares
    none (or its factor has not scored a frame yet): the logistic of ``intercept +
    slope × feature + spread_slope × log spread + response_slope × response``, with the
    factor's ``confidence_feature`` (and ``confidence_response``) and the posterior's
    spread (:func:`posterior_spread`). ``record`` (the step's record) is needed where
    the declaration has a ``spread_slope``."""
    spec = graph.meta.get("confidence")
    if spec is None:
        return None
    check_confidence_spec(spec, graph.factors)
    feature = getattr(graph.factors[spec["factor"]], "confidence_feature", None)
    if feature is None or not np.isfinite(feature):
        return None
    z = float(spec["intercept"]) + float(spec["slope"]) * float(feature)
    c = float(spec.get("spread_slope", 0.0))
    if c != 0.0:
        if record is None:
            raise ValueError("this confidence needs the step record (posterior spread)")
        z += c * np.log(max(posterior_spread(record, graph.output[0]), 1e-6))
    d = float(spec.get("response_slope", 0.0))
    if d != 0.0:
        response = getattr(graph.factors[spec["factor"]], "confidence_response", None)
        if response is None or not np.isfinite(response):
            return None
        z += d * float(response)
    return float(0.5 * (1.0 + np.tanh(0.5 * z)))  # the logistic, overflow-free


@register_readout(DEFAULT_READOUT)
def box_readout(graph, record) -> Targets:
    """The first output variable's estimate read as the object's ``(cx, cy, w, h)``; its
    score is the graph's calibrated :func:`confidence` (1 where it declares none)."""
    c = confidence(graph, record)
    return cxcywh_target(record.estimates[graph.output[0]], 1.0 if c is None else c)
