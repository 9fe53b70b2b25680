"""Exact Kalman replicas and data association: the rules of tracking by detection.

The rules the engine applies to a plate whose box state holds a
:class:`~pgm.core.batched.BatchedGaussian` (``Engine(..., belief_types={"box":
Gaussian})``; the factors are :mod:`pgm.factors.association`'s):

* **predict** — :class:`~pgm.factors.LinearGaussianTransition` on every replica at once,
  ``m ← F m``, ``P ← F P Fᵀ + Q`` (a SORT ``cx, cy, s, r`` state whose area would turn
  non-positive has its area rate set to zero first, as SORT does); when the frame
  carries the camera's image motion, the states are moved through it
  (:func:`pgm.core.motion.linear_state_warp`: ``m ← T m + c``, ``P ← T P Tᵀ``), before
  the predict or after it and the whole box or its centre only, as the
  :class:`~pgm.factors.association.BoxTransition` says (``camera``, ``camera_order``);
* **assign** — :class:`~pgm.factors.association.DetectionAssociation`: the predicted boxes
  against the frame's detections, Hungarian assignment on IoU (or on IoU × score, or on
  the buffered IoU), round by round, each round on its pool of replicas (all, confirmed,
  tracked, lost or tentative) (:class:`Assignment`, kept as ``ctx.assignment`` for the
  frame);
* **weight** — :class:`~pgm.factors.association.AssignedDetectionLikelihood`: the Kalman
  update of each assigned replica with its detection (Joseph form), batched;
  with a :class:`~pgm.factors.multitarget.VBNoise` factor on it, the VB adaptive Kalman
  filter of Feng et al. (2015) (each replica its own inverse-Gamma measurement noise) instead;
* **estimate** — the means; no resampling.

The lifecycle (``associate`` stage, :mod:`pgm.inference.plates`) reads the assignment.

The Kalman and VB adaptive Kalman updates are :mod:`pgm.inference.kalman`'s (one each).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.batched import BatchedGaussian, BatchedInverseGamma, BatchedParticles
from pgm.core.boxes import box_coding, encode_boxes, iou_matrix, state_boxes
from pgm.core.frame import FrameContext
from pgm.core.motion import linear_state_warp
from pgm.core.resolution import appearance_matrix, learn_all
from pgm.factors import GaussianPrior, LinearGaussianTransition
from pgm.factors.association import (
    APPEARANCE,
    IOU_AFFINITY,
    LEARNED_SCORE_MAPS,
    MOMENTUM,
    AssignedDetectionLikelihood,
    DetectionAssociation,
    RoundPlan,
)
from pgm.factors.multitarget import VBNoise, vb_likelihood_refusal
from pgm.factors.persistent_quantiles import PLACED_SCORE_MAPS

from .association_terms import (
    AssociationInputs,
    PieceValues,
    direction_consistency,
)
from .batched import per_replica
from .context import RuleContext
from .info import AssociationInfo, DetectionInfo
from .kalman import kalman_update_batch, vb_akf_batch
from .rules import RuleTable
from .vb import _vb_gaussian

__all__ = ["Assignment", "assign", "detection_boxes", "iou_matrix",
           "direction_consistency", "ObservationHistory"]

#: the rules of this family (:func:`pgm.inference.default_rules` gathers every family's)
RULES = RuleTable()


@dataclass
class Assignment:
    """A frame's detections given to a plate's replicas.

    Attributes
    ----------
    rows, cols : ndarray of int
        Matched replica and detection indices (round by round, each round in replica
        order).
    boxes : ndarray (M, 4)
        The frame's detection boxes, centre ``(cx, cy, w, h)``.
    scores : ndarray (M,)
        Their scores after the association's score map.
    iou : ndarray (K, M)
        IoU of each replica's predicted box with each detection.
    rounds : ndarray of int
        The round that made each match.
    update : ndarray of bool, optional
        Per match, whether its detection updates the replica (False: a match of a
        round with ``"update": false``, which only keeps the replica matched); None: all.
    """

    rows: np.ndarray
    cols: np.ndarray
    boxes: np.ndarray
    scores: np.ndarray
    iou: np.ndarray
    rounds: np.ndarray
    update: np.ndarray | None = None

    def updating(self) -> Assignment:
        """The matches whose detections update their replicas (all without ``update``)."""
        if self.update is None:
            return self
        u = self.update
        return Assignment(self.rows[u], self.cols[u], self.boxes, self.scores, self.iou,
                          self.rounds[u])


@dataclass
class AssociationState:
    """What the association keeps across frames (``ctx.state.get(factor.name,
    AssociationState)``): the run's score model of a learned or quantile score map."""

    score_model: Any = None


