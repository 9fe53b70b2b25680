r"""Plates in the one engine: batched rules, per-replica rules, births and the track layer.

A graph with a :class:`~pgm.core.plate.Plate` declares the model of *one* target;
:class:`~pgm.inference.Engine` runs ``K`` replicas of it with the schedule it derives
for any graph, ``K`` changing as tracks start and end. This module holds what a plate
adds to that engine, and no step loop of its own:

* the replicas' state besides their beliefs (:class:`Replicas`: generators, each
  replica's view of the graph, track records); the rules for batched beliefs are
  :mod:`pgm.inference.batched`'s (all replicas in one pass, or any single-graph rule per
  replica), so everything a single graph can hold, a plate can hold;
* **births and deaths** (:func:`add`, :func:`remove`, and the ``associate`` stage,
  :func:`associate`): the replicas' boxes are matched to the frame's detections
  (Hungarian on ``1 − IoU``, :mod:`pgm.inference.tracks`); a detection that matches no
  replica starts one, its prior re-centred on the detection (``prior.born_at``), its
  templates learned from this frame and the first-frame stages run on it.

**Randomness.** Each replica owns a ``numpy.random.Generator`` (given at its birth, else
spawned from the engine's); :mod:`pgm.inference.batched` splits every batched draw over
them, so ``K = 1`` reproduces a single-graph run bit for bit.

**What is per replica.** A factor that keeps a learned state (its ``State``:
:mod:`pgm.core.learned` — a template learned in the first frame, a filter, an adaptive
offset) gets a fresh state per replica at its birth, kept in the replica's slots
(``engine.replicas.state[k]``), and the replica uses a view of the one declared factor
bound to it (``engine.factor(name, k)``): factors are never copied, and every
parameter is shared. The target's box is the bounding box of the
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
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from pgm.core.batched import BatchedGaussian, BatchedParticles, batched_type
from pgm.core.beliefs import Particles
from pgm.core.boxes import (
    bounding_box,
    box_coding,
    cxcywh_to_xywh,
    iou_matrix,
    iou_xywh,
    place_parts,
    state_boxes,
)
from pgm.core.factor import Factor
from pgm.core.frame import FrameContext
from pgm.core.graph import FactorGraph
from pgm.core.motion import warp_states
from pgm.core.readout import Targets, register_readout
from pgm.factors import LikelihoodFactor

from . import batched as _batched  # noqa: F401  (registers the batched rules)
from .association import detection_boxes  # (and the exact Kalman replicas' rules)
from .batched import box_columns, score_group  # noqa: F401  (box_columns: re-exported)
from .context import RuleContext
from .engine import Engine, StepRecord
from .info import Info, realigned
from .record import register_runtime
from .single import SingleGraph
from .state import StateSlots
from .tracks import Track, confirm_tracks, existences, match, reported, update_tracks

if TYPE_CHECKING:
    from pgm.core.plate import Lifecycle, Plate

__all__ = ["Replicas", "plate_boxes", "add", "remove", "associate", "setup", "step",
           "step_stages", "learn"]


# -------------------------------------------------------------------------------------
# boxes of a plate model
# -------------------------------------------------------------------------------------
def plate_boxes(graph: FactorGraph, estimates: dict[str, np.ndarray]) -> np.ndarray:
    """The targets' boxes ``(K, 4)`` (cx, cy, w, h): the bounding box of the output
    variables' boxes in ``estimates`` (each ``(K, d)``; any box coding of
    :data:`pgm.core.boxes.BOX_CODINGS`)."""
    return bounding_box([state_boxes(graph.variables[v].labels, estimates[v],
                                  f"plate variable {v!r}") for v in graph.output])


# -------------------------------------------------------------------------------------
# the replicas
# -------------------------------------------------------------------------------------
@dataclass
class Replicas:
    """What a plate keeps per replica besides its beliefs (which live in
    ``engine.beliefs`` as batched beliefs): its generator, its view of the graph (shared
    factors, those that learn bound to its own learned state), its track record, the
    state rules keep across frames (``state``: :class:`~pgm.inference.state.StateSlots`)
    and its latest estimates ``est`` (variable → ``(K, d)``)."""

    rngs: list[np.random.Generator | None] = field(default_factory=list)
    graphs: list[FactorGraph] = field(default_factory=list)
    tracks: list[Track] = field(default_factory=list)
    state: list[StateSlots] = field(default_factory=list)
    est: dict[str, np.ndarray] = field(default_factory=dict)
    #: where a replica born without a generator (None in ``rngs``: a plate of exact
    #: Gaussian beliefs draws nothing) gets one, spawned when first asked for
    parent: np.random.Generator | None = None

    @property
    def K(self) -> int:  # noqa: N802 - the plate's size is called K
        return len(self.rngs)

    def generators(self) -> list[np.random.Generator]:
        """Every replica's generator (those not made yet spawned now from ``parent``)."""
        missing = [k for k, g in enumerate(self.rngs) if g is None]
        if missing:
            for k, g in zip(missing, self.parent.spawn(len(missing)), strict=True):
                self.rngs[k] = g
        return self.rngs

    def select(self, idx: np.ndarray) -> Replicas:
        pick = lambda xs: [xs[i] for i in idx]  # noqa: E731
        return Replicas(pick(self.rngs), pick(self.graphs), pick(self.tracks), pick(self.state),
                        {v: a[idx] for v, a in self.est.items()}, self.parent)

    def join(self, other: Replicas) -> Replicas:
        est = {v: np.concatenate([self.est[v], other.est[v]]) if v in self.est else other.est[v]
               for v in other.est}
        return Replicas(self.rngs + other.rngs, self.graphs + other.graphs,
                        self.tracks + other.tracks, self.state + other.state, est,
                        self.parent or other.parent)


