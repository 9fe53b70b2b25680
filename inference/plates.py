r"""Plates in the one engine: batched rules, per-replica rules, births and the track layer.

A graph with a :class:`~pgm.core.plate.Plate` declares the model of *one* target;
:class:`~pgm.inference.Engine` runs ``K`` replicas of it with the schedule it derives
for any graph, ``K`` changing as tracks start and end. This module holds what a plate
adds to that engine, and no step loop of its own:

* **batched rules**, registered in :data:`~pgm.inference.DEFAULT_RULES` for
  :class:`~pgm.core.batched.BatchedParticles` (``(K, N, d)`` particles): a transition
  shared by the replicas samples the ``K·N`` particles in one call of
  ``factor.sample``; a shared likelihood scores them in one call, and per-target
  templates are scored together by ``log_likelihood_batch`` (one pass per cluster of
  overlapping replicas); interaction factors (mutual exclusion) reweight every replica
  against the others' estimates; mixture messages of particle BP, fusion, estimates
  and ESS-triggered resampling act on all replicas at once;
* :func:`per_replica`, which runs any single-graph rule once per replica where no
  batched rule is registered — VB noise per target, product fusion, exact Gaussian
  rules, a user's own rule — so everything a single graph can hold, a plate can hold;
* **births and deaths** (:func:`add`, :func:`remove`, and the ``associate`` stage,
  :func:`associate`): the replicas' boxes are matched to the frame's detections
  (Hungarian on ``1 − IoU``, :mod:`pgm.inference.tracks`); a detection that matches no
  replica starts one, its prior re-centred on the detection (``prior.born_at``), its
  templates learned from this frame and the first-frame stages run on it.

**Randomness.** Each replica owns a ``numpy.random.Generator`` (given at its birth, else
spawned from the engine's), and a batched draw of shape ``(K·N, ...)`` is made of ``K``
draws of shape ``(N, ...)``, one from each replica's generator (:class:`ReplicaRNG`).
A replica therefore consumes its stream exactly as a single-graph run of the same graph
would: ``K = 1`` reproduces that run bit for bit, and ``K`` replicas without interaction
reproduce ``K`` separate runs (tested). A factor whose ``sample``/``propagate`` draws
numbers whose leading axis is not the particle count cannot be split this way and is
refused with its name.

**What is per replica.** A factor that learns, or a likelihood that learns a template
from the first frame, is copied per replica at its birth (``engine.factor(name, k)``);
every other factor's parameters are shared. The target's box is the bounding box of the
output variables' boxes; new replicas' part boxes are placed relative to the detection as
the prior means of the declaration are placed relative to ``graph.meta["reference_box"]``
(default: the bounding box of the output variables' prior means).

Example
-------
>>> import numpy as np
>>> from pgm.inference import Engine
>>> from pgm.models import multi_pf
>>> g = multi_pf.build_graph(multi_pf.Params(num_particles=30))
>>> engine = Engine(g, rng=np.random.default_rng(0))
>>> engine.num_targets
0
"""

from __future__ import annotations

import copy
import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from pgm.core.batched import BatchedParticles, batched_type
from pgm.core.boxes import cxcywh_to_xywh, iou_xywh
from pgm.core.frame import FrameContext
from pgm.core.graph import FactorGraph
from pgm.core.motion import warp_states
from pgm.core.readout import Targets, register_readout
from pgm.factors import CouplingFactor, LikelihoodFactor, TransitionFactor
from pgm.factors.plates import InteractionFactor

from .engine import Engine, StepRecord
from .pbp import MixtureMessage, coupling_message, fuse
from .resampling import ess_triggered
from .rules import DEFAULT_RULES
from .tracks import Track, match_boxes

if TYPE_CHECKING:
    from pgm.core.plate import Plate

__all__ = ["ReplicaRNG", "Replicas", "plate_boxes", "per_replica", "add", "remove",
           "associate", "BatchedMixtureMessage"]

_BOX = ("cx", "cy", "w", "h")


