"""How the engine runs a graph without a plate (:class:`SingleGraph`): the one runtime the
engine core holds itself. A runtime is what differs between one graph and a plate of its
replicas; the plate's (:class:`pgm.inference.plates.PlateRuntime`) registers itself with
:func:`pgm.inference.record.register_runtime`. A runtime's methods that act on the rules'
state take the :class:`~pgm.inference.context.RuleContext` they run on (a plate's
newborns run on their own), the others the :class:`~pgm.inference.engine.Engine` they
serve (typed ``Any``: the engine imports this module, not the other way)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from pgm.core.factor import Factor
from pgm.core.frame import FrameContext
from pgm.core.graph import FactorGraph
from pgm.core.readout import confidence

from .context import RuleContext
from .record import StepRecord
from .state import StateSlots

__all__ = ["SingleGraph", "SINGLE_GRAPH"]


class SingleGraph:
    """How the engine runs a graph without a plate: the schedule on the graph's own
    beliefs, learning factors updated on the graph itself.

    A *runtime* is what differs between a single graph and a plate of replicas (the
    plate's is :class:`pgm.inference.plates.PlateRuntime`, registered with
    :func:`pgm.inference.record.register_runtime`); the engine's step loop, stages and
    rule dispatch are the same for both. A runtime has the methods below."""

    #: whether a frame with neither image nor detections is predicted through
    predicts_missing_frames = False
    #: which likelihood rules' factors the weight stage scores in one pass
    #: (:data:`pgm.inference.rules.GROUP_SCORING`): several factors of one graph
    group_scoring = "graph"

    def setup(self, engine: Any) -> None:
        """Keep each learning factor's state in the engine's slots (``engine.state``;
        the factor, the engine's own, is bound to it)."""
        for name, f in engine.graph.factors.items():
            if f.state is not None:
                engine.state.hold(name, f.state)

    def belief_type(self, engine: Any, variable: str, row_type: type) -> type:
        """The belief class the engine keeps for ``variable`` (one replica's: ``row_type``)."""
        return row_type

    def step_stages(self, engine: Any, frame: FrameContext, record: StepRecord,
                    lifecycle: bool) -> Iterator[tuple[str, StepRecord]]:
        """Run one frame's stages (the first frame's on the first call), yielding after
        each (:meth:`pgm.inference.engine.Engine.stages`)."""
        yield from engine._run_stages(
            engine.schedule.first_frame if engine.t == 0 else engine.schedule.phases,
            frame, record)

    def finish(self, engine: Any, record: StepRecord) -> None:
        """After the frame (its record complete): the graph's calibrated confidence, kept
        where a proposal may read it."""
        if engine._proposals:
            engine.confidence = confidence(engine.graph, record)

    def graphs(self, ctx: RuleContext) -> list[FactorGraph]:
        """The graphs whose factors the frame uses (one per replica of a plate)."""
        return [ctx.graph]

    def state_slots(self, ctx: RuleContext) -> list[StateSlots]:
        """The rules' state slots (one per replica of a plate)."""
        return [ctx.state]

    def learn(self, ctx: RuleContext, items, frame: FrameContext, record: StepRecord) -> None:
        """After the estimate stage: the factors that learn are updated with the
        estimates and the likelihood scores there."""
        learners = [f for f in ctx.graph.factors.values() if f.learns]
        if learners:
            scores = {v: ctx.score_at(v, record.estimates[v], frame) for v in items
                      if ctx.graph.factors_of(v, "likelihood")}
            for f in learners:
                f.update(record.estimates, scores, frame)

    def normalize(self, ctx: RuleContext, variable: str, belief, before):
        """A reweighted belief normalised; second, the rows kept at ``before`` (none)."""
        return belief.normalized(), None

    def score_group(self, ctx: RuleContext, fs: list[Factor], frame: FrameContext) -> list:
        """Log-likelihoods of likelihood factors of one graph scored in one pass."""
        return type(fs[0]).log_likelihood_batch(fs, [ctx.beliefs[f.variables[0]].x
                                                     for f in fs], frame)

    def num_targets(self, engine: Any) -> int:
        return 0

    def tracks(self, engine: Any) -> list:
        return []

    def factor(self, engine: Any, name: str, replica: int | None) -> Factor:
        return engine.graph.factors[name]

    def associate(self, engine: Any, frame: FrameContext, record: StepRecord) -> None:
        raise ValueError(f"graph {engine.graph.name!r} declares no plate: nothing to "
                         f"associate")

    def add(self, engine: Any, boxes, frame, **kwargs) -> list[int]:
        raise ValueError(f"graph {engine.graph.name!r} declares no plate: it has no replicas")

    def remove(self, engine: Any, indices) -> None:
        raise ValueError(f"graph {engine.graph.name!r} declares no plate: it has no replicas")


#: the runtime of every graph no registered runtime applies to
SINGLE_GRAPH = SingleGraph()
