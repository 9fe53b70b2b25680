"""What an inference rule sees: :class:`RuleContext`, not the engine.

A rule is called as ``rule(ctx, factor, frame)`` (a coupling's as ``rule(ctx, factor,
frame, src, dst)``, a belief operation's as ``rule(ctx, variable, frame)``). The context
holds exactly what a rule may read or change — the beliefs, this frame's local evidence
and messages, the generator, the engine's settings, the state slots rules keep across
frames — and, for the rules of a plate, the replicas. It holds no schedule, no rule
table, no hooks and no step loop: a rule cannot run stages or reach another rule.

The engine keeps one context (``engine.ctx``; ``engine.beliefs`` and the other state
attributes read and write it). A plate's newborn replicas run their first frame on a
fresh context (:meth:`RuleContext.newborn`), and a single-graph rule serving a plate runs
once per replica on that replica's context (:meth:`RuleContext.replica`: its rows of the
batched beliefs, its generator, its factors, its state slots). Neither swaps anything on
the engine.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from pgm.core.frame import FrameContext

from .state import StateSlots

__all__ = ["RuleContext", "ctx_field"]


class RuleContext:
    """What a rule reads and changes (module docstring).

    Attributes
    ----------
    graph : FactorGraph
        The factors the rule's beliefs answer to (a replica's: its own views of the
        factors that learn).
    beliefs : dict
        Variable name → belief; a rule replaces a variable's entry to update it.
    evidence, messages : dict
        This frame's local evidence ``variable -> (prior_log_weights, log_likelihood)``
        (weight stage) and particle-BP messages ``(src, dst) -> message`` (in-frame).
    rng : numpy.random.Generator
        The only source of randomness (a replica's own generator in its context).
    settings : EngineSettings
        What the model asked of the engine; ``num_particles`` (per variable),
        ``resampler`` and ``ess_threshold`` are derived from it.
    state : StateSlots
        Typed state rules keep across frames (:mod:`pgm.inference.state`).
    replicas, plate_spec, assignment
        A plate's replicas (:class:`pgm.inference.plates.Replicas`), what the engine
        derived from the plate, this frame's assignment of detections (``assign`` stage);
        None for a single graph and inside one replica's context.
    confidence : float or None
        The graph's calibrated confidence at the last frame (a proposal may read it).
    """

    __slots__ = ("graph", "beliefs", "evidence", "messages", "rng", "settings",
                 "num_particles", "resampler", "state", "replicas", "plate_spec",
                 "assignment", "confidence", "_belief_type", "_row_belief_type")

    def __init__(self, *, graph: Any, rng: np.random.Generator, settings: Any,
                 num_particles: dict[str, int], resampler: Callable,
                 belief_type: Callable[[str], type],
                 row_belief_type: Callable[[str], type] | None = None,
                 state: StateSlots | None = None, beliefs: dict[str, Any] | None = None,
                 evidence: dict | None = None, messages: dict | None = None,
                 replicas: Any = None, plate_spec: Any = None, confidence: float | None = None):
        self.graph = graph
        self.rng = rng
        self.settings = settings
        self.num_particles = num_particles
        self.resampler = resampler
        self._belief_type = belief_type
        self._row_belief_type = row_belief_type or belief_type
        self.state = StateSlots() if state is None else state
        self.beliefs: dict[str, Any] = {} if beliefs is None else beliefs
        self.evidence: dict[str, tuple[np.ndarray, np.ndarray]] = ({} if evidence is None
                                                                   else evidence)
        self.messages: dict[tuple[str, str], Any] = {} if messages is None else messages
        self.replicas = replicas
        self.plate_spec = plate_spec
        self.assignment = None
        self.confidence = confidence

    @property
    def ess_threshold(self) -> float:
        """Resample when ESS < ``ess_threshold`` × N."""
        return self.settings.ess_threshold

    def belief_type(self, variable: str) -> type:
        """The belief class kept for ``variable`` here (batched in a plate's context)."""
        return self._belief_type(variable)

    def row_belief_type(self, variable: str) -> type:
        """The belief class of one replica of ``variable`` (the same for a single graph)."""
        return self._row_belief_type(variable)

    def log_likelihood(self, variable: str, x: np.ndarray, frame: FrameContext) -> np.ndarray:
        """Sum of ``variable``'s likelihood factors at particles ``x`` ``(N, d)``."""
        total = np.zeros(x.shape[0])
        for f in self.graph.factors_of(variable, "likelihood"):
            total = total + f.log_likelihood(x, frame)
        return total

    def score_at(self, variable: str, value: np.ndarray, frame: FrameContext) -> float:
        """Summed log-likelihood of ``variable``'s likelihood factors at one value."""
        x = np.asarray(value, dtype=float).reshape(1, -1)
        return float(self.log_likelihood(variable, x, frame)[0])

    def newborn(self, replicas: Any) -> RuleContext:
        """A context for a plate's newborn ``replicas`` (their own first frame): no belief,
        evidence, message or assignment yet; everything else this context's."""
        return RuleContext(graph=self.graph, rng=self.rng, settings=self.settings,
                           num_particles=self.num_particles, resampler=self.resampler,
                           belief_type=self._belief_type, row_belief_type=self._row_belief_type,
                           state=self.state, replicas=replicas, plate_spec=self.plate_spec,
                           confidence=self.confidence)

    def replica(self, k: int) -> RuleContext:
        """Replica ``k`` of a plate as a single-graph rule sees it: its rows of the batched
        beliefs, evidence and messages, its generator, its view of the graph and its
        state slots."""
        reps = self.replicas
        return RuleContext(
            graph=reps.graphs[k], rng=reps.generators()[k], settings=self.settings,
            num_particles=self.num_particles, resampler=self.resampler,
            belief_type=self._row_belief_type, state=reps.state[k],
            beliefs={v: b.row(k) for v, b in self.beliefs.items()},
            evidence={v: (a[k], ll[k]) for v, (a, ll) in self.evidence.items()},
            messages={key: m.row(k) for key, m in self.messages.items()},
            confidence=self.confidence)


def ctx_field(name: str, doc: str) -> property:
    """A property reading and writing ``self.ctx.<name>`` (the engine's view of its
    rules' context)."""
    return property(lambda self: getattr(self.ctx, name),
                    lambda self, value: setattr(self.ctx, name, value), doc=doc)