@dataclass
class PlateSpec:
    """What an engine derives once from a plate declaration."""

    plate: Plate
    template: FactorGraph  # factors as declared (their states: fresh per new replica)
    local: list[str]  # factors with a learned state (each replica binds its own)
    learners: list[str]
    boxed: bool  # the output variables are boxes (births from detections possible)
    reference_box: np.ndarray | None
    prior_boxes: dict[str, np.ndarray]
    next_id: int = 1
    lazy_rngs: bool = False


def setup(engine: Engine) -> None:
    """Check a plate graph and give ``engine`` its plate and (empty) replicas."""
    g = engine.graph
    plate = engine.plate = g.plates[0]
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
    for f in g.factors.values():
        if type(f).State is None and f.kind != "prior" and (
                f.learns or (isinstance(f, LikelihoodFactor) and
                             type(f).initialize is not LikelihoodFactor.initialize)):
            raise ValueError(f"factor {f.name!r} ({type(f).__name__}) learns from the video "
                             f"but declares no State: in a plate each replica learns into "
                             f"its own, so declare what it learns as a State dataclass "
                             f"(pgm.core.learned)")
    # each replica keeps its own state of the factors that keep one (bound views)
    local = [f.name for f in g.factors.values() if f.kind != "prior" and f.state is not None]
    engine.plate_spec = PlateSpec(plate, copy.deepcopy(g), local,
                                  [f.name for f in g.factors.values() if f.learns], boxed,
                                  reference, {v: state_boxes(g.variables[v].labels, m)
                                              for v, m in means.items()})
    engine.replicas = Replicas(parent=engine.rng)
    engine.beliefs = _empty_beliefs(engine)
    # a plate whose beliefs are all exact (Gaussian, noise) draws no random numbers: its
    # replicas get their generators only if a rule asks (Replicas.generators)
    engine.plate_spec.lazy_rngs = all(
        engine.belief_type(v) is not BatchedParticles for v in g.variables)


def _has_box(graph: FactorGraph, variable: str) -> bool:
    return box_coding(graph.variables[variable].labels) is not None