# -------------------------------------------------------------------------------------
# randomness split over replicas
# -------------------------------------------------------------------------------------
class ReplicaRNG:
    """A ``Generator`` look-alike whose draws split over replicas.

    A draw of ``size = (K·n, ...)`` is made of ``K`` draws of ``(n, ...)``, the ``k``-th
    from ``generators[k]``; array arguments (``loc``, ``scale``, ``low``, ``high``)
    whose leading axis is ``K·n`` are split the same way, others are passed to every
    replica. Only the methods the toolkit's factors use are offered.
    """

    def __init__(self, generators: Sequence[np.random.Generator], n: int,
                 owner: str = "a factor"):
        self.generators = list(generators)
        self.n = int(n)
        self.owner = owner

    @property
    def total(self) -> int:
        """``K·n``: the leading axis every draw must have."""
        return len(self.generators) * self.n

    def _sizes(self, size) -> tuple[int, ...]:
        shape = (size,) if np.ndim(size) == 0 and size is not None else tuple(size or ())
        if not shape or shape[0] != self.total:
            raise ValueError(
                f"{self.owner} drew random numbers of shape {shape}, whose leading axis is not "
                f"the particle count {self.total}; the plate engine splits draws per replica "
                f"along that axis (draw one value per particle, e.g. "
                f"rng.standard_normal((n, d)))")
        return (self.n,) + shape[1:]

    def _part(self, value, k: int):
        if np.ndim(value) > 0 and np.shape(value)[0] == self.total:
            return value[k * self.n:(k + 1) * self.n]
        return value

    def _draw(self, method: str, size, *args, out=None):
        if out is not None:
            size = out.shape
        per = self._sizes(size)
        parts = [getattr(g, method)(*(self._part(a, k) for a in args), size=per)
                 for k, g in enumerate(self.generators)]
        res = np.concatenate(parts) if parts else np.zeros((0,) + per[1:])
        if out is not None:
            out[...] = res
            return out
        return res

    def standard_normal(self, size=None, dtype=np.float64, out=None):
        """Standard normal draws, split over replicas."""
        return self._draw("standard_normal", size, out=out)

    def random(self, size=None, dtype=np.float64, out=None):
        """Uniform [0, 1) draws, split over replicas."""
        return self._draw("random", size, out=out)

    def normal(self, loc=0.0, scale=1.0, size=None):
        """Normal draws, split over replicas."""
        if size is None:
            size = np.broadcast(np.asarray(loc), np.asarray(scale)).shape
        return self._draw("normal", size, loc, scale)

    def uniform(self, low=0.0, high=1.0, size=None):
        """Uniform draws, split over replicas."""
        if size is None:
            size = np.broadcast(np.asarray(low), np.asarray(high)).shape
        return self._draw("uniform", size, low, high)

    def __getattr__(self, name: str):
        raise ValueError(f"{self.owner} calls rng.{name}(), which the plate engine cannot "
                         f"split per replica (use standard_normal, random, normal or uniform "
                         f"with one draw per particle)")


# -------------------------------------------------------------------------------------
# boxes of a plate model
# -------------------------------------------------------------------------------------
def _box_columns(graph: FactorGraph, variable: str) -> list[int]:
    """Columns of cx, cy, w, h in ``variable`` (a ``ValueError`` if it is not a box)."""
    v = graph.variables[variable]
    if v.labels is None or not all(b in v.labels for b in _BOX):
        raise ValueError(f"plate variable {variable!r} must have the labels cx, cy, w, h "
                         f"(a box), got {v.labels}")
    return [v.labels.index(b) for b in _BOX]


def _bounding(boxes: list[np.ndarray]) -> np.ndarray:
    """Bounding box ``(..., 4)`` (cx, cy, w, h) of several boxes of the same shape."""
    if len(boxes) == 1:
        return boxes[0]
    b = np.stack(boxes)
    x0 = (b[..., 0] - b[..., 2] / 2).min(0)
    x1 = (b[..., 0] + b[..., 2] / 2).max(0)
    y0 = (b[..., 1] - b[..., 3] / 2).min(0)
    y1 = (b[..., 1] + b[..., 3] / 2).max(0)
    return np.stack([(x0 + x1) / 2, (y0 + y1) / 2, x1 - x0, y1 - y0], axis=-1)


def plate_boxes(graph: FactorGraph, estimates: dict[str, np.ndarray]) -> np.ndarray:
    """The targets' boxes ``(K, 4)`` (cx, cy, w, h): the bounding box of the output
    variables' boxes in ``estimates`` (each ``(K, d)``)."""
    return _bounding([np.asarray(estimates[v])[..., _box_columns(graph, v)]
                      for v in graph.output])


# -------------------------------------------------------------------------------------
# the replicas
# -------------------------------------------------------------------------------------
@dataclass
class Replicas:
    """What a plate keeps per replica besides its beliefs (which live in
    ``engine.beliefs`` as batched beliefs): its generator, its view of the graph (shared
    factors and its own copies of those that learn), its track record, the state rules
    keep across frames (``aux``) and its latest estimates ``est`` (variable →
    ``(K, d)``)."""

    rngs: list[np.random.Generator] = field(default_factory=list)
    graphs: list[FactorGraph] = field(default_factory=list)
    tracks: list[Track] = field(default_factory=list)
    aux: list[dict] = field(default_factory=list)
    est: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def K(self) -> int:  # noqa: N802 - the plate's size is called K
        return len(self.rngs)

    def select(self, idx: np.ndarray) -> Replicas:
        pick = lambda xs: [xs[i] for i in idx]  # noqa: E731
        return Replicas(pick(self.rngs), pick(self.graphs), pick(self.tracks), pick(self.aux),
                        {v: a[idx] for v, a in self.est.items()})

    def join(self, other: Replicas) -> Replicas:
        est = {v: np.concatenate([self.est[v], other.est[v]]) if v in self.est else other.est[v]
               for v in other.est}
        return Replicas(self.rngs + other.rngs, self.graphs + other.graphs,
                        self.tracks + other.tracks, self.aux + other.aux, est)


