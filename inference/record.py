"""What the engine core hands out and takes in: the step record of a frame, the hook
type, and the runtimes registered for graphs the core does not run by itself (a plate's,
by :mod:`pgm.inference.plates`: the core does not import the rule families above it).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pgm.core.frame import FrameContext

from .info import Info, PlateInfo, VariableInfo

__all__ = ["StepRecord", "Hook", "register_runtime", "runtime_for"]


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
        Diagnostics the rules report, typed (:mod:`pgm.inference.info`): per variable
        name a :class:`~pgm.inference.info.VariableInfo`, per factor name what its rule
        returned (:class:`~pgm.inference.info.VBInfo`, ...; ``{(src, dst): ...}`` for a
        message rule that reports).
    plate : PlateInfo or None
        A plate's own report (identities, boxes, births, deaths): None without a plate.
    """

    frame: int
    estimates: dict[str, Any] = field(default_factory=dict)
    beliefs: dict[str, Any] = field(default_factory=dict)
    ess: dict[str, float] = field(default_factory=dict)
    resampled: dict[str, bool] = field(default_factory=dict)
    log_evidence: dict[str, float] = field(default_factory=dict)
    messages: dict[tuple[str, str], Any] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)
    plate: PlateInfo | None = None

    def variable_info(self, variable: str) -> VariableInfo:
        """The variable's :class:`~pgm.inference.info.VariableInfo`, made at the first
        call (the stages that report on a variable add to it)."""
        info = self.info.get(variable)
        if info is None:
            info = self.info[variable] = VariableInfo()
        return info

    def plate_info(self) -> PlateInfo:
        """:attr:`plate`, made at the first call."""
        if self.plate is None:
            self.plate = PlateInfo()
        return self.plate

    def report(self, variable: str, info: Info | dict | None) -> None:
        """Add what a stage returned on ``variable`` to its :meth:`variable_info`."""
        if info:
            self.variable_info(variable).merge(info)


#: a hook: ``hook(engine, stage, frame, record)`` after each stage of a frame
Hook = Callable[[Any, str, FrameContext, StepRecord], None]


#: runtimes for graphs the engine core does not run by itself, as ``(applies, runtime)``:
#: :mod:`pgm.inference.plates` registers the plate's (the engine core does not import the
#: rule families above it); a graph no runtime applies to runs as one graph
_RUNTIMES: list[tuple[Callable[[Any], bool], Any]] = []


def register_runtime(applies: Callable[[Any], bool], runtime: Any) -> None:
    """Run the graphs for which ``applies(graph)`` holds with ``runtime`` (an object with
    the methods of :class:`pgm.inference.engine.SingleGraph`); a later registration is
    asked first."""
    _RUNTIMES.insert(0, (applies, runtime))


def runtime_for(graph: Any) -> Any | None:
    """The registered runtime that runs ``graph``, or None (the engine's own)."""
    for applies, runtime in _RUNTIMES:
        if applies(graph):
            return runtime
    return None
