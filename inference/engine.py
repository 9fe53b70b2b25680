"""The generic engine: one per-frame schedule derived from the graph, rules by dispatch.

A frame's step:

1. **predict** — every variable with a transition factor moves its belief;
2. **weight** — likelihood factors score the belief against the frame (the local
   evidence, kept unnormalised in ``engine.evidence`` for the messages);
3. **in-frame** — coupling factors (particle BP) and conjugate factors (mean-field VB)
   exchange messages, then **fuse** combines each variable's own particles with its
   incoming messages (``"mixture"`` or ``"product"``, :mod:`pgm.inference.pbp`);
4. **estimate** — per-variable estimates (before resampling: lower variance), then
   factors that learn after a frame (adaptive offsets) are updated;
5. **resample** — ESS-triggered, scheme chosen by the user; mass is kept; a fused
   mixture is always brought back to the variable's particle count.

An order with the in-frame passes before weighting would not do: both fusion rules of
:mod:`pgm.inference.pbp` need each part's local evidence first (a message carries its
source's likelihood), so the weight stage comes first here.

The first frame replaces *predict* by *prior*: each variable's belief is drawn from its
prior factor and likelihood factors may learn from the frame (e.g. a colour template at
the prior mean) before it is weighted.

Every stage dispatches through a :class:`RuleTable` keyed by *(factor class, belief
type)* — as ReactiveMP keys rules by node and edge — each resolved along its MRO (the
factor's first, then the belief's), so ``rules.register(MyLikelihood, Particles)``
gives a user's factor its own rule and a subclass (e.g. :class:`~pgm.Intensity`)
inherits rules it does not override. Belief operations (``fuse``, ``resample``,
``estimate``) are keyed by *(operation, belief type)*. The engine never knows which
model it runs: particle BP, VB and the PHD corrector are rules registered in this table.

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
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pgm.core.beliefs import Intensity, Particles
from pgm.core.errors import RuleContractError
from pgm.core.expfam import InverseGamma
from pgm.core.factor import Factor
from pgm.core.frame import FrameContext
from pgm.core.graph import FactorGraph
from pgm.core.motion import warp_states
from pgm.factors import LikelihoodFactor, PriorFactor, TransitionFactor

from .resampling import ess_triggered, get_resampler
from .settings import FUSIONS, EngineSettings

__all__ = ["Engine", "RuleTable", "DEFAULT_RULES", "StepRecord", "Schedule", "derive_schedule",
           "STAGES", "BELIEF_FOR_ROLE", "BELIEF_OPERATIONS", "RuleContractError",
           "likelihood_reweights"]

STAGES = ("prior", "predict", "weight", "inframe", "fuse", "estimate", "resample")
#: operations on one variable's belief (rules keyed by name, not by a factor class)
BELIEF_OPERATIONS = ("fuse", "resample", "estimate")

#: belief type the engine creates for each variable role (override per variable with
#: ``Engine(..., belief_types={name: type})``, e.g. :class:`~pgm.core.expfam.Gaussian` for an
#: exact Kalman / VB adaptive Kalman filter)
BELIEF_FOR_ROLE: dict[str, type] = {"part": Particles, "state": Particles,
                                    "latent": Particles, "set": Intensity,
                                    "noise": InverseGamma}

Rule = Callable[..., Any]


def likelihood_reweights(belief_type: type) -> bool:
    """Whether likelihood factors act on ``belief_type`` by reweighting (the contract)."""
    return bool(getattr(belief_type, "likelihood_reweights", False))


def _key_name(key: type | str) -> str:
    return key if isinstance(key, str) else key.__name__


class RuleTable:
    """Inference rules keyed by ``(factor class, belief type)`` or ``(operation, belief type)``.

    Factor rules are looked up along the factor class's MRO first, then the belief
    type's: ``register(PHDLikelihood, Intensity)`` wins over ``register(LikelihoodFactor,
    Intensity)`` for a PHD factor, and both over ``(LikelihoodFactor, Particles)``.

    Calling conventions
    -------------------
    * prior, transition, conjugate factors: ``rule(engine, factor, frame)``; updates
      ``engine.beliefs``; may return a dict of diagnostics;
    * likelihood factors on a belief that likelihoods reweight (:class:`~pgm.Particles`):
      ``rule(engine, factor, frame) -> log_lik`` of shape ``(N,)``, touching no belief;
      on other beliefs, as a prior rule;
    * coupling factors: ``rule(engine, factor, frame, src, dst)`` (one directed message);
    * belief operations (``fuse``, ``resample``, ``estimate``):
      ``rule(engine, variable_name, frame)``.

    Diagnostics are stored in the step record under the factor's (or variable's) name.
    """

    def __init__(self, rules: dict[tuple[type | str, type], Rule] | None = None):
        self._rules: dict[tuple[type | str, type], Rule] = dict(rules or {})
        self._resolved: dict[tuple[type | str, type], Rule] = {}

    @staticmethod
    def _check_key(key: type | str, belief_type: type) -> None:
        if isinstance(key, str):
            if key not in BELIEF_OPERATIONS:
                raise ValueError(f"unknown operation {key!r}: register a factor class, or one "
                                 f"of {BELIEF_OPERATIONS}")
        elif not (isinstance(key, type) and issubclass(key, Factor)):
            raise ValueError(f"rule key must be a Factor subclass or one of "
                             f"{BELIEF_OPERATIONS}, got {key!r}")
        if not isinstance(belief_type, type):
            raise ValueError(f"belief type must be a class, got {belief_type!r}")

    def register(self, key: type | str, belief_type: type) -> Callable[[Rule], Rule]:
        """Decorator registering a rule for ``(factor class | operation, belief type)``."""
        self._check_key(key, belief_type)

        def deco(rule: Rule) -> Rule:
            self._rules[(key, belief_type)] = rule
            self._resolved.clear()
            return rule

        return deco

    def _find(self, key: type | str, belief_type: type) -> Rule | None:
        keys = [key] if isinstance(key, str) else [
            k for k in key.__mro__ if isinstance(k, type) and issubclass(k, Factor)]
        for k in keys:
            for b in belief_type.__mro__:
                rule = self._rules.get((k, b))
                if rule is not None:
                    return rule
        return None

    def lookup(self, key: type | str, belief_type: type) -> Rule:
        """The rule for ``key`` (a factor class or a belief operation) on ``belief_type``."""
        hit = self._resolved.get((key, belief_type))
        if hit is not None:
            return hit
        rule = self._find(key, belief_type)
        if rule is None:
            raise ValueError(f"no inference rule for ({_key_name(key)}, {belief_type.__name__}):"
                             f" register one with RuleTable.register")
        self._resolved[(key, belief_type)] = rule
        return rule

    def has(self, key: type | str, belief_type: type) -> bool:
        """Whether :meth:`lookup` would succeed."""
        return self._find(key, belief_type) is not None

    def remove(self, key: type | str, belief_type: type) -> None:
        """Drop the rule registered exactly for ``(key, belief_type)``."""
        self._rules.pop((key, belief_type), None)
        self._resolved.clear()

    def items(self) -> list[tuple[tuple[type | str, type], Rule]]:
        """Every registered ``((key, belief type), rule)`` pair."""
        return list(self._rules.items())

    def copy(self) -> RuleTable:
        """An independent copy (to add rules for one engine only)."""
        return RuleTable(self._rules)

    def __repr__(self) -> str:
        keys = ", ".join(f"({_key_name(k)}, {t.__name__})" for k, t in self._rules)
        return f"RuleTable([{keys}])"


DEFAULT_RULES = RuleTable()


@dataclass
class Schedule:
    """The per-frame schedule: ``phases`` is a list of ``(stage, items)``.

    ``items`` are factor names for factor stages, ``(coupling, src, dst)`` triples for
    directed messages in the ``inframe`` stage, and variable names for ``fuse``,
    ``estimate`` and ``resample``.
    """

    first_frame: list[tuple[str, list]]
    phases: list[tuple[str, list]]

    def __repr__(self) -> str:
        def item(i):
            return f"{i[1]}→{i[2]}" if isinstance(i, tuple) else str(i)

        def fmt(ph):
            return " → ".join(f"{s}[{', '.join(item(i) for i in items)}]"
                              for s, items in ph if items)

        return f"Schedule(\n  first: {fmt(self.first_frame)}\n  step:  {fmt(self.phases)}\n)"


def message_order(graph: FactorGraph, fusion: str = "mixture",
                  iterations: int = 1) -> list[tuple[str, str, str]]:
    """Directed coupling messages ``(factor, src, dst)`` for one frame.

    ``"mixture"``: every directed edge once (all messages leave this frame's predicted
    particles). ``"product"``: on a forest, a leaves-to-root then root-to-leaves sweep
    (exact for trees); with loops, ``iterations`` flooding rounds.
    """
    import networkx as nx

    couplings = graph.factors_by_kind("coupling")
    if not couplings:
        return []
    flood = [(f.name, f.variables[1], f.variables[0]) for f in couplings] + \
            [(f.name, f.variables[0], f.variables[1]) for f in couplings]
    if fusion == "mixture":
        return flood
    g = nx.MultiGraph()
    for f in couplings:
        g.add_edge(*f.variables, key=f.name)
    if not nx.is_forest(nx.Graph(g)) or g.number_of_edges() != nx.Graph(g).number_of_edges():
        return flood * max(1, iterations)
    by_pair = {frozenset(f.variables): f.name for f in couplings}
    order: list[tuple[str, str, str]] = []
    for comp in nx.connected_components(g):
        root = min(comp, key=list(graph.variables).index)
        tree_edges = list(nx.dfs_edges(nx.Graph(g).subgraph(comp), root))  # parent -> child
        up = [(by_pair[frozenset((p, c))], c, p) for p, c in reversed(tree_edges)]
        down = [(by_pair[frozenset((p, c))], p, c) for p, c in tree_edges]
        order += up + down
    return order


def derive_schedule(graph: FactorGraph, inframe_iterations: int = 1,
                    fusion: str = "mixture") -> Schedule:
    """Derive the per-frame schedule from the factor kinds of ``graph``."""
    if inframe_iterations < 0:
        raise ValueError(f"inframe_iterations must be >= 0, got {inframe_iterations}")
    if fusion not in FUSIONS:
        raise ValueError(f"unknown fusion {fusion!r} (choose from {FUSIONS})")
    names = lambda kind: [f.name for f in graph.factors_by_kind(kind)]  # noqa: E731
    # likelihoods parameterised by a noise variable are updated inside the VB fixed point
    under_vb: set[str] = set()
    for c in graph.factors_by_kind("conjugate"):
        lik = getattr(c, "likelihood", None)
        under_vb |= ({lik} if lik else {f.name for f in graph.factors_of(c.variables[1],
                                                                         "likelihood")})
    messages = message_order(graph, fusion, inframe_iterations)
    conjugates = names("conjugate") * (inframe_iterations if names("conjugate") else 0)
    receivers = [v for v in graph.variables if any(dst == v for _, _, dst in messages)]
    particle_vars = [v.name for v in graph.variables.values() if v.role != "noise"]
    weighted = [n for n in names("likelihood") if n not in under_vb]
    tail = [("weight", weighted), ("inframe", messages + conjugates),
            ("fuse", receivers), ("estimate", list(graph.variables)),
            ("resample", particle_vars)]
    return Schedule(first_frame=[("prior", names("prior"))] + tail,
                    phases=[("predict", names("transition"))] + tail)


@dataclass
class StepRecord:
    """What happened in one frame (for output, inspection and tests).

    Attributes
    ----------
    frame : int
    estimates : dict
        Variable name → estimate (the weighted mean for particle beliefs).
    beliefs : dict
        Variable name → posterior belief after resampling (immutable objects).
    messages : dict
        ``(src, dst)`` → the message of this frame (particle BP), for inspection.
    ess : dict
        ESS after weighting, before resampling.
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