@dataclass
class TrackState:
    """What the association's rules keep per replica for its box variable
    (``ctx.replicas.state[k].get(variable, TrackState)``).

    Attributes
    ----------
    observations : ObservationHistory
        Its recent detections (OC-SORT's momentum and recovery rounds).
    appearance : list
        Its appearance models, learned from the detections it is given.
    posterior : tuple
        Its last Kalman posterior ``(m, P)``, where a later gap's re-update starts.
    """

    observations: ObservationHistory | None = None
    appearance: list | None = None
    posterior: tuple[np.ndarray, np.ndarray] | None = None

    def observations_or(self, delta_t: int) -> ObservationHistory:
        """The observation history, started (with ``delta_t``) at the first call."""
        if self.observations is None:
            self.observations = ObservationHistory(delta_t)
        return self.observations


def detection_boxes(frame: FrameContext) -> np.ndarray:
    """The frame's detections as centre boxes ``(M, 4)``."""
    d = frame.detections
    if d is None:
        return np.zeros((0, 4))
    b = np.array(d.boxes, dtype=float).reshape(-1, 4)
    b[:, :2] += b[:, 2:] / 2.0
    return b


def assign(inputs: AssociationInputs, plans: list[RoundPlan],
           confirmed: np.ndarray | None = None, tracked: np.ndarray | None = None,
           owner: str = "association") -> Assignment:
    """Assign the detections of ``inputs`` (:class:`AssociationInputs`) to its predicted
    boxes in ``plans``' rounds (:attr:`~pgm.factors.association.DetectionAssociation.
    plans`): in each, the Hungarian assignment between the replicas of the round's pool
    no earlier round matched and the detections still free (mapped score in the round's
    range) maximising the round's affinity plus its weighted terms over the pairs its
    gates allow; a matched pair whose affinity is below the round's threshold is no
    match. ``confirmed`` ``(K,)``: which replicas have an identity, ``tracked`` ``(K,)``:
    which were matched in the previous frame (a round's pool:
    :data:`~pgm.factors.association.TRACK_POOLS`)."""
    from scipy.optimize import linear_sum_assignment

    pred, boxes, scores = inputs.pred, inputs.boxes, inputs.scores
    K, M = len(pred), len(boxes)  # noqa: N806
    iou = iou_matrix(pred, boxes) if K and M else np.zeros((K, M))
    values = PieceValues(inputs, owner)
    values.seed({"fn": IOU_AFFINITY, "args": {}}, iou)
    if len(plans) == 1 and plans[0].plain and K and M:
        # SORT's one round over every detection: the assignment, gated (the loop below
        # gives the same, with more bookkeeping)
        a, b = linear_sum_assignment(iou, maximize=True)
        ok = iou[a, b] >= plans[0].threshold
        return Assignment(a[ok], b[ok], boxes, scores, iou, np.zeros(int(ok.sum()), dtype=int))
    free = np.ones(K, dtype=bool)
    unused = np.ones(M, dtype=bool)
    rows: list[np.ndarray] = []
    cols: list[np.ndarray] = []
    made: list[np.ndarray] = []
    for i, plan in enumerate(plans):
        ks = np.flatnonzero(free & _pool(plan.tracks, K, confirmed, tracked))
        js = np.flatnonzero(unused & (scores >= plan.min_score) & (scores < plan.max_score))
        if not len(ks) or not len(js):
            continue
        sub = None if len(ks) == K and len(js) == M else np.ix_(ks, js)
        part = functools.partial(_part, sub)
        gate = part(values(plan.affinity, "affinity"))
        cost = gate
        for t in plan.terms:
            if t["weight"]:
                cost = cost + t["weight"] * part(values(t, "term"))
        mask = None
        for g in plan.gates:
            ok = part(values(g, "gate")).astype(bool)
            mask = ok if mask is None else mask & ok
        if mask is not None:  # a pair a gate forbids is never taken
            cost = np.where(mask, cost, -1e9)
        a, b = linear_sum_assignment(cost, maximize=True)
        ok = gate[a, b] >= plan.threshold
        if mask is not None:
            ok &= mask[a, b]
        rows.append(ks[a[ok]])
        cols.append(js[b[ok]])
        made.append(np.full(int(ok.sum()), i))
        free[ks[a[ok]]] = False
        unused[js[b[ok]]] = False
    cat = lambda xs: np.concatenate(xs) if xs else np.zeros(0, dtype=int)  # noqa: E731
    return Assignment(cat(rows), cat(cols), boxes, scores, iou, cat(made))