@dataclass
class PlateSpec:
    """What an engine derives once from a plate declaration."""

    plate: Plate
    template: FactorGraph  # factors as declared: copied per new replica
    local: list[str]  # factors copied per replica (they learn per target)
    learners: list[str]
    boxed: bool  # the output variables are boxes (births from detections possible)
    reference_box: np.ndarray | None
    prior_boxes: dict[str, np.ndarray]
    next_id: int = 1


def setup(engine: Engine) -> None:
    """Check a plate graph and give ``engine`` its (empty) replicas."""
    g = engine.graph
    plate = engine.plate
    outside = [v for v in g.variables if v not in plate.variables]
    if outside:
        raise ValueError(f"graph {g.name!r}: variables {outside} are outside the plate "
                         f"{plate.name!r}; a plate graph holds every variable in its plate "
                         f"(shared parameters belong in factors)")
    for v in g.variables.values():
        if v.role == "set":
            raise ValueError(f"plate variable {v.name!r} has role 'set': a random finite set "
                             f"already holds every target; it needs no plate")
        if len(g.factors_of(v.name, "prior")) != 1:
            raise ValueError(f"plate variable {v.name!r} needs one prior factor")
    priors = g.factors_by_kind("prior")
    boxed = bool(g.output) and all(_has_box(g, v) for v in g.output)
    means = {f.variables[0]: np.asarray(f.mean(), dtype=float) for f in priors
             if _has_box(g, f.variables[0])}
    ref = g.meta.get("reference_box")
    reference = (np.asarray(ref, dtype=float) if ref is not None else
                 plate_boxes(g, {v: m[None] for v, m in means.items()})[0] if boxed else None)
    local = [f.name for f in g.factors.values() if f.kind != "prior"
             and (f.learns or (isinstance(f, LikelihoodFactor) and
                               type(f).initialize is not LikelihoodFactor.initialize))]
    engine.plate_spec = PlateSpec(plate, copy.deepcopy(g), local,
                                  [f.name for f in g.factors.values() if f.learns], boxed,
                                  reference, {v: m[_box_columns(g, v)] for v, m in means.items()})
    engine.replicas = Replicas()
    engine.beliefs = _empty_beliefs(engine)


def _has_box(graph: FactorGraph, variable: str) -> bool:
    labels = graph.variables[variable].labels
    return labels is not None and all(b in labels for b in _BOX)


def _empty_beliefs(engine: Engine) -> dict[str, Any]:
    out = {}
    for v, var in engine.graph.variables.items():
        bt = engine.belief_type(v)
        if bt is BatchedParticles:
            tr = engine.graph.factors_of(v, "transition")
            out[v] = BatchedParticles.empty(engine.num_particles[v], var.dim,
                                            max(0, getattr(tr[0], "order", 1) - 1) if tr else 0)
        else:
            out[v] = bt.stack([])
    return out


def _replica_graph(engine: Engine, values: dict[str, dict[str, float]] | None) -> FactorGraph:
    """A replica's view of the graph: the shared factors, its own copies of those that
    learn, and its priors re-centred on its birth box (``values``)."""
    spec = engine.plate_spec
    g = copy.copy(engine.graph)
    factors = dict(engine.graph.factors)
    for name in spec.local:
        factors[name] = copy.deepcopy(spec.template.factors[name])
    if values is not None:
        for f in engine.graph.factors_by_kind("prior"):
            v = f.variables[0]
            if v in values:
                factors[f.name] = f.born_at(values[v], g.variables[v].labels)
    g.factors = factors
    return g


def _part_values(engine: Engine, box: np.ndarray) -> dict[str, dict[str, float]]:
    """Each variable's box for a target whose box is ``box`` (cx, cy, w, h)."""
    spec = engine.plate_spec
    ref = spec.reference_box
    sw, sh = box[2] / ref[2], box[3] / ref[3]
    return {v: {"cx": box[0] + (p[0] - ref[0]) * sw, "cy": box[1] + (p[1] - ref[1]) * sh,
                "w": p[2] * sw, "h": p[3] * sh} for v, p in spec.prior_boxes.items()}