def _empty_beliefs(engine: Engine) -> dict[str, Any]:
    out = {}
    for v, var in engine.graph.variables.items():
        bt = engine.belief_type(v)
        if bt is BatchedParticles:
            tr = engine.graph.factors_of(v, "transition")
            out[v] = BatchedParticles.empty(engine.num_particles[v], var.dim,
                                            max(0, getattr(tr[0], "order", 1) - 1) if tr else 0)
        elif bt is BatchedGaussian:
            out[v] = BatchedGaussian.empty(var.dim)
        else:
            out[v] = bt.stack([])
    return out


def _replica_graph(engine: Engine, values: dict[str, dict[str, float]] | None,
                   slots: StateSlots) -> FactorGraph:
    """A replica's view of the graph: the shared factors, those that learn bound to the
    replica's own learned state (made here, fresh, in its ``slots``: the factors are not
    copied), and its priors re-centred on its birth box (``values``)."""
    spec = engine.plate_spec
    g = object.__new__(type(engine.graph))  # a shallow copy (copy.copy, without its overhead)
    g.__dict__.update(engine.graph.__dict__)
    factors = dict(engine.graph.factors)
    for name in spec.local:
        declared = spec.template.factors[name]
        factors[name] = declared.bind(slots.hold(name, declared.fresh_state()))
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
    return place_parts(box, spec.reference_box, spec.prior_boxes)


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
    if rngs is None:
        rngs = [None] * m if spec.lazy_rngs else engine.rng.spawn(m)
    rngs = list(rngs)
    if len(rngs) != m:
        raise ValueError(f"{m} replicas but {len(rngs)} generators")
    if m == 0:
        return []
    tracks = [Track(s) for s in states]
    if not engine.plate.lifecycle.birth_counts:  # matches are counted after the birth
        for t in tracks:
            t.hits = t.streak = 0
    if confirmed:
        for t in tracks:
            t.track_id = spec.next_id
            spec.next_id += 1
    slots = [StateSlots() for _ in range(m)]
    newborn = Replicas(rngs, [_replica_graph(engine, v, s) for v, s in zip(values, slots,
                                                                          strict=True)],
                       tracks, slots, parent=engine.rng)
    # newborns: their own first frame, on a context of their own (no detection was
    # assigned to them)
    ctx = engine.ctx.newborn(newborn)
    rec = StepRecord(frame=frame.index)
    engine._run(engine.schedule.first_frame, frame, rec, hooks=False,
                skip=("interaction", "associate"), ctx=ctx)
    born = ctx.beliefs
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
    """The engine's frame for a plate graph (:func:`step_stages` run to its end)."""
    for _ in step_stages(engine, frame, record, lifecycle):
        pass


def step_stages(engine: Engine, frame: FrameContext, record: StepRecord, lifecycle: bool
                ) -> Iterator[tuple[str, StepRecord]]:
    """The engine's frame for a plate graph: the schedule on the replicas there are, then
    the ``associate`` stage, yielding after each stage whose hooks run. A frame with
    neither image nor detections is *missing*: the replicas are only predicted (no
    weighting, learning, resampling, births or deaths)."""
    reps = engine.replicas
    missing = frame.image is None and frame.detections is None and frame.measurements is None
    if reps.K:
        if missing:
            yield from engine._run_stages(engine.schedule.phases[:1], frame, record)
            for v in engine.graph.variables:
                rule = engine.rules.lookup("estimate", type(engine.beliefs[v]))
                record.estimates[v] = rule(engine.ctx, v, frame)
            reps.est = dict(record.estimates)
        else:
            yield from engine._run_stages(engine.schedule.phases, frame, record,
                                          skip=("associate",))
    elif not missing:  # no replica yet: the association still reads the frame's detections
        # (a score model learned on the video sees every frame; births read mapped scores)
        engine._run([p for p in engine.schedule.phases if p[0] == "assign"], frame, record,
                    hooks=False)
    info = record.plate_info()
    if lifecycle and not missing:
        yield from engine._run_stages([("associate", [engine.plate.name])], frame, record)
    info.missing = missing
    reps = engine.replicas
    record.estimates = {v: reps.est.get(v, np.zeros((0, engine.graph.variables[v].dim)))
                        for v in engine.graph.variables}
    lc = engine.plate.lifecycle
    boxes = (plate_boxes(engine.graph, reps.est) if reps.K and engine.plate_spec.boxed
             else np.zeros((reps.K, 4)))
    shown = reported(reps.tracks, lc.max_coast)
    if lc.report != "estimate":  # only where matched: the detection's box, or the estimate
        matched = np.array([t.matched for t in reps.tracks], dtype=bool)
        shown &= matched
        located = np.array([t.located for t in reps.tracks], dtype=bool)  # matched too
        if lc.report == "detection" and located.any():  # a presence match: the estimate
            boxes = boxes.copy()
            boxes[located] = [t.state for t in reps.tracks if t.located]
    info.ids = np.array([t.track_id or 0 for t in reps.tracks], dtype=np.int64)
    info.boxes, info.reported, info.existence = boxes, shown, existences(reps.tracks)
    if lc.fill_gaps or lc.fill_births:
        info.filled = _filled_gaps(reps.tracks, frame.index, boxes, shown, info.existence,
                                   lc, frame.camera_motion)