Hook = Callable[["Engine", str, FrameContext, StepRecord], None]


class Engine:
    """Runs a :class:`~pgm.FactorGraph` frame by frame.

    Parameters
    ----------
    graph : FactorGraph
        The model. The engine works on a deep copy, so factors that learn from the
        first frame (templates) never change the caller's graph; the learned copy is
        ``engine.graph``.
    rng : numpy.random.Generator
        The only source of randomness.
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
        Defaults to :data:`DEFAULT_RULES`.
    belief_types : dict, optional
        Variable name → belief class, overriding :data:`BELIEF_FOR_ROLE` (e.g.
        :class:`~pgm.core.expfam.Gaussian` for an exact Kalman filter).
    """

    def __init__(self, graph: FactorGraph, rng: np.random.Generator, *,
                 settings: EngineSettings | None = None,
                 num_particles: int | dict[str, int] | None = None,
                 resampling: str | Callable | None = None, ess_threshold: float | None = None,
                 inframe_iterations: int | None = None, fusion: str | None = None,
                 rules: RuleTable | None = None,
                 belief_types: dict[str, type] | None = None):
        if not isinstance(graph, FactorGraph):
            raise ValueError(f"Engine needs a FactorGraph, got {type(graph).__name__}")
        if not isinstance(rng, np.random.Generator):
            raise ValueError("Engine needs rng=numpy.random.Generator (e.g. "
                             "numpy.random.default_rng(seed))")
        self.graph = copy.deepcopy(graph)
        self.rng = rng
        if settings is None:
            settings = EngineSettings.from_dict(self.graph.meta.get("engine"))
        elif not isinstance(settings, EngineSettings):
            raise ValueError(f"settings must be an EngineSettings, got {type(settings).__name__}")
        #: the typed settings this engine runs with
        self.settings = settings.replace(
            num_particles=num_particles, resampling=resampling, ess_threshold=ess_threshold,
            inframe_iterations=inframe_iterations, fusion=fusion)
        self.graph.meta["engine"] = self.settings.to_dict(full=True)  # saved with the run
        self.num_particles = self._particle_counts(self.settings.num_particles)
        self.resampler = get_resampler(self.settings.resampling)
        self.ess_threshold = self.settings.ess_threshold
        self.rules = rules if rules is not None else DEFAULT_RULES
        self.belief_types = dict(belief_types or {})
        unknown = sorted(set(self.belief_types) - set(self.graph.variables))
        if unknown:
            raise ValueError(f"belief_types names unknown variables {unknown}")
        self.schedule = derive_schedule(self.graph, self.settings.inframe_iterations,
                                        self.settings.fusion)
        self.beliefs: dict[str, Any] = {}
        #: per variable, this frame's ``(prior_log_weights, log_likelihood)`` (weight stage)
        self.evidence: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        #: this frame's messages ``(src, dst) -> message`` (in-frame stage)
        self.messages: dict[tuple[str, str], Any] = {}
        #: per-variable state that rules keep across frames (PHD tracks, extraction, ...)
        self.aux: dict[str, dict[str, Any]] = {}
        self._learners = [f for f in self.graph.factors.values() if f.learns]
        self._groups_cache: dict[tuple, list[tuple[list[Factor], list[Rule], bool]]] = {}
        self.frame: FrameContext | None = None
        self.t = 0
        self._hooks: dict[str, list[Hook]] = {s: [] for s in STAGES}
        self._check_rules()

    # -- set-up ------------------------------------------------------------------------
    def _particle_counts(self, num_particles) -> dict[str, int]:
        names = [v.name for v in self.graph.variables.values() if v.role != "noise"]
        if isinstance(num_particles, dict):
            unknown = set(num_particles) - set(names)
            if unknown:
                raise ValueError(f"num_particles names unknown variables {sorted(unknown)}")
            counts = {n: num_particles.get(n, EngineSettings.num_particles) for n in names}
        else:
            counts = {n: num_particles for n in names}
        return {n: int(c) for n, c in counts.items()}  # validated by EngineSettings

    def belief_type(self, variable: str) -> type:
        """Belief class of a variable (from its role)."""
        role = self.graph.variables[variable].role
        bt = self.belief_types.get(variable) or BELIEF_FOR_ROLE.get(role)
        if bt is None:
            raise ValueError(f"variable {variable!r}: no belief type for role {role!r} in this "
                             f"engine")
        return bt

    def factor_belief_type(self, factor: Factor) -> type:
        """The belief type a factor's rule is dispatched on (its first non-noise variable's)."""
        for v in factor.variables:
            if self.graph.variables[v].role != "noise":
                return self.belief_type(v)
        return self.belief_type(factor.variables[0])

    def rule_for(self, factor: Factor) -> Rule:
        """The rule this engine applies to ``factor``."""
        return self.rules.lookup(type(factor), self.factor_belief_type(factor))

    def _check_rules(self) -> None:
        """Fail at construction, naming the factor, if some stage has no rule."""
        factor_stages = ("prior", "predict", "inframe", "weight")
        for phases in (self.schedule.first_frame, self.schedule.phases):
            for stage, items in phases:
                for item in items:
                    if stage in factor_stages:
                        f = self.graph.factors[item[0] if isinstance(item, tuple) else item]
                        bt = self.factor_belief_type(f)
                        if not self.rules.has(type(f), bt):
                            raise ValueError(f"factor {f.name!r}: no inference rule for "
                                             f"({type(f).__name__}, {bt.__name__}) in this "
                                             f"engine")
                    else:
                        bt = self.belief_type(item)
                        if not self.rules.has(stage, bt):
                            raise ValueError(f"variable {item!r}: no {stage} rule for "
                                             f"{bt.__name__}")

    def add_hook(self, stage: str, hook: Hook) -> None:
        """Call ``hook(engine, stage, frame, record)`` after every ``stage``."""
        if stage not in STAGES:
            raise ValueError(f"unknown stage {stage!r} (expected one of {STAGES})")
        self._hooks[stage].append(hook)

    # -- running -----------------------------------------------------------------------
    def step(self, frame: FrameContext) -> StepRecord:
        """Process one frame (the first call initialises from the priors)."""
        if not isinstance(frame, FrameContext):
            raise ValueError(f"step() needs a FrameContext, got {type(frame).__name__}")
        self.frame = frame
        self.evidence = {}
        self.messages = {}
        record = StepRecord(frame=frame.index)
        phases = self.schedule.first_frame if self.t == 0 else self.schedule.phases
        for stage, items in phases:
            getattr(self, f"_stage_{stage}")(items, frame, record)
            for hook in self._hooks[stage]:
                hook(self, stage, frame, record)
        record.beliefs = dict(self.beliefs)
        record.messages = dict(self.messages)
        self.t += 1
        return record

    def run(self, frames: Iterable[FrameContext]) -> Iterator[StepRecord]:
        """Step through ``frames`` lazily, yielding one :class:`StepRecord` per frame."""
        for frame in frames:
            yield self.step(frame)

    # -- stages ------------------------------------------------------------------------
    def _apply_factor(self, name: str, frame: FrameContext, record: StepRecord) -> None:
        f = self.graph.factors[name]
        info = self.rule_for(f)(self, f, frame)
        if info:
            record.info[name] = info

    def _stage_prior(self, items, frame, record) -> None:
        for name in items:
            self._apply_factor(name, frame, record)
        for f in self.graph.factors_by_kind("likelihood"):
            priors = self.graph.factors_of(f.variables[0], "prior")
            if priors:
                f.initialize(frame, priors[0].mean())

    def _stage_predict(self, items, frame, record) -> None:
        for name in items:
            self._apply_factor(name, frame, record)

    def _stage_inframe(self, items, frame, record) -> None:
        for item in items:
            if isinstance(item, tuple):
                name, src, dst = item
                f = self.graph.factors[name]
                rule = self.rules.lookup(type(f), self.belief_type(dst))
                info = rule(self, f, frame, src, dst)
                if info:
                    record.info.setdefault(name, {})[(src, dst)] = info
            else:
                self._apply_factor(item, frame, record)

    def _stage_fuse(self, items, frame, record) -> None:
        for v in items:
            info = self.rules.lookup("fuse", type(self.beliefs[v]))(self, v, frame)
            if info:
                record.info.setdefault(v, {}).update(info)

    def _weight_groups(self, items) -> list[tuple[list[Factor], list[Rule], bool]]:
        """Likelihood factors grouped by ``batch_key``, each group with its factors' rules
        and whether it is scored in one batched pass (resolved once, then cached)."""
        key = tuple(items)
        groups = self._groups_cache.get(key)
        if groups is None:
            by_key: dict[Any, list[str]] = {}
            groups = []
            for name in items:
                f = self.graph.factors[name]
                bk = getattr(f, "batch_key", None)
                if bk is None:
                    groups.append([name])
                    continue
                bk = (type(f), bk)
                if bk not in by_key:
                    by_key[bk] = []
                    groups.append(by_key[bk])
                by_key[bk].append(name)
            resolved = []
            for names in groups:
                fs = [self.graph.factors[n] for n in names]
                rules = [self.rule_for(f) for f in fs]
                resolved.append((fs, rules,
                                 len(fs) > 1 and all(r is _weight_particles for r in rules)))
            groups = self._groups_cache[key] = resolved
        return groups

    def _stage_weight(self, items, frame, record) -> None:
        """Apply the likelihood factors (the weight-stage contract: module docstring)."""
        before: dict[str, Particles] = {}  # reweighted beliefs as they entered the stage
        log_lik: dict[str, np.ndarray] = {}
        for fs, rules, batched in self._weight_groups(items):
            vs = [f.variables[0] for f in fs]
            if batched:
                lls = type(fs[0]).log_likelihood_batch(fs, [self.beliefs[v].x for v in vs],
                                                       frame)
            else:
                lls = [self._likelihood_increment(f, r, frame, record)
                       for f, r in zip(fs, rules, strict=True)]
            for f, v, ll in zip(fs, vs, lls, strict=True):
                if ll is None:  # a belief the rule updated itself
                    continue
                b = self.beliefs[v]
                ll = _check_ll(f, ll, b.num)
                before.setdefault(v, b)
                log_lik[v] = log_lik[v] + ll if v in log_lik else ll
                self.beliefs[v] = b.reweight(ll)
        for v, b0 in before.items():
            b = self.beliefs[v]
            self.evidence[v] = (b0.log_weights, log_lik[v])
            record.log_evidence[v] = b.log_mass - b0.log_mass
            record.ess[v] = b.ess
            self.beliefs[v] = b.normalized()

    def _likelihood_increment(self, factor: Factor, rule: Rule, frame: FrameContext,
                              record: StepRecord) -> np.ndarray | None:
        """Call one likelihood rule; its increment, or None where it updated the belief."""
        v = factor.variables[0]
        b = self.beliefs[v]
        out = rule(self, factor, frame)
        if not likelihood_reweights(type(b)):
            if out:
                record.info[factor.name] = out
            return None
        if self.beliefs[v] is not b:
            raise RuleContractError(
                f"likelihood rule {getattr(rule, '__qualname__', rule)!r} for factor "
                f"{factor.name!r} replaced the belief of {v!r}: on {type(b).__name__} a "
                f"likelihood rule returns its log-likelihood increment (N,) and never moves, "
                f"reorders or resamples particles")
        if not isinstance(out, np.ndarray):
            raise RuleContractError(
                f"likelihood rule {getattr(rule, '__qualname__', rule)!r} for factor "
                f"{factor.name!r} returned {type(out).__name__}, not its log-likelihood "
                f"increment (an array of shape ({b.num},))")
        return out

    def _stage_resample(self, items, frame, record) -> None:
        for v in items:
            rule = self.rules.lookup("resample", type(self.beliefs[v]))
            info = rule(self, v, frame)
            record.resampled.setdefault(v, False)
            if info:
                record.info.setdefault(v, {}).update(info)
                record.resampled[v] = bool(info.get("resampled", False))

    def _stage_estimate(self, items, frame, record) -> None:
        for v in items:
            rule = self.rules.lookup("estimate", type(self.beliefs[v]))
            record.estimates[v] = rule(self, v, frame)
        if self._learners:
            scores = {v: self.score_at(v, record.estimates[v], frame) for v in items
                      if self.graph.factors_of(v, "likelihood")}
            for f in self._learners:
                f.update(record.estimates, scores, frame)

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