def _part(sub: tuple | None, value: np.ndarray) -> np.ndarray:
    return value if sub is None else value[sub]


def _pool(tracks: str, K: int, confirmed: np.ndarray | None,  # noqa: N803
          tracked: np.ndarray | None) -> np.ndarray | bool:
    """The mask ``(K,)`` of the replicas in a round's pool ``tracks`` (True: all)."""
    if tracks == "all":
        return True
    if confirmed is None or (tracks in ("tracked", "lost") and tracked is None):
        raise ValueError(f"a round on the {tracks} tracks needs the replicas' status "
                         f"(confirmed, tracked)")
    confirmed = np.asarray(confirmed, dtype=bool).reshape(K)
    if tracks == "confirmed":
        return confirmed
    if tracks == "tentative":
        return ~confirmed
    tracked = np.asarray(tracked, dtype=bool).reshape(K)
    return confirmed & tracked if tracks == "tracked" else confirmed & ~tracked


@RULES.register(GaussianPrior, BatchedGaussian)
def prior_gaussians(ctx: RuleContext, factor, frame: FrameContext) -> None:
    """Each replica's prior (its own, re-centred on its birth box), stacked."""
    priors = [g.factors[factor.name] for g in ctx.replicas.graphs]
    ctx.beliefs[factor.variables[0]] = BatchedGaussian(
        np.stack([p.mean() for p in priors]), np.stack([p.cov for p in priors]))


@RULES.register(LinearGaussianTransition, BatchedGaussian)
def predict_gaussians(ctx: RuleContext, factor, frame: FrameContext) -> None:
    """``m ← F m``, ``P ← F P Fᵀ + Q`` for every replica."""
    var = factor.variables[0]
    b: BatchedGaussian = ctx.beliefs[var]
    m, P = b.m, b.P
    labels = ctx.graph.variables[var].labels
    camera = getattr(factor, "camera", "box")
    warp = None if camera == "none" else linear_state_warp(
        labels, frame.camera_motion, sizes="keep" if camera == "centre" else "scale")
    after = getattr(factor, "camera_order", "before") == "after"
    if warp is not None and not after:  # last frame's states into this frame's image
        T, c = warp
        m, P = m @ T.T + c, T @ P @ T.T
    m, P = _predict(factor, labels, m, P)
    if warp is not None and after:  # the prediction into this frame's image (BoT-SORT)
        T, c = warp
        m, P = m @ T.T + c, T @ P @ T.T
    ctx.beliefs[var] = BatchedGaussian(m, P)