def _filled_gaps(tracks: list[Track], index: int, boxes: np.ndarray, shown: np.ndarray,
                 existence: np.ndarray, lc: Lifecycle, camera: np.ndarray | None = None
                 ) -> tuple | None:
    """The rows of earlier frames that the replicas reported in frame ``index`` fill
    (:attr:`~pgm.core.plate.Lifecycle.fill_gaps`), with the replica's existence now.

    A replica reported again after a gap of at most ``lc.fill_gaps`` frames fills it once
    it has been matched ``lc.fill_after`` frames in a row since (default
    ``confirm_hits``: a gap closed on a single match may have been closed on a false
    detection). The gap's boxes lie on the line between the two boxes that bound it in
    the world the camera sees: both are taken to the coordinates of the frame before the
    gap through the camera's image motions of the gap's frames (``camera``: this frame's,
    None: still), interpolated there and moved into each frame's own coordinates (also
    in the frames it had a detection but was not reported, recovering: interpolation
    between two reported boxes measured better than the estimates of a recovery's first
    matches). With ``lc.fill_births`` a replica reported for the first time also
    reports the frames it was tentative in, with the boxes estimated then. A gap
    is not filled when another replica's reported boxes overlap the replica's by more
    than ``lc.birth_iou`` at both of its ends: the two are on one object (a second box
    on it that survived the birth rule), and what the gap misses, the other reported.
    None when there are no rows.

    Every replica remembers the frames and boxes it reported lately (the last
    ``fill_gaps + 2`` of them), the camera's motions since its latest, the frames and
    boxes of a birth in progress, and rows waiting to be reported (dropped when it is
    not reported before they are)."""
    longest = lc.fill_gaps
    after = lc.confirm_hits if lc.fill_after is None else lc.fill_after
    held_most = max(lc.confirm_hits, longest + 1)
    frames, ids, filled, scores = [], [], [], []
    motion = _homogeneous(camera)  # shared, never written to
    for k, t in enumerate(tracks):
        if t.last_reported is not None and len(t.gap_motions) <= longest + 1:
            t.gap_motions.append(motion)
        last = t.last_reported
        if not shown[k]:
            t.pending_gap = None
            if lc.fill_births and last is None and (t.matched or t.age == 1):
                # a birth in progress: its frames and boxes, reported if it is confirmed
                t.held = (t.held + [(index, np.array(boxes[k], dtype=float))])[-held_most:]
            continue
        found = np.array(boxes[k], dtype=float)
        if last is None:
            if t.held:  # confirmed: the frames it was tentative
                at = np.array([f for f, _ in t.held], dtype=np.int64)
                t.pending_gap = (at, np.array([b for _, b in t.held]), None)
        elif 1 < index - last[0] <= longest + 1:
            start, before = last
            t.pending_gap = (np.arange(start + 1, index, dtype=np.int64),
                             _gap_boxes(before, found, t.gap_motions),
                             (start, before, index, found))
        t.gap_motions, t.held = [], []
        t.recent_reports = (t.recent_reports + [(index, found)])[-(longest + 2):]
    for k, t in enumerate(tracks):
        if not shown[k] or t.pending_gap is None:
            continue
        at, gap_boxes, ends = t.pending_gap
        if ends is not None and t.streak < after:
            continue
        t.pending_gap = None
        if ends is not None and _shared(*ends, [o for o in tracks if o is not t],
                                        lc.birth_iou):
            continue
        frames.append(at)
        ids.append(np.full(len(at), t.track_id, dtype=np.int64))
        filled.append(gap_boxes)
        scores.append(np.full(len(at), existence[k]))
    if not frames:
        return None
    return (np.concatenate(frames).astype(np.int64), np.concatenate(ids),
            np.concatenate(filled), np.concatenate(scores))