# -------------------------------------------------------------------------------------
# default rules for particle beliefs (sequential Monte Carlo)
# -------------------------------------------------------------------------------------
def _history_len(engine: Engine, variable: str) -> int:
    trans = engine.graph.factors_of(variable, "transition")
    return max(0, getattr(trans[0], "order", 1) - 1) if trans else 0


@DEFAULT_RULES.register(PriorFactor, Particles)
def _prior_particles(engine: Engine, factor, frame) -> None:
    var = factor.variables[0]
    n = engine.num_particles[var]
    x = np.asarray(factor.sample(engine.rng, n), dtype=float).reshape(n, -1)
    cls = engine.belief_type(var)
    engine.beliefs[var] = cls.uniform(x, mass=1.0, history_len=_history_len(engine, var))


@DEFAULT_RULES.register(TransitionFactor, Particles)
def _predict_particles(engine: Engine, factor, frame) -> None:
    var = factor.variables[0]
    b: Particles = engine.beliefs[var]
    if frame.camera_motion is not None:  # past states into this frame's image coordinates
        labels = engine.graph.variables[var].labels
        b = b._trusted(warp_states(b.x, labels, frame.camera_motion), b.log_weights,
                       tuple(warp_states(h, labels, frame.camera_motion) for h in b.history))
    x_new = np.asarray(factor.sample(engine.rng, b.x, *b.history), dtype=float)
    if x_new.shape != b.x.shape:
        raise ValueError(f"factor {factor.name!r}: sample() returned shape {x_new.shape}, "
                         f"expected {b.x.shape}")
    engine.beliefs[var] = b.moved(x_new, history_len=max(0, factor.order - 1))