def add(engine: Engine, boxes: np.ndarray | None, frame: FrameContext,
        rngs: Sequence[np.random.Generator] | None = None, confirmed: bool = False,
        count: int | None = None) -> list[int]:
    """Start replicas on ``boxes`` ``(M, 4)`` (cx, cy, w, h) in ``frame``.

    Each replica's prior is re-centred on its box (``boxes=None``: ``count`` replicas
    from the priors as declared); the engine's first-frame stages run on the new
    replicas (prior, templates learned from ``frame``, weight, in-frame, fuse, estimate,
    resample), as a single-graph engine treats its first frame. ``rngs`` gives each
    replica its generator (default: spawned from the engine's); ``confirmed`` starts them
    with identities (targets given by the user). Returns their indices."""
    if engine.plate is None:
        raise ValueError(f"graph {engine.graph.name!r} declares no plate: it has no replicas")
    if not isinstance(frame, FrameContext):
        raise ValueError(f"add() needs a FrameContext, got {type(frame).__name__}")
    spec = engine.plate_spec
    if boxes is None:
        m = 1 if count is None else int(count)
        values: list[dict | None] = [None] * m
        states = [np.full(4, np.nan)] * m
    else:
        if not spec.boxed:
            raise ValueError(f"graph {engine.graph.name!r}: the output variables are not boxes "
                             f"(cx, cy, w, h); start replicas with boxes=None")
        boxes = np.asarray(boxes, dtype=float).reshape(-1, 4)
        if not np.all(np.isfinite(boxes)) or np.any(boxes[:, 2:] <= 0):
            raise ValueError("replica boxes must be finite with positive width and height")
        m = len(boxes)
        values = [_part_values(engine, b) for b in boxes]
        states = [b.copy() for b in boxes]
    rngs = list(engine.rng.spawn(m) if rngs is None else rngs)
    if len(rngs) != m:
        raise ValueError(f"{m} replicas but {len(rngs)} generators")
    if m == 0:
        return []
    tracks = [Track(s) for s in states]
    if confirmed:
        for t in tracks:
            t.track_id = spec.next_id
            spec.next_id += 1
    newborn = Replicas(rngs, [_replica_graph(engine, v) for v in values], tracks,
                       [{} for _ in range(m)])
    saved = engine.beliefs, engine.replicas, engine.evidence, engine.messages
    engine.beliefs, engine.replicas, engine.evidence, engine.messages = {}, newborn, {}, {}
    rec = StepRecord(frame=frame.index)
    try:
        engine._run(engine.schedule.first_frame, frame, rec, hooks=False,
                    skip=("interaction", "associate"))
        born = engine.beliefs
    finally:
        engine.beliefs, engine.replicas, engine.evidence, engine.messages = saved
    first = engine.replicas.K
    for v, b in born.items():
        engine.beliefs[v] = engine.beliefs[v].concat(b)
    newborn.est = dict(rec.estimates)
    engine.replicas = engine.replicas.join(newborn)
    return list(range(first, first + m))


def remove(engine: Engine, indices: Sequence[int]) -> None:
    """Remove the replicas at ``indices``."""
    keep = np.ones(engine.num_targets, dtype=bool)
    keep[np.asarray(list(indices), dtype=int)] = False
    _keep(engine, np.flatnonzero(keep))


def _keep(engine: Engine, idx: np.ndarray) -> None:
    engine.beliefs = {v: b.select(idx) for v, b in engine.beliefs.items()}
    engine.replicas = engine.replicas.select(idx)


# -------------------------------------------------------------------------------------
# one frame
# -------------------------------------------------------------------------------------
def step(engine: Engine, frame: FrameContext, record: StepRecord, lifecycle: bool) -> None:
    """The engine's frame for a plate graph: the schedule on the replicas there are, then
    the ``associate`` stage. A frame with neither image nor detections is *missing*: the
    replicas are only predicted (no weighting, learning, resampling, births or deaths)."""
    reps = engine.replicas
    missing = frame.image is None and frame.detections is None and frame.measurements is None
    if reps.K:
        if missing:
            engine._run(engine.schedule.phases[:1], frame, record)
            for v in engine.graph.variables:
                rule = engine.rules.lookup("estimate", type(engine.beliefs[v]))
                record.estimates[v] = rule(engine, v, frame)
            reps.est = dict(record.estimates)
        else:
            engine._run(engine.schedule.phases, frame, record, skip=("associate",))
    info = record.info.setdefault(engine.plate.name, {})
    if lifecycle and not missing:
        engine._run([("associate", [engine.plate.name])], frame, record)
    info["missing"] = missing
    reps = engine.replicas
    record.estimates = {v: reps.est.get(v, np.zeros((0, engine.graph.variables[v].dim)))
                        for v in engine.graph.variables}
    lc = engine.plate.lifecycle
    info.update(
        ids=np.array([t.track_id or 0 for t in reps.tracks], dtype=np.int64),
        boxes=(plate_boxes(engine.graph, reps.est) if reps.K and engine.plate_spec.boxed
               else np.zeros((reps.K, 4))),
        reported=np.array([t.track_id is not None and t.misses <= lc.max_coast
                           and not t.recovering for t in reps.tracks], dtype=bool),
        existence=np.array([t.existence for t in reps.tracks], dtype=float))