def _shared(start: int, before: np.ndarray, end: int, found: np.ndarray, others: list[Track],
            most: float) -> bool:
    """Whether one of ``others`` reported boxes overlapping ``before`` at frame ``start``
    and ``found`` at frame ``end`` (centre boxes) by IoU above ``most``."""
    if most >= 1.0:
        return False
    for o in others:
        seen = dict((f, b) for f, b in o.recent_reports if f in (start, end))
        if len(seen) == 2 and iou_matrix(np.array([before, found]),
                                         np.array([seen[start], seen[end]])
                                         ).diagonal().min() > most:
            return True
    return False


_BOX_LABELS = ("cx", "cy", "w", "h")


def _homogeneous(affine: np.ndarray | None) -> np.ndarray:
    """The image motion ``affine`` ``(2, 3)`` as a ``3 × 3`` matrix (None: the identity)."""
    out = np.eye(3)
    if affine is not None:
        out[:2] = affine
    return out


def _gap_boxes(before: np.ndarray, after: np.ndarray, motions: list[np.ndarray]
               ) -> np.ndarray:
    """The boxes ``(cx, cy, w, h)`` of a gap's frames between ``before`` (the frame before
    the gap) and ``after`` (the frame after it), ``motions`` the camera's image motions
    ``3 × 3`` of the gap's frames and the one after: linear in the first frame's
    coordinates, each then moved into its own frame's."""
    gap = len(motions)
    # to_frame[j]: the first frame's coordinates to those of the gap's j-th frame (1-based)
    to_frame = [np.eye(3)]
    for m in motions:
        to_frame.append(m @ to_frame[-1])
    back = np.linalg.inv(to_frame[-1])[:2]
    found = warp_states(after[None], _BOX_LABELS, back)[0]
    w = (np.arange(1, gap) / gap)[:, None]
    line = (1.0 - w) * before + w * found
    return np.concatenate([warp_states(line[j - 1:j], _BOX_LABELS, to_frame[j][:2])
                           for j in range(1, gap)]) if gap > 1 else np.zeros((0, 4))


def _explained_tentative(tracks: list[Track], rows: np.ndarray, cols: np.ndarray,
                         iou: np.ndarray, det_boxes: np.ndarray, scores: np.ndarray,
                         lc: Lifecycle) -> np.ndarray:
    """Which replicas ``(K,)`` are tentative and matched to a detection a confirmed replica
    explains (:attr:`~pgm.core.plate.Lifecycle.explain_tentative`): the birth rule
    applied to every match of a track not yet confirmed."""
    confirmed = np.array([t.track_id is not None for t in tracks], dtype=bool)
    out = np.zeros(len(tracks), dtype=bool)
    if not confirmed.any():
        return out
    tentative = [(k, j) for k, j in zip(rows, cols, strict=True) if not confirmed[k]]
    if not tentative:
        return out
    ks, js = np.array(tentative).T
    if lc.explain_tentative == "prediction":  # its detection overlaps a confirmed prediction
        out[ks] = (iou[np.ix_(confirmed, js)] > lc.birth_iou).any(axis=0)
        return out
    # "detection": its detection overlaps a higher-scored one a confirmed replica was given
    held = np.array([j for k, j in zip(rows, cols, strict=True) if confirmed[k]], dtype=int)
    if len(held):
        over = _iou(det_boxes[js][:, None, :], det_boxes[held][None, :, :]) > lc.birth_iou
        out[ks] = (over & (scores[held][None, :] > scores[js][:, None])).any(axis=1)
    return out


