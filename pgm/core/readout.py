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
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.boxes import cxcywh_to_xywh

__all__ = ["Targets", "register_readout", "get_readout", "readout", "DEFAULT_READOUT",
           "cxcywh_target", "box_readout"]

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
    """

    ids: np.ndarray
    boxes: np.ndarray
    scores: np.ndarray
    text: str = ""

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

    def __len__(self) -> int:
        return int(self.ids.shape[0])


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
    """The readout registered as ``name``."""
    try:
        return _READOUTS[name]
    except KeyError:
        raise ValueError(f"unknown readout {name!r}: import the model module that registers "
                         f"it (known: {sorted(_READOUTS)})") from None


def readout(graph, record) -> Targets:
    """The targets ``graph``'s readout reports for one step record."""
    return get_readout(graph.meta.get("readout", DEFAULT_READOUT))(graph, record)


def cxcywh_target(box: Any) -> Targets:
    """One target (identity 1, score 1) from a ``(cx, cy, w, h)`` box."""
    return Targets(np.array([1]), cxcywh_to_xywh(np.asarray(box, dtype=float)[:4])[None],
                   np.ones(1))


@register_readout(DEFAULT_READOUT)
def box_readout(graph, record) -> Targets:
    """The first output variable's estimate read as the object's ``(cx, cy, w, h)``."""
    return cxcywh_target(record.estimates[graph.output[0]])