def learn(engine: Engine, items: list[str], frame: FrameContext, record: StepRecord) -> None:
    """After the estimate stage: every replica's learning factors are updated with its
    estimates and scores (as a single-graph engine updates its own)."""
    reps = engine.replicas
    reps.est = {v: np.asarray(record.estimates[v]) for v in items}
    learners = engine.plate_spec.learners
    if not learners:
        return
    for k in range(reps.K):
        g = reps.graphs[k]
        est = {v: reps.est[v][k] for v in items}
        scores = {}
        for v in items:
            fs = g.factors_of(v, "likelihood")
            if fs:
                x = np.asarray(est[v], dtype=float).reshape(1, -1)
                total = np.zeros(1)
                for f in fs:
                    total = total + f.log_likelihood(x, frame)
                scores[v] = float(total[0])
        for name in learners:
            g.factors[name].update(est, scores, frame)


def associate(engine: Engine, frame: FrameContext, record: StepRecord) -> None:
    """The ``associate`` stage: the replicas' boxes against the frame's detections
    (:func:`pgm.inference.tracks.match_boxes`), the track life cycle of the plate's
    :class:`~pgm.core.plate.Lifecycle`, births from the detections no replica explains."""
    spec = engine.plate_spec
    info = record.info.setdefault(engine.plate.name, {})
    dets = frame.detections
    if dets is None or not spec.boxed:
        det_boxes, scores = np.zeros((0, 4)), np.zeros(0)
    else:
        d = np.asarray(dets.boxes, dtype=float).reshape(-1, 4)
        det_boxes = np.column_stack([d[:, 0] + d[:, 2] / 2, d[:, 1] + d[:, 3] / 2,
                                     d[:, 2], d[:, 3]])
        scores = np.asarray(dets.scores, dtype=float)
    reps = engine.replicas
    lc = engine.plate.lifecycle
    boxes = plate_boxes(engine.graph, reps.est) if reps.K and spec.boxed else np.zeros((0, 4))
    iou = _iou(boxes[:, None, :], det_boxes[None, :, :])
    matched = match_boxes(iou, [t.misses > lc.max_coast for t in reps.tracks], lc.match_iou)
    keep = np.ones(reps.K, dtype=bool)
    for k, t in enumerate(reps.tracks):
        t.age += 1
        if k in matched:
            if t.misses > lc.max_coast and t.track_id is not None:
                t.recovering, t.streak = True, 0
            t.hit(lc.confirm_hits, lc.hit_log_odds)
            t.state = det_boxes[matched[k]].copy()
        else:
            t.miss(lc.miss_log_odds)
            if t.track_id is None or t.misses > lc.max_lost:
                keep[k] = False
        if t.track_id is None and t.hits >= lc.confirm_hits and keep[k]:
            t.track_id = spec.next_id
            spec.next_id += 1
    used = set(matched.values())
    free = [j for j in range(len(det_boxes)) if j not in used
            and scores[j] >= lc.birth_min_score
            and (not reps.K or iou[:, j].max() < lc.birth_iou)]
    # the free detections must not overlap each other either (one birth per person)
    births: list[int] = []
    for j in sorted(free, key=lambda j: -scores[j]):
        if all(_iou(det_boxes[j], det_boxes[i]) < lc.birth_iou for i in births):
            births.append(j)
    info["deaths"] = np.array([reps.tracks[k].track_id or 0 for k in np.flatnonzero(~keep)],
                              dtype=np.int64)
    _keep(engine, np.flatnonzero(keep))
    # the frame's per-replica diagnostics follow the replicas (births: none yet)
    for per_variable, fill in ((record.ess, np.nan), (record.log_evidence, np.nan),
                               (record.resampled, False)):
        for v, a in per_variable.items():
            if isinstance(a, np.ndarray) and a.shape == keep.shape:
                per_variable[v] = np.concatenate([a[keep], np.full(len(births), fill,
                                                                   dtype=a.dtype)])
    info["births"] = len(births)
    if births:
        add(engine, det_boxes[sorted(births)], frame)


# -------------------------------------------------------------------------------------
# single-graph rules, once per replica
# -------------------------------------------------------------------------------------
class _ReplicaView:
    """Replica ``k`` of a plate engine as a single-graph rule sees an engine: its own
    beliefs (rows of the batched beliefs), generator, graph, evidence, messages and
    ``aux``; everything else is the engine's."""

    log_likelihood = Engine.log_likelihood
    score_at = Engine.score_at
    factor_belief_type = Engine.factor_belief_type
    rule_for = Engine.rule_for

    def __init__(self, engine: Engine, k: int):
        self._engine = engine
        reps = engine.replicas
        self.replica = k
        self.graph = reps.graphs[k]
        self.rng = reps.rngs[k]
        self.aux = reps.aux[k]
        self.rows = {v: b.row(k) for v, b in engine.beliefs.items()}
        self.beliefs = dict(self.rows)
        self.evidence = {v: (a[k], ll[k]) for v, (a, ll) in engine.evidence.items()}
        self.message_rows = {key: m.row(k) for key, m in engine.messages.items()}
        self.messages = dict(self.message_rows)

    def __getattr__(self, name: str):
        return getattr(self._engine, name)

    def belief_type(self, variable: str) -> type:
        return self._engine.row_belief_type(variable)