def learn(ctx: RuleContext, items: list[str], frame: FrameContext, record: StepRecord) -> None:
    """After the estimate stage: every replica's learning factors are updated with its
    estimates and scores (as a single-graph engine updates its own)."""
    reps = ctx.replicas
    reps.est = {v: np.asarray(record.estimates[v]) for v in items}
    learners = ctx.plate_spec.learners
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
    (:func:`pgm.inference.tracks.match` on ``1 − IoU``; or, in a graph with an
    association factor, the assignment its ``assign`` stage made before the
    likelihoods), the track life cycle of the plate's :class:`~pgm.core.plate.Lifecycle`,
    births from the detections no replica explains."""
    spec = engine.plate_spec
    info = record.plate_info()
    reps = engine.replicas
    lc = engine.plate.lifecycle
    assignment = engine.assignment
    if assignment is not None:  # the assign stage matched the replicas' predictions
        det_boxes, scores = assignment.boxes, assignment.scores
        rows, cols = assignment.rows, assignment.cols
        iou = assignment.iou
    else:
        dets = frame.detections
        if dets is None or not spec.boxed:
            det_boxes, scores = np.zeros((0, 4)), np.zeros(0)
        else:
            det_boxes, scores = detection_boxes(frame), np.asarray(dets.scores, dtype=float)
        boxes = plate_boxes(engine.graph, reps.est) if reps.K and spec.boxed else np.zeros((0, 4))
        iou = _iou(boxes[:, None, :], det_boxes[None, :, :])
        rows, cols = match(-iou, iou >= lc.match_iou,
                           [t.misses > lc.max_coast for t in reps.tracks])
    for t in reps.tracks:
        t.matched = t.located = False
        t.age += 1
    update = np.ones(len(rows), dtype=bool) if assignment is None or \
        assignment.update is None else assignment.update
    for k, j, u in zip(rows, cols, update, strict=True):
        if u:  # a presence match (a round with "update": false) keeps the last box
            reps.tracks[k].state = det_boxes[j].copy()
        reps.tracks[k].matched, reps.tracks[k].located = True, bool(u)
    keep = update_tracks(reps.tracks, rows, confirm_hits=lc.confirm_hits,
                         max_coast=lc.max_coast, max_lost=lc.max_lost,
                         hit_log_odds=lc.hit_log_odds, miss_log_odds=lc.miss_log_odds,
                         recover_hits=lc.recover_hits, tentative_lost=lc.tentative_lost)
    if lc.explain_tentative != "none" and len(rows):
        keep &= ~_explained_tentative(reps.tracks, rows, cols, iou, det_boxes, scores, lc)
    if engine.t <= lc.warmup_frames:  # the video's first frames: matched means confirmed
        for k in rows:
            t = reps.tracks[k]
            t.recovering = False
            if t.track_id is None:
                t.track_id = spec.next_id
                spec.next_id += 1
    spec.next_id = confirm_tracks([t for t, k in zip(reps.tracks, keep, strict=True) if k],
                                  lc.confirm_hits, spec.next_id, on=lc.confirm_on)
    used = set(cols.tolist())
    overlap = lc.birth_iou < 1.0
    free = [j for j in range(len(det_boxes)) if j not in used
            and scores[j] >= lc.birth_min_score
            and (not overlap or not reps.K or iou[:, j].max() < lc.birth_iou)]
    # the free detections must not overlap each other either (one birth per person)
    births: list[int] = []
    for j in sorted(free, key=lambda j: -scores[j]):
        if not overlap or all(_iou(det_boxes[j], det_boxes[i]) < lc.birth_iou for i in births):
            births.append(j)
    info.deaths = np.array([reps.tracks[k].track_id or 0 for k in np.flatnonzero(~keep)],
                           dtype=np.int64)
    if births or not keep.all():
        _keep(engine, np.flatnonzero(keep))
        # the frame's per-replica diagnostics follow the replicas (births: none yet)
        for per_variable in (record.ess, record.log_evidence, record.resampled):
            per_variable.update(realigned(per_variable, keep, len(births)))
        for name, values in record.info.items():
            if isinstance(values, Info):
                realigned(values, keep, len(births))
            elif isinstance(values, dict):
                record.info[name] = realigned(values, keep, len(births))
    info.births = len(births)
    if births:
        first = lc.activate_first and engine.t == 0  # the first frame's births: confirmed
        new = add(engine, det_boxes[sorted(births)], frame, confirmed=first)
        if first:  # and reported now, with their birth boxes
            for k in new:
                engine.replicas.tracks[k].matched = engine.replicas.tracks[k].located = True

def _iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of centre boxes ``a`` and ``b``, broadcasting over the leading axes."""
    return iou_xywh(cxcywh_to_xywh(a), cxcywh_to_xywh(b))

