"""What the engine core hands out and takes in: the step record of a frame, the hook
type, and the plate's stages registered by :mod:`pgm.inference.plates` (the core does
not import the rule families above it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pgm.core.frame import FrameContext

__all__ = ["StepRecord", "Hook", "register_plate_runtime"]


@dataclass
class StepRecord:
    """What happened in one frame (for output, inspection and tests).

    Attributes
    ----------
    frame : int
    estimates : dict
        Variable name → estimate (the weighted mean for particle beliefs; ``(K, d)`` for
        a plate variable, one row per replica).
    beliefs : dict
        Variable name → posterior belief after resampling (immutable objects).
    messages : dict
        ``(src, dst)`` → the message of this frame (particle BP), for inspection.
    ess : dict
        ESS after weighting, before resampling (``(K,)`` for a plate variable).
    resampled : dict
        Whether each variable was resampled.
    log_evidence : dict
        ``log p(z_t | z_{1:t-1})`` estimate per weighted variable (the log of the mean
        incremental weight), the particle filter's marginal-likelihood increment.
    info : dict
        Diagnostics returned by rules (messages, VB iterations, ...), keyed by factor
        or variable name.
    """

    frame: int
    estimates: dict[str, Any] = field(default_factory=dict)
    beliefs: dict[str, Any] = field(default_factory=dict)
    ess: dict[str, float] = field(default_factory=dict)
    resampled: dict[str, bool] = field(default_factory=dict)
    log_evidence: dict[str, float] = field(default_factory=dict)
    messages: dict[tuple[str, str], Any] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)


#: a hook: ``hook(engine, stage, frame, record)`` after each stage of a frame
Hook = Callable[[Any, str, FrameContext, StepRecord], None]


#: the plate's stages (:mod:`pgm.inference.plates`, which registers itself: the engine
#: core does not import the rule families above it)
_PLATE_RUNTIME: Any = None


def register_plate_runtime(runtime: Any) -> None:
    """Give the engine the plate's stages (``setup``, ``step``, ``add``, ``remove``,
    ``score_group``, ``learn``, ``associate``): :mod:`pgm.inference.plates` calls it when
    imported."""
    global _PLATE_RUNTIME
    _PLATE_RUNTIME = runtime


def _plate_runtime() -> Any:
    if _PLATE_RUNTIME is None:  # pragma: no cover - pgm.inference imports the plates
        raise RuntimeError("no plate runtime registered: import pgm.inference")
    return _PLATE_RUNTIME
