"""The generic engine: one per-frame schedule derived from the graph, rules by dispatch.

A frame's step (DESIGN.md):

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

DESIGN.md lists in-frame passes before weighting; both fusion rules of SPEC §2 need
each part's local evidence first (a message carries its source's likelihood), so the
weight stage comes first here.

The first frame replaces *predict* by *prior*: each variable's belief is drawn from its
prior factor and likelihood factors may learn from the frame (e.g. a colour template at
the prior mean) before it is weighted.

Every stage dispatches through a :class:`RuleTable` keyed by ``(operation, belief
type)`` — ``operation`` is a factor kind (``prior``, ``transition``, ``likelihood``,
``coupling``, ``conjugate``) or a belief operation (``resample``, ``estimate``) — and
the lookup walks the belief type's MRO, so a subclass (e.g. :class:`~pgm.Intensity`)
inherits rules it does not override. The engine never knows which model it runs:
particle BP, VB and the PHD corrector are rules registered in this table.

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
from pgm.core.expfam import InverseGamma
from pgm.core.frame import FrameContext
from pgm.core.graph import FactorGraph
from pgm.factors import Factor

from .resampling import ess_triggered, get_resampler

__all__ = ["Engine", "RuleTable", "DEFAULT_RULES", "StepRecord", "Schedule", "derive_schedule",
           "STAGES", "BELIEF_FOR_ROLE"]

STAGES = ("prior", "predict", "weight", "inframe", "fuse", "estimate", "resample")
OPERATIONS = ("prior", "transition", "likelihood", "coupling", "conjugate", "fuse", "resample",
              "estimate")
FUSIONS = ("mixture", "product")

#: belief type the engine creates for each variable role (override per variable with
#: ``options={"belief_types": {name: type}}``, e.g. :class:`~pgm.core.expfam.Gaussian` for an
#: exact Kalman / VB adaptive Kalman filter)
BELIEF_FOR_ROLE: dict[str, type] = {"part": Particles, "state": Particles,
                                    "latent": Particles, "set": Intensity,
                                    "noise": InverseGamma}

Rule = Callable[..., Any]


class RuleTable:
    """Inference rules keyed by ``(operation, belief type)``, looked up along the MRO.

    Factor rules are called as ``rule(engine, factor, frame)`` and update
    ``engine.beliefs``; coupling rules as ``rule(engine, factor, frame, src, dst)`` (one
    directed message); belief rules (``fuse``, ``resample``, ``estimate``) as
    ``rule(engine, variable_name, frame)``. A rule may return a dict of diagnostics,
    stored in the step record under the factor's (or variable's) name.
    """

    def __init__(self, rules: dict[tuple[str, type], Rule] | None = None):
        self._rules: dict[tuple[str, type], Rule] = dict(rules or {})
        self._resolved: dict[tuple[str, type], Rule] = {}

    def register(self, operation: str, belief_type: type) -> Callable[[Rule], Rule]:
        """Decorator registering ``rule`` for ``(operation, belief_type)``."""
        if operation not in OPERATIONS:
            raise ValueError(f"unknown operation {operation!r} (expected one of {OPERATIONS})")

        def deco(rule: Rule) -> Rule:
            self._rules[(operation, belief_type)] = rule
            self._resolved.clear()
            return rule

        return deco

    def lookup(self, operation: str, belief_type: type) -> Rule:
        """The rule for ``operation`` on the nearest registered base of ``belief_type``."""
        hit = self._resolved.get((operation, belief_type))
        if hit is not None:
            return hit
        for t in belief_type.__mro__:
            rule = self._rules.get((operation, t))
            if rule is not None:
                self._resolved[(operation, belief_type)] = rule
                return rule
        raise ValueError(f"no inference rule for ({operation!r}, {belief_type.__name__}): "
                         f"register one with RuleTable.register")

    def has(self, operation: str, belief_type: type) -> bool:
        """Whether :meth:`lookup` would succeed."""
        return any((operation, t) in self._rules for t in belief_type.__mro__)

    def remove(self, operation: str, belief_type: type) -> None:
        """Drop the rule registered exactly for ``(operation, belief_type)``."""
        self._rules.pop((operation, belief_type), None)
        self._resolved.clear()

    def copy(self) -> RuleTable:
        """An independent copy (to add rules for one engine only)."""
        return RuleTable(self._rules)

    def __repr__(self) -> str:
        keys = ", ".join(f"({op}, {t.__name__})" for op, t in self._rules)
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
    num_particles : int or dict, optional
        Particles per variable (one int for all, or name → int). Default:
        ``graph.meta["engine"]["num_particles"]``, else 100.
    resampling : str or callable
        ``"systematic"`` (default), ``"multinomial"``, ``"stratified"``, ``"residual"``.
    ess_threshold : float
        Resample when ESS < ``ess_threshold`` × N (0.5 default; 1 = every frame).
    inframe_iterations : int
        Flooding rounds of the in-frame phase on loopy graphs (trees need one sweep).
    fusion : {"mixture", "product"}, optional
        Particle-BP fusion rule (:mod:`pgm.inference.pbp`); default
        ``graph.meta["engine"]["fusion"]``, else ``"mixture"``.
    rules : RuleTable, optional
        Defaults to :data:`DEFAULT_RULES`.
    options : dict, optional
        Extra settings read by rules (e.g. particle-BP fusion), merged over
        ``graph.meta["engine"]``.
    """

    def __init__(self, graph: FactorGraph, rng: np.random.Generator, *,
                 num_particles: int | dict[str, int] | None = None,
                 resampling: str | Callable = "systematic", ess_threshold: float = 0.5,
                 inframe_iterations: int | None = None, fusion: str | None = None,
                 rules: RuleTable | None = None, options: dict[str, Any] | None = None):
        if not isinstance(graph, FactorGraph):
            raise ValueError(f"Engine needs a FactorGraph, got {type(graph).__name__}")
        if not isinstance(rng, np.random.Generator):
            raise ValueError("Engine needs rng=numpy.random.Generator (e.g. "
                             "numpy.random.default_rng(seed))")
        self.graph = copy.deepcopy(graph)
        self.rng = rng
        defaults = dict(self.graph.meta.get("engine", {}))
        self.options: dict[str, Any] = {**defaults, **(options or {})}
        if num_particles is None:
            num_particles = self.options.get("num_particles", 100)
        self.num_particles = self._particle_counts(num_particles)
        self.resampler = get_resampler(resampling)
        if not np.isfinite(ess_threshold) or not 0.0 <= ess_threshold <= 1.0:
            raise ValueError(f"ess_threshold must be in [0, 1], got {ess_threshold}")
        self.ess_threshold = float(ess_threshold)
        self.rules = rules if rules is not None else DEFAULT_RULES
        if fusion is not None:
            self.options["fusion"] = fusion
        self.options.setdefault("fusion", "mixture")
        if inframe_iterations is None:
            inframe_iterations = int(self.options.get("inframe_iterations", 1))
        self.schedule = derive_schedule(self.graph, inframe_iterations, self.options["fusion"])
        self.beliefs: dict[str, Any] = {}
        #: per variable, this frame's ``(prior_log_weights, log_likelihood)`` (weight stage)
        self.evidence: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        #: this frame's messages ``(src, dst) -> message`` (in-frame stage)
        self.messages: dict[tuple[str, str], Any] = {}
        #: per-variable state that rules keep across frames (PHD tracks, extraction, ...)
        self.aux: dict[str, dict[str, Any]] = {}
        self._learners = [f for f in self.graph.factors.values() if f.learns]
        self._groups_cache: dict[tuple, list[list[str]]] = {}
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
            counts = {n: num_particles.get(n, self.options.get("num_particles", 100))
                      for n in names}
        else:
            counts = {n: num_particles for n in names}
        for n, c in counts.items():
            if isinstance(c, bool) or not isinstance(c, (int, np.integer)) or c < 1:
                raise ValueError(f"number of particles for {n!r} must be a positive integer, "
                                 f"got {c!r}")
        return {n: int(c) for n, c in counts.items()}

    def belief_type(self, variable: str) -> type:
        """Belief class of a variable (from its role)."""
        role = self.graph.variables[variable].role
        bt = self.options.get("belief_types", {}).get(variable) or BELIEF_FOR_ROLE.get(role)
        if bt is None:
            raise ValueError(f"variable {variable!r}: no belief type for role {role!r} in this "
                             f"engine")
        return bt

    def _factor_belief_type(self, factor: Factor) -> type:
        for v in factor.variables:
            if self.graph.variables[v].role != "noise":
                return self.belief_type(v)
        return self.belief_type(factor.variables[0])

    def _check_rules(self) -> None:
        """Fail at construction, naming the factor, if some stage has no rule."""
        factor_stages = ("prior", "predict", "inframe", "weight")
        for phases in (self.schedule.first_frame, self.schedule.phases):
            for stage, items in phases:
                for item in items:
                    if stage in factor_stages:
                        f = self.graph.factors[item[0] if isinstance(item, tuple) else item]
                        bt = self._factor_belief_type(f)
                        if not self.rules.has(f.kind, bt):
                            raise ValueError(f"factor {f.name!r}: no inference rule for "
                                             f"({f.kind!r}, {bt.__name__}) in this engine")
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
        rule = self.rules.lookup(f.kind, self._factor_belief_type(f))
        info = rule(self, f, frame)
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
                rule = self.rules.lookup(f.kind, self.belief_type(dst))
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

    def _weight_groups(self, items) -> list[list[str]]:
        """Likelihood factors grouped by ``batch_key`` (scored in one pass when possible)."""
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
            self._groups_cache[key] = groups
        return groups

    def _stage_weight(self, items, frame, record) -> None:
        before = {v: self.beliefs[v] for v in self.beliefs
                  if isinstance(self.beliefs[v], Particles)}
        weighted: list[str] = []
        for group in self._weight_groups(items):
            fs = [self.graph.factors[n] for n in group]
            vs = [f.variables[0] for f in fs]
            batchable = len(fs) > 1 and all(
                self.rules.lookup("likelihood", type(self.beliefs[v])) is _weight_particles
                for v in vs)
            if batchable:
                lls = type(fs[0]).log_likelihood_batch(fs, [self.beliefs[v].x for v in vs],
                                                       frame)
                for f, v, ll in zip(fs, vs, lls, strict=True):
                    _check_ll(f, ll, self.beliefs[v].num)
                    self.beliefs[v] = self.beliefs[v].reweight(ll)
            else:
                for name in group:
                    self._apply_factor(name, frame, record)
            for f in fs:
                for v in f.variables:
                    if v in before and v not in weighted:
                        weighted.append(v)
        for v in weighted:
            b, b0 = self.beliefs[v], before[v]
            if isinstance(b, Intensity):
                continue  # a set's update is not a reweighting: no evidence/ESS here
            log_lik = b.log_weights - b0.log_weights
            if not b0.log_weights.min() > -np.inf:  # a zero-weight prior particle
                with np.errstate(invalid="ignore"):
                    log_lik = np.where(np.isfinite(b0.log_weights), log_lik, -np.inf)
            self.evidence[v] = (b0.log_weights, log_lik)
            record.log_evidence[v] = b.log_mass - b0.log_mass
            record.ess[v] = b.ess
            if not isinstance(b, Intensity):
                self.beliefs[v] = b.normalized()

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


@DEFAULT_RULES.register("prior", Particles)
def _prior_particles(engine: Engine, factor, frame) -> None:
    var = factor.variables[0]
    n = engine.num_particles[var]
    x = np.asarray(factor.sample(engine.rng, n), dtype=float).reshape(n, -1)
    cls = engine.belief_type(var)
    engine.beliefs[var] = cls.uniform(x, mass=1.0, history_len=_history_len(engine, var))


@DEFAULT_RULES.register("transition", Particles)
def _predict_particles(engine: Engine, factor, frame) -> None:
    var = factor.variables[0]
    b: Particles = engine.beliefs[var]
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
    return ll


@DEFAULT_RULES.register("likelihood", Particles)
def _weight_particles(engine: Engine, factor, frame) -> None:
    var = factor.variables[0]
    b: Particles = engine.beliefs[var]
    engine.beliefs[var] = b.reweight(_check_ll(factor, factor.log_likelihood(b.x, frame), b.num))


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