@register_readout("plate")
def plate_targets(graph: FactorGraph, record: StepRecord) -> Targets:
    """The replicas an engine step reports for a plate (confirmed, not lost): identities,
    boxes and existence scores (the ``"plate"`` readout)."""
    info = record.plate
    keep = info.reported
    filled = None
    if info.filled is not None:
        f, i, b, c = info.filled
        filled = Targets(i, cxcywh_to_xywh(b), c, frames=f)
    return Targets(info.ids[keep], cxcywh_to_xywh(info.boxes[keep]),
                   info.existence[keep], text=f"{int(keep.sum())} targets", filled=filled)


class PlateRuntime(SingleGraph):
    """How the engine runs a plate graph: the module's :func:`setup`, :func:`step`,
    :func:`learn`, :func:`associate`, :func:`add` and :func:`remove` on ``K`` replicas
    whose beliefs are batched (the engine's step loop and stages are a single graph's)."""

    predicts_missing_frames = True
    group_scoring = "replicas"  # the replicas' views of a factor scored together

    setup = staticmethod(setup)
    step_stages = staticmethod(step_stages)
    learn = staticmethod(learn)
    associate = staticmethod(associate)
    add = staticmethod(add)
    remove = staticmethod(remove)
    score_group = staticmethod(score_group)

    def belief_type(self, engine: Engine, variable: str, row_type: type) -> type:
        if issubclass(row_type, Particles) and row_type is not Particles:
            raise ValueError(f"variable {variable!r}: a plate keeps Particles batched "
                             f"(BatchedParticles); {row_type.__name__} has no batched form "
                             f"(give it one and register its rules, or use Particles)")
        return batched_type(row_type)

    def finish(self, engine: Engine, record: StepRecord) -> None:
        pass

    def graphs(self, ctx: RuleContext) -> list[FactorGraph]:
        return ctx.replicas.graphs

    def state_slots(self, ctx: RuleContext) -> list[StateSlots]:
        return ctx.replicas.state

    def normalize(self, ctx: RuleContext, variable: str, belief, before):
        """Normalised; a replica no particle of which explains the frame keeps its
        prediction ``before`` (second: which replicas did)."""
        return belief.normalized(fallback=before)

    def num_targets(self, engine: Engine) -> int:
        return engine.replicas.K

    def tracks(self, engine: Engine) -> list:
        return list(engine.replicas.tracks)

    def factor(self, engine: Engine, name: str, replica: int | None) -> Factor:
        if replica is None:
            return engine.graph.factors[name]
        return engine.replicas.graphs[replica].factors[name]


register_runtime(lambda graph: bool(graph.plates), PlateRuntime())
