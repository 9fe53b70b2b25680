"""The generic engine: one per-frame schedule derived from the graph, rules by dispatch.

A frame's step:

1. **predict** — every variable with a transition factor moves its belief;
2. **assign** — (a plate with an association factor) the frame's detections assigned to
   the replicas, whose likelihoods then read their own detection;
3. **weight** — likelihood factors score the belief against the frame (the local
   evidence, kept unnormalised in ``engine.evidence`` for the messages);
4. **in-frame** — coupling factors (particle BP) and conjugate factors (mean-field VB)
   exchange messages, then **fuse** combines each variable's own particles with its
   incoming messages (``"mixture"`` or ``"product"``, :mod:`pgm.inference.pbp`);
5. **estimate** — per-variable estimates (before resampling: lower variance), then
   factors that learn after a frame (adaptive offsets) are updated;
6. **resample** — ESS-triggered, scheme chosen by the user; mass is kept; a fused
   mixture is always brought back to the variable's particle count.

An order with the in-frame passes before weighting would not do: both fusion rules of
:mod:`pgm.inference.pbp` need each part's local evidence first (a message carries its
source's likelihood), so the weight stage comes first here.

The first frame replaces *predict* by *prior*: each variable's belief is drawn from its
prior factor and likelihood factors may learn from the frame (e.g. a colour template at
the prior mean) before it is weighted.

Every stage dispatches through a :class:`~pgm.inference.rules.RuleTable` keyed by
*(factor class, belief type)*, each resolved along its MRO, so
``rules.register(MyLikelihood, Particles)`` gives a user's factor its own rule. The
engine never knows which model it runs: particle BP, VB and the PHD corrector are rules
registered in this table.

**Plates.** A graph with a :class:`~pgm.core.plate.Plate` runs on the same engine and the
same schedule: the plate's variables hold *batched* beliefs (:mod:`pgm.core.batched`:
particles ``(K, N, d)``, one Gaussian or noise belief per replica), rules registered for
the batched types act on all ``K`` replicas at once, and any other single-graph rule runs
once per replica (:mod:`pgm.inference.plates`). Interaction factors between replicas are
the ``interaction`` stage; the ``associate`` stage is the track layer (births from
unmatched detections, confirmation, coasting, the lost stage, identities). Each replica
draws from its own generator, so ``K = 1`` reproduces a single-graph run bit for bit.

**The weight-stage contract.** On a belief that likelihoods reweight
(``belief_type.likelihood_reweights``, true for :class:`~pgm.Particles`), a likelihood
rule *returns* its log-likelihood increment per particle, shape ``(N,)``, and never
touches ``engine.beliefs``: the engine applies the increment and keeps it as the
variable's local evidence (``engine.evidence``), which particle-BP messages read. A
rule that replaces the belief (e.g. resamples or reorders particles) is a
:class:`RuleContractError` naming it. On other beliefs (an intensity's PHD corrector, a
Gaussian's Kalman update) the rule updates the belief itself and returns diagnostics.
:func:`pgm.inference.conformance.checked` wraps a rule table so that every rule call
is checked against its contract.

Example
-------
>>> import numpy as np
>>> from pgm.models import linear_gaussian
>>> from pgm.core.frame import FrameContext
>>> from pgm.inference import Engine
>>> graph = linear_gaussian.build_graph(linear_gaussian.Params())
>>> engine = Engine(graph, rng=np.random.default_rng(0), num_particles=500)
>>> rec = engine.step(FrameContext(1, measurements=np.array([0.3])))
>>> rec.estimates["x"].shape
(2,)
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Iterable, Iterator

import numpy as np

from pgm.core.beliefs import Intensity, Particles
from pgm.core.errors import RuleContractError
from pgm.core.expfam import InverseGamma
from pgm.core.factor import Factor
from pgm.core.frame import FrameContext
from pgm.core.graph import FactorGraph
from pgm.core.rng import as_generator
from pgm.factors import LikelihoodFactor

from . import weighting
from .context import RuleContext, ctx_field
from .record import Hook, StepRecord, runtime_for
from .resampling import get_resampler
from .rules import (
    BELIEF_OPERATIONS,
    DEFAULT_RULES,
    Rule,
    RuleTable,
    likelihood_reweights,
    per_replica,
    rule_name,
    saved_rules,
)
from .schedule import STAGES, Schedule, derive_schedule, message_order
from .settings import EngineSettings
from .single import SINGLE_GRAPH

__all__ = ["Engine", "RuleTable", "DEFAULT_RULES", "StepRecord", "Schedule", "derive_schedule",
           "STAGES", "BELIEF_FOR_ROLE", "BELIEF_OPERATIONS", "RuleContractError",
           "likelihood_reweights", "message_order"]

#: belief type the engine creates for each variable role (override per variable with
#: ``Engine(..., belief_types={name: type})``, e.g. :class:`~pgm.core.expfam.Gaussian` for an
#: exact Kalman / VB adaptive Kalman filter)
BELIEF_FOR_ROLE: dict[str, type] = {"part": Particles, "state": Particles,
                                    "latent": Particles, "set": Intensity,
                                    "noise": InverseGamma}


#: the stages whose items are factors (the others' are variables)
_FACTOR_STAGES = ("prior", "predict", "assign", "inframe", "weight", "interaction")


class Engine:
    """Runs a :class:`~pgm.FactorGraph` frame by frame, with or without a plate.

    Parameters
    ----------
    graph : FactorGraph
        The model. The engine works on a deep copy, so factors that learn from the
        first frame (templates) never change the caller's graph; the learned copy is
        ``engine.graph``.
    rng : int or numpy.random.Generator
        The only source of randomness (an int is a seed). In a plate, each replica
        gets a generator spawned from it at its birth (or given to :meth:`add`).
    settings : EngineSettings, optional
        Default: ``EngineSettings.from_dict(graph.meta["engine"])`` (what the model
        config asked for). The keyword arguments below override single fields.
    num_particles : int or dict, optional
        Particles per variable (one int for all, or name → int).
    resampling : str or callable, optional
        ``"systematic"`` (default), ``"multinomial"``, ``"stratified"``, ``"residual"``.
    ess_threshold : float, optional
        Resample when ESS < ``ess_threshold`` × N (0.5 default; 1 = every frame).
    inframe_iterations : int, optional
        Flooding rounds of the in-frame phase on loopy graphs (trees need one sweep).
    fusion : {"mixture", "product"}, optional
        Particle-BP fusion rule (:mod:`pgm.inference.pbp`).
    rules : RuleTable, optional
        Defaults to :data:`DEFAULT_RULES` — except for the factors a saved model names
        a rule for (``graph.meta["rules"]``, written by every engine: factor name →
        ``"module:function"``), which run with that rule, found by name (a one-line
        ``ValueError`` naming it where it cannot be found: never a run with another
        rule). Given, the table decides every factor's rule.
    belief_types : dict, optional
        Variable name → belief class, overriding :data:`BELIEF_FOR_ROLE` (e.g.
        :class:`~pgm.core.expfam.Gaussian` for an exact Kalman filter). For a plate
        variable name the belief of one replica; the engine keeps its batched form.
    """

    def __init__(self, graph: FactorGraph, rng: int | np.random.Generator, *,
                 settings: EngineSettings | None = None,
                 num_particles: int | dict[str, int] | None = None,
                 resampling: str | Callable | None = None, ess_threshold: float | None = None,
                 inframe_iterations: int | None = None, fusion: str | None = None,
                 rules: RuleTable | None = None,
                 belief_types: dict[str, type] | None = None):
        if not isinstance(graph, FactorGraph):
            raise ValueError(f"Engine needs a FactorGraph, got {type(graph).__name__}")
        self.rng = as_generator(rng)
        self.graph = copy.deepcopy(graph)
        if settings is None:
            settings = EngineSettings.from_dict(self.graph.meta.get("engine"))
        elif not isinstance(settings, EngineSettings):
            raise ValueError(f"settings must be an EngineSettings, got {type(settings).__name__}")
        #: the typed settings this engine runs with
        self.settings = settings.replace(
            num_particles=num_particles, resampling=resampling, ess_threshold=ess_threshold,
            inframe_iterations=inframe_iterations, fusion=fusion).with_beliefs(belief_types)
        self.graph.meta["engine"] = self.settings.to_dict(full=True)  # saved with the run
        self.num_particles = self.settings.particle_counts(self.graph)
        self.resampler = get_resampler(self.settings.resampling)
        self.rules = rules if rules is not None else DEFAULT_RULES
        self.belief_types = {**self.settings.belief_classes(), **dict(belief_types or {})}
        unknown = sorted(set(self.belief_types) - set(self.graph.variables))
        if unknown:
            raise ValueError(f"belief_types names unknown variables {unknown}")
        self.schedule = derive_schedule(self.graph, self.settings.inframe_iterations,
                                        self.settings.fusion)
        #: what the rules see (:class:`~pgm.inference.context.RuleContext`): the beliefs,
        #: this frame's evidence and messages, the state slots, the generator, the
        #: settings; ``engine.beliefs``, ``.evidence``, ``.messages``, ``.state``,
        #: ``.assignment``, ``.replicas`` and ``.confidence`` read and write it
        self.ctx = RuleContext(graph=self.graph, rng=self.rng, settings=self.settings,
                               num_particles=self.num_particles, resampler=self.resampler,
                               belief_type=self.belief_type,
                               row_belief_type=self.row_belief_type)
        #: likelihoods that learn something from the first frame (a template)
        self._initializers = [f.name for f in self.graph.factors_by_kind("likelihood")
                              if getattr(type(f), "initialize", LikelihoodFactor.initialize)
                              is not LikelihoodFactor.initialize]
        self._proposals = bool(self.graph.factors_by_kind("proposal"))
        self._groups_cache: dict[tuple, list[tuple[list[Factor], list[Rule], bool]]] = {}
        self._rule_cache: dict[tuple, Rule] = {}
        #: per factor name, the rule a saved model named for it (``graph.meta["rules"]``)
        self._factor_rules: dict[str, tuple[Rule, bool]] = (
            {} if rules is not None else saved_rules(self.graph))
        self.frame: FrameContext | None = None
        self._in_frame: int | None = None  # the frame whose stages are running, if any
        self.t = 0
        self._hooks: dict[str, list[Hook]] = {s: [] for s in STAGES}
        self._stage_functions = {s: getattr(self, f"_stage_{s}") for s in STAGES}
        #: the plate (:class:`~pgm.core.plate.Plate`), or None (set by the runtime)
        self.plate = None
        #: how this graph's frame runs (:class:`SingleGraph`, or the runtime registered
        #: for it: a plate's, :class:`pgm.inference.plates.PlateRuntime`)
        self.runtime = runtime_for(self.graph) or SINGLE_GRAPH
        self.runtime.setup(self)
        self._check_rules()
        #: which rule serves each factor, by importable name: saved with the run
        self.graph.meta["rules"] = self._rule_names()

    # -- the rules' state (engine.ctx) ---------------------------------------------------
    beliefs = ctx_field("beliefs", "Variable name → belief (``engine.ctx.beliefs``).")
    evidence = ctx_field("evidence", "Per variable, this frame's ``(prior_log_weights, "
                                     "log_likelihood)`` (weight stage).")
    messages = ctx_field("messages", "This frame's messages ``(src, dst) -> message``.")
    state = ctx_field("state", "The state rules keep across frames, typed, per owner "
                               "(:mod:`pgm.inference.state`): PHD tracks, score models, ...")
    assignment = ctx_field("assignment", "This frame's assignment of detections to a "
                                         "plate's replicas (``assign`` stage), or None.")
    replicas = ctx_field("replicas", "The plate's replicas (:class:`pgm.inference.plates."
                                     "Replicas`), or None.")
    plate_spec = ctx_field("plate_spec", "What the engine derived from the plate, or None.")
    confidence = ctx_field("confidence", "The graph's calibrated confidence at the last "
                                         "frame (:func:`pgm.core.readout.confidence`).")

    ess_threshold = property(lambda self: self.settings.ess_threshold,
                             doc="Resample when ESS < ``ess_threshold`` × N.")

    # -- set-up ------------------------------------------------------------------------
    def row_belief_type(self, variable: str) -> type:
        """Belief class of one replica of a variable (from its role)."""
        role = self.graph.variables[variable].role
        bt = self.belief_types.get(variable) or BELIEF_FOR_ROLE.get(role)
        if bt is None:
            raise ValueError(f"variable {variable!r}: no belief type for role {role!r} in this "
                             f"engine")
        return bt

    def belief_type(self, variable: str) -> type:
        """Belief class of a variable: its role's, as the runtime keeps it (batched for a
        plate variable)."""
        return self.runtime.belief_type(self, variable, self.row_belief_type(variable))

    def factor_belief_type(self, factor: Factor) -> type:
        """The belief type a factor's rule is dispatched on (its first non-noise variable's)."""
        for v in factor.variables:
            if self.graph.variables[v].role != "noise":
                return self.belief_type(v)
        return self.belief_type(factor.variables[0])

    def _rule_names(self) -> dict[str, str]:
        """Factor name → the importable name of the rule that serves it."""
        names = {}
        for phases in (self.schedule.first_frame, self.schedule.phases):
            for stage, items in phases:
                for item in items:
                    if stage in _FACTOR_STAGES:
                        name = item[0] if isinstance(item, tuple) else item
                        f = self.graph.factors[name]
                        dst = item[2] if isinstance(item, tuple) else None
                        names[name] = rule_name(self._rule(f, dst))
        return names

    def _rule(self, factor: Factor, dst: str | None = None) -> Rule:
        """The rule for ``factor`` (a coupling's: for its message to ``dst``)."""
        saved = self._factor_rules.get(factor.name)
        if saved is not None:
            rule, replicated = saved
            return per_replica(rule, type(factor)) if replicated else rule
        if dst is not None:
            return self.rules.lookup(type(factor), self.belief_type(dst))
        return self.rule_for(factor)

    def rule_for(self, factor: Factor) -> Rule:
        """The rule this engine applies to ``factor`` (looked up once per factor type and
        belief type: both are fixed for an engine's life)."""
        if factor.name in self._factor_rules:
            return self._rule(factor)
        key = (type(factor), factor.variables)
        rule = self._rule_cache.get(key)
        if rule is None:
            rule = self._rule_cache[key] = self.rules.lookup(type(factor),
                                                             self.factor_belief_type(factor))
        return rule

    def _check_rules(self) -> None:
        """Fail at construction, naming the factor, if some stage has no rule."""
        for phases in (self.schedule.first_frame, self.schedule.phases):
            for stage, items in phases:
                for item in items:
                    if stage in _FACTOR_STAGES:
                        f = self.graph.factors[item[0] if isinstance(item, tuple) else item]
                        if f.name in self._factor_rules:
                            continue
                        bt = self.factor_belief_type(f)
                        if not self.rules.has(type(f), bt):
                            raise ValueError(f"factor {f.name!r}: no inference rule for "
                                             f"({type(f).__name__}, {bt.__name__}) in this "
                                             f"engine")
                    elif stage != "associate":
                        bt = self.belief_type(item)
                        if not self.rules.has(stage, bt):
                            raise ValueError(f"variable {item!r}: no {stage} rule for "
                                             f"{bt.__name__}")

    def add_hook(self, stage: str, hook: Hook) -> None:
        """Call ``hook(engine, stage, frame, record)`` after every ``stage``."""
        if stage not in STAGES:
            raise ValueError(f"unknown stage {stage!r} (expected one of {STAGES})")
        self._hooks[stage].append(hook)

    # -- a plate's replicas ------------------------------------------------------------
    @property
    def predicts_missing_frames(self) -> bool:
        """Whether a frame with neither image nor detections is predicted through (a
        plate's replicas are; a single graph's likelihoods need their frame)."""
        return self.runtime.predicts_missing_frames

    @property
    def num_targets(self) -> int:
        """Number of replicas ``K`` of the plate (tentative, confirmed and lost); 0 without."""
        return self.runtime.num_targets(self)

    @property
    def tracks(self) -> list:
        """The replicas' track records (identities, hits, existence), in replica order."""
        return self.runtime.tracks(self)

    def factor(self, name: str, replica: int | None = None) -> Factor:
        """The factor ``name`` (as replica ``replica`` uses it: bound to the replica's own
        learned state if it keeps one)."""
        return self.runtime.factor(self, name, replica)

    def add(self, boxes: np.ndarray | None, frame: FrameContext, rngs=None,
            confirmed: bool = False, count: int | None = None) -> list[int]:
        """Start replicas of the plate on ``boxes`` ``(M, 4)`` (cx, cy, w, h) in ``frame``
        (:func:`pgm.inference.plates.add`); returns their indices."""
        return self.runtime.add(self, boxes, frame, rngs=rngs, confirmed=confirmed,
                                count=count)

    def remove(self, indices) -> None:
        """Remove the replicas at ``indices``."""
        self.runtime.remove(self, indices)

    # -- running -----------------------------------------------------------------------
    def step(self, frame: FrameContext, *, lifecycle: bool = True) -> StepRecord:
        """Process one frame (the first call initialises from the priors).

        With a plate, replicas are born at the ``associate`` stage (and run the
        first-frame stages there); ``lifecycle=False`` skips that stage (replicas managed
        by the caller with :meth:`add` and :meth:`remove`). A frame with neither image nor
        detections is *missing* for a plate: its replicas are only predicted.

        Hooks (:meth:`add_hook`) run after each stage of the frame's schedule; for a plate,
        on the replicas there are (none on a frame without replicas; only ``predict`` on a
        missing frame), and not on the first-frame stages of replicas born in the frame."""
        *_, (_, record) = self.stages(frame, lifecycle=lifecycle)  # run to the end
        return record

    def stages(self, frame: FrameContext, *, lifecycle: bool = True
               ) -> Iterator[tuple[str, StepRecord]]:
        """Step through one frame stage by stage (notebooks, the viewer, teaching): yields
        ``(stage, record)`` after each stage where :meth:`step` runs hooks — the record as
        filled so far (this frame's messages, ESS, VB diagnostics, estimates; the beliefs
        are ``engine.beliefs``) — and last ``("done", record)``, the frame complete.
        :meth:`step` is this generator run to its end; run it to its end too before the
        next frame (a frame left half-way leaves the engine half-way through it)."""
        if not isinstance(frame, FrameContext):
            raise ValueError(f"step() needs a FrameContext, got {type(frame).__name__}")
        if self._in_frame is not None:
            raise ValueError(f"frame {self._in_frame} was left half-way (its stages() not run "
                             f"to the end): the engine's beliefs are mid-frame; run that "
                             f"generator to its end first")
        self.frame = frame
        self._in_frame = frame.index
        ctx = self.ctx
        ctx.evidence, ctx.messages, ctx.assignment = {}, {}, None
        # the record is filled as the stages run: a hook sees this frame's messages, ESS,
        # diagnostics and estimates so far (the messages' dict is the engine's own)
        record = StepRecord(frame=frame.index, messages=ctx.messages)
        try:
            yield from self.runtime.step_stages(self, frame, record, lifecycle)
            record.beliefs = dict(self.beliefs)
            record.messages = dict(self.messages)
            self.runtime.finish(self, record)
        except Exception:  # an error ends the frame (a generator left open does not)
            self._in_frame = None
            raise
        self.t += 1
        self._in_frame = None
        yield "done", record

    def _run(self, phases, frame: FrameContext, record: StepRecord, hooks: bool = True,
             skip: tuple[str, ...] = (), ctx: RuleContext | None = None) -> None:
        """:meth:`_run_stages` run through (``ctx``: a plate's newborns have their own)."""
        for _ in self._run_stages(phases, frame, record, hooks, skip, ctx):
            pass

    def _run_stages(self, phases, frame: FrameContext, record: StepRecord, hooks: bool = True,
                    skip: tuple[str, ...] = (), ctx: RuleContext | None = None
                    ) -> Iterator[tuple[str, StepRecord]]:
        """Run the stages ``phases``, yielding after each whose hooks run (``hooks``). A
        stage with nothing to do is not called (the prior stage always is: it also
        initialises templates); its hooks still are."""
        stages = self._stage_functions
        ctx = self.ctx if ctx is None else ctx
        for stage, items in phases:
            if stage in skip:
                continue
            if items or stage == "prior":
                stages[stage](ctx, items, frame, record)
            if hooks:
                for hook in self._hooks[stage]:
                    hook(self, stage, frame, record)
                yield stage, record

    def run(self, frames: Iterable[FrameContext], *, lifecycle: bool = True
            ) -> Iterator[StepRecord]:
        """Step through ``frames`` lazily, yielding one :class:`StepRecord` per frame
        (``lifecycle``: as for :meth:`step`)."""
        for frame in frames:
            yield self.step(frame, lifecycle=lifecycle)

    # -- stages ------------------------------------------------------------------------
    def _apply_factor(self, ctx: RuleContext, name: str, frame: FrameContext,
                      record: StepRecord) -> None:
        f = ctx.graph.factors[name]
        info = self.rule_for(f)(ctx, f, frame)
        if info:
            record.info[name] = info

    def _stage_prior(self, ctx, items, frame, record) -> None:
        for name in items:
            self._apply_factor(ctx, name, frame, record)
        if not self._initializers:
            return
        for g in self.runtime.graphs(ctx):  # templates learned at the prior mean (each
            # replica its own)
            for name in self._initializers:
                f = g.factors[name]
                priors = g.factors_of(f.variables[0], "prior")
                if priors:
                    f.initialize(frame, priors[0].mean())

    def _stage_predict(self, ctx, items, frame, record) -> None:
        for name in items:
            self._apply_factor(ctx, name, frame, record)

    _stage_interaction = _stage_predict
    _stage_assign = _stage_predict

    def _stage_inframe(self, ctx, items, frame, record) -> None:
        for item in items:
            if isinstance(item, tuple):
                name, src, dst = item
                f = ctx.graph.factors[name]
                info = self._rule(f, dst)(ctx, f, frame, src, dst)
                if info:
                    record.info.setdefault(name, {})[(src, dst)] = info
            else:
                self._apply_factor(ctx, item, frame, record)

    def _stage_fuse(self, ctx, items, frame, record) -> None:
        for v in items:
            record.report(v, self.rules.lookup("fuse", type(ctx.beliefs[v]))(ctx, v, frame))

    def _stage_weight(self, ctx, items, frame, record) -> None:
        """Apply the likelihood factors (the weight-stage contract: module docstring;
        :mod:`pgm.inference.weighting`)."""
        weighting.stage_weight(self, ctx, items, frame, record)

    def _stage_resample(self, ctx, items, frame, record) -> None:
        for v in items:
            rule = self.rules.lookup("resample", type(ctx.beliefs[v]))
            info = rule(ctx, v, frame)
            record.report(v, info)
            res = (info or {}).get("resampled", False)
            record.resampled[v] = res if isinstance(res, np.ndarray) else bool(res)

    def _stage_estimate(self, ctx, items, frame, record) -> None:
        for v in items:
            rule = self.rules.lookup("estimate", type(ctx.beliefs[v]))
            record.estimates[v] = rule(ctx, v, frame)
        self.runtime.learn(ctx, items, frame, record)

    def _stage_associate(self, ctx, items, frame, record) -> None:
        self.runtime.associate(self, frame, record)

    def log_likelihood(self, variable: str, x: np.ndarray, frame: FrameContext) -> np.ndarray:
        """Sum of ``variable``'s likelihood factors at particles ``x`` ``(N, d)``."""
        return self.ctx.log_likelihood(variable, x, frame)

    def score_at(self, variable: str, value: np.ndarray, frame: FrameContext) -> float:
        """Summed log-likelihood of ``variable``'s likelihood factors at one value."""
        return self.ctx.score_at(variable, value, frame)