def _predict(factor, labels, m: np.ndarray, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``F m``, ``F P Fᵀ + Q`` of states ``m`` ``(B, d)``, ``P`` ``(B, d, d)`` (``Q``
    scale-aware where the transition says so; an ``xysr`` state whose area would turn
    non-positive has its area rate set to zero first, as SORT does)."""
    if box_coding(labels) == "xysr" and "vs" in labels:  # keep the area positive
        s, vs = labels.index("s"), labels.index("vs")
        m = m.copy()
        m[m[:, s] + m[:, vs] <= 0, vs] = 0.0
    F = factor.F
    Q = factor.noise_cov(m) if hasattr(factor, "noise_cov") else factor.Q
    return m @ F.T, F @ P @ F.T + Q


def _means(belief) -> np.ndarray:
    """``(K, d)`` the replicas' point estimates (a Gaussian batch's means, or weighted
    particle means: the belief protocol's ``estimate()``)."""
    return belief.estimate()


@RULES.register(DetectionAssociation, BatchedParticles)
@RULES.register(DetectionAssociation, BatchedGaussian)
def assign_detections(ctx: RuleContext, factor, frame: FrameContext) -> AssociationInfo:
    """The ``assign`` stage: ``ctx.assignment`` for this frame (and, for momentum and
    recovery rounds, each replica's observation history, :class:`TrackState`). The
    replicas' predicted boxes are their means: a Kalman replica's, or a particle
    replica's weighted mean."""
    var = factor.variables[0]
    pred = state_boxes(ctx.graph.variables[var].labels, _means(ctx.beliefs[var]))
    boxes = detection_boxes(frame)
    model = None
    if factor.score_map in LEARNED_SCORE_MAPS:  # the run's score model, kept with the engine
        state = ctx.state.get(factor.name, AssociationState)
        model = state.score_model
        if model is None:
            model = state.score_model = factor.score_model()
    pools: dict[str, Any] = {}
    placed = factor.score_map in PLACED_SCORE_MAPS
    if factor.uses_pools or placed:
        # which replicas have an identity, which were matched last frame
        tracks = ctx.replicas.tracks
        pools.update(confirmed=np.array([t.track_id is not None for t in tracks], dtype=bool),
                     tracked=np.array([t.misses == 0 for t in tracks], dtype=bool))
    # "placed" learns from the predicted boxes of the tracks confirmed and matched last frame
    references = pred[pools["confirmed"] & pools["tracked"]] if placed else None
    scores = factor.scores(frame, model, boxes, references)
    fields: dict[str, Any] = {}
    if APPEARANCE in factor.term_fns:
        fields["appearance"] = _appearance(ctx, factor, frame, boxes)
    if factor.extended:  # pieces of one's own read the state beliefs and the graph
        b = ctx.beliefs[var]
        fields.update(mean=b.mean(), cov=b.cov(), labels=tuple(ctx.graph.variables[var].labels),
                      variable=var, graph=ctx.graph, frame=frame)
    histories = None
    if frame.camera_motion is not None and (factor.keeps_observations or factor.extended):
        _observations_through_camera(ctx, var, frame.camera_motion)
    if factor.keeps_observations or factor.extended:
        fields["last"] = np.array([t.state for t in ctx.replicas.tracks],
                                  dtype=float).reshape(-1, 4)
    if factor.keeps_observations:
        histories = [slots.get(var, TrackState).observations_or(factor.delta_t)
                     for slots in ctx.replicas.state]
        for h in histories:
            h.age += 1
        if MOMENTUM in factor.term_fns and len(pred) and len(boxes):
            fields["velocity"] = np.array([h.velocity if h.velocity is not None else (0.0, 0.0)
                                           for h in histories], dtype=float)
            fields["known"] = np.array([h.velocity is not None for h in histories], dtype=float)
            prev = [h.previous(h.age) for h in histories]
            fields["reference"] = np.array([fields["last"][k] if p is None else p
                                            for k, p in enumerate(prev)], dtype=float)
    a = assign(AssociationInputs(pred, boxes, scores, **fields), factor.plans,
               **(pools if factor.uses_pools else {}),
               owner=f"factor {factor.name!r}")
    if factor.presence_rounds:  # their matches keep a replica, its state left as it is
        a.update = ~np.logical_or.reduce([a.rounds == r for r in factor.presence_rounds])
    u = a.updating()
    if histories is not None:
        for k, j in zip(u.rows, u.cols, strict=True):
            histories[k].observe(boxes[j])
    if factor.appearance is not None and frame.image is not None:  # learn from the match
        _learn_appearance(ctx, factor, frame, boxes, u)
    ctx.assignment = a
    # per replica, the index of its detection (NaN: none), a float so that replicas born
    # later in the frame read NaN too
    matched = np.full(len(pred), np.nan)
    matched[a.rows] = a.cols
    presence = None
    if a.update is not None:
        presence = np.zeros(len(pred), dtype=bool)
        presence[a.rows[~a.update]] = True
    return AssociationInfo(matched=matched, presence=presence)


def _appearance(ctx: RuleContext, factor, frame: FrameContext, boxes: np.ndarray
                ) -> np.ndarray | None:
    """``(K, M)`` similarity of each replica's appearance model with each detection
    (``exp(log-likelihood / λ)`` per cue, multiplied over cues; 0 for a replica without a
    model yet), or None (no appearance, no image, no detections). Each cue scores every
    replica against every detection in one call, each detection read at the resolution it
    needs (:func:`pgm.core.resolution.appearance_matrix`)."""
    if factor.appearance is None or frame.image is None or not len(boxes):
        return None
    var = factor.variables[0]
    slots = ctx.replicas.state
    out = np.zeros((len(slots), len(boxes)))
    rows, models = [], []
    for k, slot in enumerate(slots):
        state = slot.find(var, TrackState)
        if state is not None and state.appearance is not None:
            rows.append(k)
            models.append(state.appearance)
    if not rows:
        return out
    ll = np.zeros((len(rows), len(boxes)))
    for c in range(len(models[0])):
        cue = [m[c] for m in models]
        lam = np.array([getattr(m, "lam", 1.0) for m in cue], dtype=float)[:, None]
        ll += appearance_matrix(cue, boxes, frame, factor.appearance_pixels) / lam
    out[rows] = np.exp(ll)
    return out


def _learn_appearance(ctx: RuleContext, factor, frame: FrameContext, boxes: np.ndarray,
                      a: Assignment) -> None:
    """Each matched replica's appearance models learn its detection (a replica's first
    match gives it its models), every cue in one call, on the frame at the resolution the
    detections need (as :func:`_appearance` scores them). A detection wholly outside the
    image shows nothing and teaches nothing."""
    var = factor.variables[0]
    h, w = frame.image.shape[:2]
    half = boxes[:, 2:] / 2.0
    seen = np.all((boxes[:, :2] + half > 0) & (boxes[:, :2] - half < (w, h)), axis=1)
    pairs = [(int(k), int(j)) for k, j in zip(a.rows, a.cols, strict=True) if seen[j]]
    if not pairs:
        return
    models = []
    for k, _ in pairs:
        state = ctx.replicas.state[k].get(var, TrackState)
        if state.appearance is None:
            state.appearance = factor.appearance_model()
        models.append(state.appearance)
    learned = boxes[[j for _, j in pairs]]
    for c in range(len(models[0])):
        learn_all([m[c] for m in models], frame, learned, factor.appearance_pixels)


def _observations_through_camera(ctx: RuleContext, var: str, affine: np.ndarray) -> None:
    """Each replica's last detection and observation history moved into this frame's image
    coordinates through the camera's motion, as its state is by the transition (the same
    mode: the whole box, its centre only, or nothing), so that OC-SORT's recovery round
    and momentum compare boxes of one frame's coordinates (one warp for all of them)."""
    camera = next((getattr(f, "camera", "box") for f in ctx.graph.factors_of(var, "transition")
                   if isinstance(f, LinearGaussianTransition)), "none")
    if camera == "none":
        return
    T, c = linear_state_warp(("cx", "cy", "w", "h"), affine,  # noqa: N806
                             sizes="keep" if camera == "centre" else "scale")
    tracks = ctx.replicas.tracks
    histories = [h for h in (slots.get(var, TrackState).observations
                             for slots in ctx.replicas.state) if h is not None and h.boxes]
    parts = [np.array([t.state for t in tracks], dtype=float).reshape(-1, 4)]
    parts += [np.array(list(h.boxes.values()), dtype=float) for h in histories]
    moved = np.concatenate(parts) @ T.T + c
    for t, box in zip(tracks, moved[:len(tracks)], strict=True):
        t.state = box
    at = len(tracks)
    for h in histories:
        h.boxes = dict(zip(h.boxes, moved[at:at + len(h.boxes)], strict=True))
        at += len(h.boxes)


class ObservationHistory:
    """A replica's recent detections (centre boxes), by age in frames, and its unit
    direction of motion ``(dy, dx)`` from the observation ``delta_t`` frames back to the
    newest (OC-SORT's momentum; None until two observations)."""

    def __init__(self, delta_t: int):
        self.delta_t = int(delta_t)
        self.age = 0
        self.boxes: dict[int, np.ndarray] = {}
        self.velocity: np.ndarray | None = None

    def previous(self, age: int) -> np.ndarray | None:
        """The observation ``delta_t`` frames before ``age`` (or the closest after it in
        that window, else the newest; None without any)."""
        if not self.boxes:
            return None
        for back in range(self.delta_t, 0, -1):
            if age - back in self.boxes:
                return self.boxes[age - back]
        return self.boxes[max(self.boxes)]

    def observe(self, box: np.ndarray) -> None:
        """Record this frame's detection ``box`` and the direction of motion to it."""
        prev = self.previous(self.age)
        if prev is not None:
            d = box[:2] - prev[:2]
            norm = np.sqrt(d[0] ** 2 + d[1] ** 2) + 1e-6
            self.velocity = np.array([d[1], d[0]]) / norm
        self.boxes[self.age] = np.asarray(box, dtype=float).copy()
        for key in [key for key in self.boxes if key < self.age - self.delta_t]:
            del self.boxes[key]


def _assigned(ctx: RuleContext, factor) -> tuple[np.ndarray, np.ndarray] | None:
    """The assigned replicas and their coded detection boxes, or None."""
    a: Assignment | None = ctx.assignment
    if a is None:
        return None
    a = a.updating()
    if not len(a.rows):
        return None
    coding = box_coding(ctx.graph.variables[factor.variables[0]].labels)
    return a.rows, encode_boxes(a.boxes[a.cols], coding)


@RULES.register(AssignedDetectionLikelihood, BatchedGaussian)
def update_assigned(ctx: RuleContext, factor, frame: FrameContext) -> None:
    """Kalman update of every replica a detection was assigned to."""
    got = _assigned(ctx, factor)
    if got is None:
        return None
    rows, z = got
    var = factor.variables[0]
    b: BatchedGaussian = ctx.beliefs[var]
    m0, P0 = b.m[rows], b.P[rows]
    info = None
    if factor.reupdate:  # OC-SORT's re-update of replicas found again after a gap
        m0, P0, info = _reupdate(ctx, factor, rows, m0, P0)
    R = factor.noise_cov(m0)
    if factor.occlusion_gate is not None:  # hidden edges carry no information
        R, hidden = _hide_edges(m0, P0, R, z, factor.occlusion_gate)
        if hidden.any():
            info = info or DetectionInfo()
            info.hidden_edges = int(hidden.sum())
    m, P = kalman_update_batch(m0, P0, factor.H, R, z, factor.selects)
    mean, cov = b.m.copy(), b.P.copy()
    mean[rows], cov[rows] = m, P
    ctx.beliefs[var] = BatchedGaussian(mean, cov)
    if factor.reupdate:  # each replica's last posterior, where a later gap starts from
        for i, k in enumerate(rows):
            ctx.replicas.state[int(k)].get(var, TrackState).posterior = (m[i].copy(),
                                                                         P[i].copy())
    return info


@RULES.register(AssignedDetectionLikelihood, BatchedParticles)
def weight_assigned(ctx: RuleContext, factor, frame: FrameContext) -> np.ndarray:
    """``(K, N)`` log-likelihood increments of particle replicas: ``log N(z_k; H x, R)``
    at each particle of a replica given detection ``z_k`` (its noise scale-aware at the
    replica's mean where the factor says so), 0 for a replica given none."""
    var = factor.variables[0]
    b: BatchedParticles = ctx.beliefs[var]
    out = np.zeros(b.log_weights.shape)
    got = _assigned(ctx, factor)
    if got is None:
        return out
    rows, z = got
    x = b.x[rows]  # (B, N, d)
    r = z[:, None, :] - x @ factor.H.T  # (B, N, k)
    R = factor.noise_cov(_means(b)[rows])
    R = np.broadcast_to(R, (len(rows),) + R.shape[-2:])
    L = np.linalg.cholesky(R)  # (B, k, k)
    u = np.linalg.solve(L[:, None, :, :], r[..., None])[..., 0]  # (B, N, k)
    k = factor.H.shape[0]
    logdet = 2.0 * np.log(np.diagonal(L, axis1=1, axis2=2)).sum(axis=1)  # (B,)
    out[rows] = -0.5 * (u ** 2).sum(-1) - 0.5 * (logdet[:, None] + k * np.log(2 * np.pi))
    return out


#: which way an edge of a corner box moves when it is hidden: x1 and y1 inwards is up,
#: x2 and y2 inwards is down
_INWARDS = np.array([1.0, 1.0, -1.0, -1.0])


def _hide_edges(m: np.ndarray, P: np.ndarray, R: np.ndarray, z: np.ndarray, gate: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """``R`` with the rows of hidden edges made uninformative (variance 1e12), and the mask
    ``(B, 4)`` of those edges: an edge of detection ``z`` (corners) inside the predicted
    box ``m[:, :4]`` by more than ``gate`` innovation standard deviations. At most two
    edges (one per axis) are hidden, so a detection always updates its box."""
    R = np.broadcast_to(R, (len(m),) + R.shape[-2:]).copy()
    S = np.diagonal(P[:, :4, :4], axis1=1, axis2=2) + np.diagonal(R, axis1=1, axis2=2)
    inside = _INWARDS * (z - m[:, :4]) / np.sqrt(S)  # > 0: the edge moved into the box
    hidden = inside > gate
    for a, b in ((0, 2), (1, 3)):  # never both edges of one axis: keep the less inside
        both = hidden[:, a] & hidden[:, b]
        keep_a = inside[:, a] <= inside[:, b]
        hidden[both & keep_a, a] = False
        hidden[both & ~keep_a, b] = False
    idx = np.nonzero(hidden)
    R[idx[0], idx[1], idx[1]] = 1e12
    return R, hidden


def _reupdate(ctx: RuleContext, factor, rows: np.ndarray, m0: np.ndarray, P0: np.ndarray):
    """Observation-centric re-update (OC-SORT): a replica matched after ``g − 1`` frames
    without a detection restarts from its prediction one frame after its last detection
    and is updated along ``g`` virtual detections interpolated between that detection and
    this frame's (box centre and size, or corners), with a predict between them; the real
    update follows."""
    var = factor.variables[0]
    labels = ctx.graph.variables[var].labels
    coding = box_coding(labels)
    trans = ctx.graph.factors_of(var, "transition")
    a: Assignment = ctx.assignment
    det = dict(zip(a.rows.tolist(), a.cols.tolist(), strict=True))
    m0, P0 = m0.copy(), P0.copy()
    redone = []
    for i, k in enumerate(rows):
        k = int(k)
        track = ctx.replicas.tracks[k]
        if track.misses < 1 or not trans:
            continue
        state = ctx.replicas.state[k].find(var, TrackState)
        post = None if state is None else state.posterior
        if post is None:  # not updated since its birth: its prior is its last posterior
            prior = ctx.replicas.graphs[k].factors_of(var, "prior")[0]
            post = (prior.mean(), prior.cov)
        gap = track.misses + 1
        m, P = (a[0] for a in _predict(trans[0], labels, post[0][None], post[1][None]))
        last, new = np.asarray(track.state, dtype=float), a.boxes[det[k]]
        if coding == "xyxy":
            last, new = encode_boxes(last, "xyxy"), encode_boxes(new, "xyxy")
        for step in range(gap):
            box = last + (step + 1) * (new - last) / gap
            z = box if coding == "xyxy" else encode_boxes(box, coding)
            mm, PP = kalman_update_batch(m[None], P[None], factor.H,
                                         factor.noise_cov(m[None]), z[None], factor.selects)
            m, P = mm[0], PP[0]
            if step < gap - 1:
                m, P = (a[0] for a in _predict(trans[0], labels, m[None], P[None]))
        m0[i], P0[i] = m, P
        redone.append(k)
    return m0, P0, (DetectionInfo(reupdated=np.array(redone)) if redone else None)


@RULES.register(VBNoise, BatchedGaussian)
def vb_assigned(ctx: RuleContext, factor, frame: FrameContext) -> AssociationInfo | None:
    """Feng et al.'s (2015) VB adaptive measurement noise per replica, batched: for each assigned
    replica the fixed point of ``q(x) q(R)`` (:func:`pgm.inference.vb.vb_akf_update`, all
    replicas at once; ``R = diag(β / α)``)."""
    noise, target = factor.variables
    liks = [f for f in ctx.graph.factors_of(target, "likelihood")
            if factor.likelihood in (None, f.name)]
    if len(liks) == 1 and not isinstance(liks[0], AssignedDetectionLikelihood):
        # a likelihood of the frame's own measurements: the single-graph VB-AKF, per replica
        return per_replica(_vb_gaussian, VBNoise)(ctx, factor, frame)
    if len(liks) != 1:
        raise vb_likelihood_refusal(factor, ctx.graph)
    if getattr(factor, "tie", None) is not None:
        raise ValueError(f"factor {factor.name!r}: tied noise components are implemented "
                         f"for the VB-PHD (Intensity) rule only")
    got = _assigned(ctx, liks[0])
    if got is None:
        return None
    rows, z = got
    H = liks[0].H
    b: BatchedGaussian = ctx.beliefs[target]
    q: BatchedInverseGamma = ctx.beliefs[noise]
    alpha0, beta0 = q.alpha[rows], q.beta[rows]
    m0, P0 = b.m[rows], b.P[rows]
    # scale-aware noise: the noise belief is of the variance in units of the box's size
    # along each component's axis (R = diag(r · size²)); residuals are measured so too
    sizes = liks[0].scales(m0)
    size2 = 1.0 if sizes is None else sizes ** 2
    m, P, alpha, beta, it = vb_akf_batch(m0, P0, alpha0, beta0, H, z, factor.tol,
                                         factor.max_iter, size2, liks[0].selects)
    mean, cov = b.m.copy(), b.P.copy()
    mean[rows], cov[rows] = m, P
    ctx.beliefs[target] = BatchedGaussian(mean, cov)
    a_all, b_all = q.alpha.copy(), q.beta.copy()
    a_all[rows], b_all[rows] = alpha, beta
    ctx.beliefs[noise] = BatchedInverseGamma(a_all, b_all)
    return AssociationInfo(iterations=it)


@RULES.register("estimate", BatchedGaussian)
def estimate_gaussians(ctx: RuleContext, variable: str, frame) -> np.ndarray:
    """The replicas' means ``(K, d)``."""
    return ctx.beliefs[variable].m.copy()


@RULES.register("resample", BatchedGaussian)
def no_resample(ctx: RuleContext, variable: str, frame) -> None:
    """Nothing to resample."""
    return None