def _check_ll(factor, ll, n: int) -> np.ndarray:
    ll = np.asarray(ll, dtype=float)
    if ll.shape != (n,):
        raise ValueError(f"factor {factor.name!r}: log_likelihood returned shape {ll.shape}, "
                         f"expected ({n},)")
    if np.isnan(ll).any():  # NaN evidence is no evidence: -inf, as Particles.reweight does
        ll = np.where(np.isnan(ll), -np.inf, ll)
    return ll


@DEFAULT_RULES.register(LikelihoodFactor, Particles)
def _weight_particles(engine: Engine, factor, frame) -> np.ndarray:
    """The factor's log-likelihood at every particle: the increment the engine applies."""
    return factor.log_likelihood(engine.beliefs[factor.variables[0]].x, frame)


@DEFAULT_RULES.register("resample", Particles)
def _resample_particles(engine: Engine, variable: str, frame) -> dict[str, Any]:
    b: Particles = engine.beliefs[variable]
    n = engine.num_particles[variable]
    if b.num != n:  # a fused mixture: always back to the variable's particle count
        engine.beliefs[variable] = b.resample(engine.rng, engine.resampler, n)
        return {"resampled": True}
    ess = b.ess
    if ess_triggered(ess, b.num, engine.ess_threshold):
        engine.beliefs[variable] = b.resample(engine.rng, engine.resampler, n)
        return {"resampled": True, "ess": ess}
    return {"resampled": False, "ess": ess}


@DEFAULT_RULES.register("estimate", Particles)
def _estimate_particles(engine: Engine, variable: str, frame) -> np.ndarray:
    return engine.beliefs[variable].mean()