class RowMessages:
    """Messages of one directed edge, one per replica (from a per-replica rule)."""

    def __init__(self, items: Sequence[Any]):
        self.items = list(items)

    def row(self, k: int) -> Any:
        return self.items[k]


def _merge(outs: list[Any]) -> Any:
    """The replicas' returns of one rule as one value: arrays stacked ``(K, ...)``, dicts
    merged key by key, ``None`` where every replica returned ``None``."""
    if all(o is None for o in outs):
        return None
    if all(isinstance(o, dict) for o in outs):
        keys = list(dict.fromkeys(k for o in outs for k in o))
        return {k: _merge([o.get(k) for o in outs]) for k in keys}
    if all(isinstance(o, (np.ndarray, float, int, bool, np.number, np.bool_)) for o in outs):
        try:
            return np.stack([np.asarray(o) for o in outs])
        except ValueError:  # shapes differ
            return list(outs)
    return list(outs)


@functools.cache
def per_replica(rule: Callable, key: type | str) -> Callable:
    """``rule`` (a single-graph rule for the replica's belief type) run once per replica:
    on each replica's view of the engine (its rows of the batched beliefs, its generator,
    its factor copies), writing the rows it changes back into the batched beliefs. Its
    returns are merged (likelihood increments stacked to ``(K, N)``)."""
    operation = isinstance(key, str)

    def run(engine: Engine, item, frame: FrameContext, *args: Any) -> Any:
        reps = engine.replicas
        outs, views = [], []
        for k in range(reps.K):
            view = _ReplicaView(engine, k)
            target = item if operation else view.graph.factors[item.name]
            outs.append(rule(view, target, frame, *args))
            views.append(view)
        if not views:
            return None
        for v in dict.fromkeys(v for view in views for v in view.beliefs):
            if any(view.beliefs.get(v) is not view.rows.get(v) for view in views):
                engine.beliefs[v] = engine.belief_type(v).stack([view.beliefs[v]
                                                                 for view in views])
        for m in dict.fromkeys(m for view in views for m in view.messages):
            if any(view.messages.get(m) is not view.message_rows.get(m) for view in views):
                engine.messages[m] = RowMessages([view.messages[m] for view in views])
        return _merge(outs)

    run.__qualname__ = f"per_replica({getattr(rule, '__qualname__', rule)})"
    run.row_rule = rule
    return run


# -------------------------------------------------------------------------------------
# batched rules (all replicas at once)
# -------------------------------------------------------------------------------------
def _local(engine: Engine, name: str) -> bool:
    return name in engine.plate_spec.local


@DEFAULT_RULES.register(TransitionFactor, BatchedParticles)
def predict_batched(engine: Engine, factor, frame: FrameContext) -> None:
    """Move every replica's particles: one ``factor.sample`` call on ``(K·N, d)`` for a
    shared transition (draws split per replica), one call per replica for its own copy."""
    var = factor.variables[0]
    b: BatchedParticles = engine.beliefs[var]
    reps = engine.replicas
    K, n, d = b.x.shape  # noqa: N806
    flat = b.x.reshape(K * n, d)
    past = [h.reshape(K * n, d) for h in b.history]
    if frame.camera_motion is not None:  # past states into this frame's image coordinates
        labels = engine.graph.variables[var].labels
        flat = warp_states(flat, labels, frame.camera_motion)
        past = [warp_states(h, labels, frame.camera_motion) for h in past]
    if _local(engine, factor.name):  # a transition that learns per target: one call each
        new = np.concatenate([np.asarray(reps.graphs[k].factors[factor.name].sample(
            reps.rngs[k], flat[k * n:(k + 1) * n], *(h[k * n:(k + 1) * n] for h in past)),
            dtype=float) for k in range(K)])
    else:
        rng = ReplicaRNG(reps.rngs, n, owner=f"transition {factor.name!r}")
        new = np.asarray(factor.sample(rng, flat, *past), dtype=float)
    if new.shape != flat.shape:
        raise ValueError(f"factor {factor.name!r}: sample() returned shape {new.shape}, "
                         f"expected {flat.shape}")
    n_hist = max(0, getattr(factor, "order", 1) - 1)
    engine.beliefs[var] = BatchedParticles._trusted(
        new.reshape(K, n, d), b.log_weights,
        tuple(a.reshape(K, n, d) for a in ([flat] + past)[:n_hist]))


@DEFAULT_RULES.register(LikelihoodFactor, BatchedParticles)
def weight_batched(engine: Engine, factor, frame: FrameContext) -> np.ndarray:
    """``(K, N)`` log-likelihood increments of every replica's particles."""
    return score_group(engine, [factor], frame)[0]


def score_group(engine: Engine, fs: list, frame: FrameContext) -> list[np.ndarray]:
    """``(K, N)`` log-likelihoods of each factor of one weight group ``fs`` (equal
    ``batch_key``)."""
    reps = engine.replicas
    K = reps.K  # noqa: N806
    local = [_local(engine, f.name) for f in fs]
    if K * len(fs) > 1 and fs[0].batch_key is not None and all(local):
        # the copies of the group's factors scored together, one pass per cluster of
        # replicas whose particles' boxes overlap (a joint pass costs the area of its
        # boxes' union, so distant targets are not scored through the empty space
        # between them); replica-major, so that one replica's order is the
        # single-graph engine's
        out = [np.empty(engine.beliefs[f.variables[0]].log_weights.shape) for f in fs]
        for members in _clusters(_extents(engine, fs)):
            copies = [reps.graphs[k].factors[f.name] for k in members for f in fs]
            xs = [engine.beliefs[f.variables[0]].x[k] for k in members for f in fs]
            lls = type(fs[0]).log_likelihood_batch(copies, xs, frame)
            for i, ll in enumerate(lls):
                out[i % len(fs)][members[i // len(fs)]] = ll
        return out
    out = []
    for f, own in zip(fs, local, strict=True):
        x = engine.beliefs[f.variables[0]].x
        _, n, d = x.shape
        if not own:  # shared: all replicas' particles in one call
            out.append(np.asarray(f.log_likelihood(x.reshape(K * n, d), frame),
                                  dtype=float).reshape(K, n))
        else:
            out.append(np.stack([np.asarray(reps.graphs[k].factors[f.name].log_likelihood(
                x[k], frame), dtype=float) for k in range(K)]))
    return out


def _extents(engine: Engine, fs: list) -> np.ndarray:
    """``(K, 4)`` rectangles ``x0, y0, x1, y1`` around every particle's box of the
    group ``fs`` in each replica."""
    lo, hi = [], []
    for f in fs:
        v = f.variables[0]
        bx = engine.beliefs[v].x[..., _box_columns(engine.graph, v)]  # (K, N, 4)
        lo.append((bx[..., :2] - np.abs(bx[..., 2:]) / 2).min(axis=1))
        hi.append((bx[..., :2] + np.abs(bx[..., 2:]) / 2).max(axis=1))
    return np.concatenate([np.min(lo, axis=0), np.max(hi, axis=0)], axis=1)


@DEFAULT_RULES.register(InteractionFactor, BatchedParticles)
def interact_batched(engine: Engine, factor, frame: FrameContext) -> None:
    """Reweight every replica's particles against the other replicas' current estimates
    (a replica the potential leaves with no finite weight keeps its weights)."""
    v = factor.variables[0]
    b: BatchedParticles = engine.beliefs[v]
    if b.K < 2:
        return
    pot = np.asarray(factor.log_potential(b.x, b.mean(), frame), dtype=float)
    engine.beliefs[v], _ = b.reweight(pot).normalized(fallback=b)
    if v in engine.evidence:
        lw0, ll = engine.evidence[v]
        engine.evidence[v] = (lw0, ll + pot)


def _batched_mixture(engine: Engine) -> bool:
    s = engine.settings
    return s.fusion == "mixture" and s.message_weight == "source" and not s.message_particles


@dataclass(frozen=True)
class BatchedMixtureMessage:
    """Mixture messages of all replicas: ``x`` ``(K, M, d)``, log-weights ``(K, M)`` on
    the common scale, histories ``(K, M, d)``."""

    x: np.ndarray
    log_weights: np.ndarray
    history: tuple[np.ndarray, ...]

    def row(self, k: int) -> MixtureMessage:
        return MixtureMessage(self.x[k], self.log_weights[k], tuple(h[k] for h in self.history))


def _evidence(engine: Engine, v: str) -> tuple[np.ndarray, np.ndarray]:
    b = engine.beliefs[v]
    return engine.evidence.get(v, (b.log_weights, np.zeros_like(b.log_weights)))


@DEFAULT_RULES.register(CouplingFactor, BatchedParticles)
def coupling_batched(engine: Engine, factor, frame: FrameContext, src: str, dst: str):
    """The message ``src → dst`` of every replica (mixture with source weights batched;
    any other setting per replica, :func:`pgm.inference.pbp.coupling_message`)."""
    if not _batched_mixture(engine):
        return per_replica(coupling_message, CouplingFactor)(engine, factor, frame, src, dst)
    reps = engine.replicas
    b = engine.beliefs[src]
    K, n, d = b.x.shape  # noqa: N806
    flat = b.x.reshape(K * n, d)
    if _local(engine, factor.name):
        x_msg = np.concatenate([np.asarray(reps.graphs[k].factors[factor.name].propagate(
            reps.rngs[k], flat[k * n:(k + 1) * n], src)) for k in range(K)])
    else:
        x_msg = np.asarray(factor.propagate(ReplicaRNG(reps.rngs, n,
                                                       owner=f"coupling {factor.name!r}"),
                                            flat, src), dtype=float)
    d_dst = engine.beliefs[dst].dim
    x_msg = x_msg.reshape(K, n, d_dst)
    n_hist = len(engine.beliefs[dst].history)
    hist = [np.asarray(factor.map(h.reshape(K * n, d), src)).reshape(K, n, d_dst)
            for h in b.history[:n_hist]]
    hist += [x_msg.copy() for _ in range(n_hist - len(hist))]
    lw0, ll = _evidence(engine, src)
    engine.messages[(src, dst)] = BatchedMixtureMessage(x_msg, lw0 + ll, tuple(hist))
    return None


def _row_log_normalize(lw: np.ndarray) -> np.ndarray:
    """Per-row :func:`pgm.core.numerics.log_normalize` (the same arithmetic per row)."""
    lw = np.where(np.isnan(lw), -np.inf, lw)
    shifted = lw - lw.max(axis=1, keepdims=True)
    e = np.exp(shifted)
    return shifted - np.array([math.log(float(row.sum())) for row in e])[:, None]


@DEFAULT_RULES.register("fuse", BatchedParticles)
def fuse_batched(engine: Engine, variable: str, frame: FrameContext) -> dict:
    """Every replica's own weighted particles joined with its incoming mixture messages
    (product fusion: per replica, :func:`pgm.inference.pbp.fuse`)."""
    if not _batched_mixture(engine):
        return per_replica(fuse, "fuse")(engine, variable, frame)
    b: BatchedParticles = engine.beliefs[variable]
    lw0, ll = _evidence(engine, variable)
    incoming = [m for (_, dst), m in engine.messages.items() if dst == variable]
    lw = _row_log_normalize(np.concatenate([lw0 + ll] + [m.log_weights for m in incoming],
                                           axis=1))
    x = np.concatenate([b.x] + [m.x for m in incoming], axis=1)
    hist = tuple(np.concatenate([h] + [m.history[i] for m in incoming], axis=1)
                 for i, h in enumerate(b.history))
    engine.beliefs[variable] = BatchedParticles._trusted(x, lw, hist, log_mass=np.zeros(b.K))
    return {"own_mass": np.array([float(np.exp(row[:b.num]).sum()) for row in lw])}


@DEFAULT_RULES.register("estimate", BatchedParticles)
def estimate_batched(engine: Engine, variable: str, frame: FrameContext) -> np.ndarray:
    """``(K, d)`` weighted means."""
    return engine.beliefs[variable].mean()


@DEFAULT_RULES.register("resample", BatchedParticles)
def resample_batched(engine: Engine, variable: str, frame: FrameContext) -> dict[str, Any]:
    """ESS-triggered resampling per replica, each with its own generator (a fused
    mixture: every replica back to the variable's particle count)."""
    b: BatchedParticles = engine.beliefs[variable]
    n = engine.num_particles[variable]
    ess = b.ess
    if b.num != n:
        rows = np.arange(b.K)
    else:
        rows = np.array([k for k in range(b.K)
                         if ess_triggered(float(ess[k]), b.num, engine.ess_threshold)], int)
    engine.beliefs[variable] = b.resample_rows(engine.replicas.rngs, engine.resampler, n, rows)
    return {"resampled": np.isin(np.arange(b.K), rows), "ess": ess}


def _iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of centre boxes ``a`` and ``b``, broadcasting over the leading axes."""
    return iou_xywh(cxcywh_to_xywh(a), cxcywh_to_xywh(b))


def _clusters(rects: np.ndarray) -> list[list[int]]:
    """Groups of indices of rectangles ``(K, 4)`` (x0, y0, x1, y1) connected by overlap,
    each group in increasing order, groups by their first member."""
    k = len(rects)
    if k == 0:
        return []
    ov = ((rects[:, None, 0] < rects[None, :, 2]) & (rects[None, :, 0] < rects[:, None, 2])
          & (rects[:, None, 1] < rects[None, :, 3]) & (rects[None, :, 1] < rects[:, None, 3]))
    from scipy.sparse.csgraph import connected_components

    _, label = connected_components(ov, directed=False)
    groups: dict[int, list[int]] = {}
    for i, lab in enumerate(label.tolist()):
        groups.setdefault(lab, []).append(i)
    return sorted(groups.values(), key=lambda g: g[0])



@register_readout("plate")
def plate_targets(graph: FactorGraph, record: StepRecord) -> Targets:
    """The replicas a plate engine's step reports (confirmed, not lost): identities,
    boxes and existence scores (the ``"plate"`` readout)."""
    info = record.info[graph.plates[0].name]
    keep = info["reported"]
    return Targets(info["ids"][keep], cxcywh_to_xywh(info["boxes"][keep]),
                   info["existence"][keep], text=f"{int(keep.sum())} targets")
