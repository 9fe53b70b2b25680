"""Tracking by detection as factors: a box state with exact Kalman rules, and data association.

The classic trackers (SORT, ByteTrack) are a plate of per-target linear-Gaussian box
states whose measurement is *the detection assigned to the target*. Declared as a
factor graph of the one engine (:mod:`pgm.models.sort`), one target is

* a ``state`` variable whose first four columns code its box (:data:`pgm.core.boxes.
  BOX_CODINGS`: the corners ``x1, y1, x2, y2`` of the ``trackers`` package, or the SORT
  paper's centre, area and aspect ``cx, cy, s, r``) followed by their rates;
* :class:`BoxPrior` — a Gaussian prior centred on the birth detection, rates zero;
* a :class:`~pgm.factors.LinearGaussianTransition` (constant velocity);
* :class:`DetectionAssociation` (kind ``"association"``) — the data-association node
  between the replicas and the frame's detections: Hungarian assignment on IoU in one or
  more *rounds* (SORT: one; ByteTrack: high-score detections first, then the
  low-score ones against the replicas left over), each with its IoU gate; the engine
  runs it at its ``assign`` stage, after predict and before the likelihoods;
* :class:`AssignedDetectionLikelihood` — ``z = H x + N(0, R)`` with ``z`` the coded box of
  the detection assigned to this replica (no assignment: no evidence), updated by the
  exact Kalman rule of :mod:`pgm.inference.association`, for all replicas in a few
  batched matrix products.

The track layer (confirmation, coasting, the lost stage, births from the detections
no replica took) is the plate's :class:`~pgm.core.plate.Lifecycle`, as for every plate;
with an association factor it reads the assignment of the ``assign`` stage instead of
matching again.

>>> f = DetectionAssociation("box", rounds=[{"iou": 0.3}])
>>> f.rounds[0]["min_score"], f.rounds[0]["iou"]
(-inf, 0.3)
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.boxes import (
    BOX_CODINGS,
    box_code_columns,
    box_coding,
    decode_boxes,
    encode_boxes,
    xywh_to_cxcywh,
)
from pgm.core.factor import Factor
from pgm.core.frame import FrameContext
from pgm.core.numerics import check_finite_param
from pgm.core.variable import Variable
from pgm.factors.gaussian import GaussianPrior, LinearGaussianTransition, _as_cov
from pgm.factors.kinds import LikelihoodFactor
from pgm.factors.scores import PersistenceScoreModel, ScoreQuantiles

__all__ = ["BoxPrior", "BoxTransition", "DetectionAssociation", "AssignedDetectionLikelihood",
           "SCORE_MAPS", "LEARNED_SCORE_MAPS", "TRACK_POOLS", "map_scores", "constant_velocity",
           "axis_sizes", "X_LABELS", "CAMERA_WARPS", "CAMERA_ORDERS", "RoundPlan",
           "IOU_AFFINITY", "MOMENTUM", "APPEARANCE"]

#: how detection scores are brought to [0, 1] before the rounds' thresholds: ``"none"``
#: (as given), ``"logistic"`` (``1 / (1 + e^{-s})``: one monotone map for a detector whose
#: scores are margins or unbounded, as MOT15's and MOT16's public ones are), ``"constant"``
#: (every detection 1: a detector whose scores say nothing of confidence, such as
#: background subtraction's fill fractions — as the ``trackers`` package treats
#: detections without scores), ``"learned"`` (the probability that the detection is of a
#: target, learned on the video from which detections are found again and read from the
#: score's rank: :class:`~pgm.factors.scores.PersistenceScoreModel`; the same for any
#: strictly increasing map of the detector's scores, so thresholds are statements about
#: the detections, not about a number on the detector's scale), ``"quantile"`` (the
#: score's quantile among the video's scores so far: a threshold is a share of the
#: detections, :class:`~pgm.factors.scores.ScoreQuantiles`; also the same for any
#: strictly increasing map)
SCORE_MAPS = ("none", "logistic", "constant", "learned", "quantile")
#: the score maps learned on the video (kept per run by the association rule)
LEARNED_SCORE_MAPS = ("learned", "quantile")
#: the replicas a round of :class:`DetectionAssociation` may take (``"tracks"``), of those
#: no earlier round matched: every one; those with an identity (``"confirmed"``); those
#: confirmed and matched (or born) in the previous frame (``"tracked"``); those confirmed
#: and missed then (``"lost"``); those without an identity yet (``"tentative"``)
TRACK_POOLS = ("all", "confirmed", "tracked", "lost", "tentative")

#: the association's built-in pieces, by the name a round or a saved model gives them
#: (:mod:`pgm.inference.association_terms`): the IoU affinity (against the prediction or
#: the last detection, buffered, times the score), OC-SORT's momentum term and the
#: appearance similarity
IOU_AFFINITY = "pgm.inference.association_terms:iou_affinity"
MOMENTUM = "pgm.inference.association_terms:momentum"
APPEARANCE = "pgm.inference.association_terms:appearance_similarity"


@dataclass(frozen=True)
class RoundPlan:
    """One round of a :class:`DetectionAssociation` as its rule runs it, every piece a
    named function of :class:`pgm.inference.association_terms.AssociationInputs`.

    The round takes the replicas of pool ``tracks`` no earlier round matched and the
    detections still free with a mapped score in ``[min_score, max_score)``; it maximises
    ``affinity + Σ weight × term`` over the pairs every gate allows (Hungarian), and keeps
    a matched pair only if its affinity is at least ``threshold``.

    Attributes
    ----------
    affinity : dict
        ``{"fn", "args"}``: the pair's affinity ``(K, M)`` (default the IoU,
        :data:`IOU_AFFINITY`, whose ``against``, ``buffer`` and ``fuse_score`` args the
        round's keys of those names set).
    threshold : float
        The least affinity of a match (the round's ``"iou"``).
    terms, gates : tuple of dict
        ``{"fn", "weight", "args"}`` and ``{"fn", "args"}``: the momentum term
        (:data:`MOMENTUM`, weight ``direction_weight``) of a ``"direction"`` round, the
        appearance term (:data:`APPEARANCE`, weight ``appearance_weight``) of an
        ``"appearance"`` round, then the factor's terms and the round's own.
    """

    affinity: dict
    threshold: float
    min_score: float
    max_score: float
    tracks: str
    terms: tuple = ()
    gates: tuple = ()

    @property
    def plain(self) -> bool:
        """The IoU against the predictions, on every replica and detection, nothing added
        (SORT's one round)."""
        return (self.affinity["fn"] == IOU_AFFINITY and not self.affinity["args"]
                and not self.terms and not self.gates and self.tracks == "all"
                and self.min_score == -math.inf and self.max_score == math.inf)


def map_scores(scores: np.ndarray, score_map: str) -> np.ndarray:
    """``scores`` through the map ``score_map`` (:data:`SCORE_MAPS`)."""
    s = np.asarray(scores, dtype=float)
    if score_map == "none":
        return s
    if score_map == "logistic":
        return 0.5 * (1.0 + np.tanh(0.5 * s))  # the logistic, without overflow
    if score_map == "constant":
        return np.ones_like(s)
    if score_map in LEARNED_SCORE_MAPS:
        raise ValueError(f"the {score_map!r} score map is learned on the video: "
                         "DetectionAssociation.score_model() keeps it per run")
    raise ValueError(f"unknown score map {score_map!r} (choose from {SCORE_MAPS})")


def _box_labels(factor: Factor, variables: dict[str, Variable], var: str) -> str:
    coding = box_coding(variables[var].labels)
    if coding is None:
        raise ValueError(f"factor {factor.name!r}: variable {var!r} must code a box in its "
                         f"first columns (labels {BOX_CODINGS}), got {variables[var].labels}")
    return coding


#: the box labels read along the image's x axis (their noise scales with the box's width);
#: the others of a box state along y (height)
X_LABELS = frozenset({"x1", "x2", "cx", "w", "vx1", "vx2", "vcx", "vw"})


def axis_sizes(labels, coding: str, x: np.ndarray) -> np.ndarray:
    """``(..., d)``: for each state component of ``x`` ``(..., d)`` the size of its box
    along the component's axis (width for ``x1, x2, cx, w`` and their rates, height for
    the rest): what scale-aware noise is in units of."""
    if coding == "xysr":
        raise ValueError("scale-aware noise needs a box state of corners (xyxy) or centre and "
                         "size (cxcywh), not area and aspect (xysr)")
    cols = box_code_columns(tuple(labels))[1]
    box = decode_boxes(x[..., cols], coding)
    w, h = np.abs(box[..., 2:3]), np.abs(box[..., 3:4])
    is_x = np.array([lab in X_LABELS for lab in labels])
    return np.where(is_x, w, h)


def _relative_std(factor: Factor, value, n: int) -> np.ndarray | None:
    """A factor's ``relative_std``: ``n`` positive finite stds, or None."""
    if value is None:
        return None
    r = np.asarray(value, dtype=float).reshape(-1)
    check_finite_param(f"{factor.name}.relative_std", r, positive=True)
    if r.size != n:
        raise ValueError(f"factor {factor.name!r}: relative_std needs {n} values, got {r.size}")
    return r


def constant_velocity(coding: str) -> tuple[list[str], np.ndarray, np.ndarray]:
    """Labels, transition ``F`` and measurement ``H`` of a constant-velocity box state in
    ``coding``: the four box columns and a rate for each (``xysr``: none for the aspect
    ``r``, which SORT holds constant)."""
    box = list(BOX_CODINGS[coding])
    moving = box[:3] if coding == "xysr" else box
    labels = box + [f"v{c}" for c in moving]
    d = len(labels)
    F = np.eye(d)
    for i in range(len(moving)):
        F[i, 4 + i] = 1.0
    H = np.eye(4, d)
    return labels, F, H


class _RelativeStd:
    """A factor with an optional ``relative_std`` (scale-aware noise), saved with it."""

    relative_std: np.ndarray | None = None

    def params(self) -> dict[str, Any]:
        p = super().params()
        if self.relative_std is not None:
            p["relative_std"] = self.relative_std
        return p


class BoxPrior(_RelativeStd, GaussianPrior):
    """A Gaussian prior on a box state (any :data:`~pgm.core.boxes.BOX_CODINGS`), re-centred
    on each new target's detection box with its rates set to zero. Its covariance is
    ``cov`` (the initial uncertainty ``P0``) or, with ``relative_std`` (one std per state
    component, in units of the box's width or height along the component's axis,
    :func:`axis_sizes`), ``diag((relative_std · size)²)`` of each new target's box (the
    scale-aware ``P0`` of BoT-SORT).
    """

    def __init__(self, variable: str, *, mean, cov=0.0, relative_std=None,
                 name: str | None = None):
        super().__init__(variable, mean=mean, cov=cov, name=name)
        self.relative_std = _relative_std(self, relative_std, self.mean_.size)

    def check(self, variables: dict[str, Variable]) -> None:
        super().check(variables)
        coding = _box_labels(self, variables, self.variables[0])
        if self.relative_std is not None:
            axis_sizes(variables[self.variables[0]].labels, coding, self.mean_)

    def born_at(self, values: dict[str, float], labels) -> BoxPrior:
        coding, cols = box_code_columns(tuple(labels or ()))
        try:
            box = np.array([values["cx"], values["cy"], values["w"], values["h"]], dtype=float)
        except KeyError:
            box = None
        if coding is None or box is None:
            raise ValueError(f"prior {self.name!r}: needs a box (cx, cy, w, h) and a box state, "
                             f"got {sorted(values)} for labels {labels}")
        mean = np.zeros(self.mean_.shape)
        if coding == "xyxy":  # inline: a plate's births call this once per new target
            cx, cy, hw, hh = box[0], box[1], box[2] / 2.0, box[3] / 2.0
            mean[cols] = (cx - hw, cy - hh, cx + hw, cy + hh)
        else:
            mean[cols] = encode_boxes(box, coding)
        new = self._with_mean(mean)
        if self.relative_std is not None:
            new.cov = np.diag((self.relative_std * axis_sizes(labels, coding, mean)) ** 2)
        return new


class DetectionAssociation(Factor):
    """The assignment of the frame's detections to a plate's replicas (kind
    ``"association"``).

    Each round assigns the detections whose (mapped) score lies in
    ``[min_score, max_score)`` to the replicas no earlier round matched, by the
    Hungarian algorithm maximising the IoU between each replica's box and the
    detection's (``scipy.optimize.linear_sum_assignment``); a pair below the round's
    ``iou`` gate is no match. A replica's box is its prediction, or with ``"against":
    "last"`` the last detection it was given (OC-SORT's observation-centric recovery); a
    round with ``"direction": true`` adds OC-SORT's momentum term to what is maximised:
    ``direction_weight`` × score × the agreement, ``(π/2 − |angle|)/π``, between the
    replica's direction of motion over its last ``delta_t`` observations and the
    direction from its observation ``delta_t`` frames back to the detection (the IoU
    alone is gated).

    Three more keys make BoT-SORT's and C-BIoU's rounds (:mod:`pgm.models.botsort`,
    :mod:`pgm.models.cbiou`): ``"tracks"`` restricts a round to a pool of the replicas
    left (:data:`TRACK_POOLS`: ``"all"``, the default; ``"confirmed"``, with an identity;
    ``"tracked"``, confirmed and matched in the previous frame; ``"lost"``, confirmed and
    not; ``"tentative"``, without an identity); ``"fuse_score": true`` maximises the IoU
    times the detection's (mapped) score, and the gate reads that product; ``"buffer":
    b`` computes the IoU of both boxes enlarged about their centres to ``(1 + 2b) w ×
    (1 + 2b) h`` (the buffered IoU of C-BIoU: boxes that do not touch may still match).

    Every piece of a round is a named function of
    :class:`pgm.inference.association_terms.AssociationInputs` (:class:`RoundPlan`; the
    factor's :attr:`plans`): the keys above are shorthands — the IoU affinity
    (:data:`IOU_AFFINITY`, its args ``against``, ``buffer``, ``fuse_score``), the momentum
    term (:data:`MOMENTUM`, weight ``direction_weight``), the appearance term
    (:data:`APPEARANCE`, weight ``appearance_weight``) — and a round may name its own
    ``"affinity": {"fn": f, "args": {...}}`` (its ``"iou"`` then the least affinity of a
    match) and ``"terms"``/``"gates"`` (below), the built-in ones included: ``{"fn":
    MOMENTUM, "weight": 0.2}`` in a round's terms is ``"direction": true``.

    Parameters
    ----------
    variable : str
        The plate's box state.
    rounds : list of dict
        ``{"iou": gate, "min_score": ..., "max_score": ..., "against": "prediction" |
        "last", "direction": bool, "tracks": pool, "fuse_score": bool, "buffer": b}`` per
        round (scores default to all, tracks to all, buffer to 0). SORT: ``[{"iou":
        0.3}]``; ByteTrack: ``[{"iou": 0.1, "min_score": 0.6}, {"iou": 0.1, "max_score":
        0.6}]``; OC-SORT: ``[{"iou": 0.3, "min_score": 0.6, "direction": true}, {"iou":
        0.3, "min_score": 0.6, "against": "last"}]``; BoT-SORT: ``[{"iou": 0.2,
        "min_score": 0.6, "tracks": "confirmed", "fuse_score": true}, {"iou": 0.5,
        "min_score": 0.1, "max_score": 0.6, "tracks": "tracked"}, {"iou": 0.3,
        "min_score": 0.6, "tracks": "tentative", "fuse_score": true}]``.
    score_map : {"none", "logistic", "constant", "learned"}
        Map applied to the detection scores first (:data:`SCORE_MAPS`); the mapped scores
        are also what the plate's ``birth_min_score`` compares. ``"learned"``: each
        score becomes the probability that its detection is of a target, learned on the
        run's video (:class:`~pgm.factors.scores.PersistenceScoreModel`), and every
        threshold is on that probability.
    direction_weight : float
        Weight of the momentum term (OC-SORT: 0.2).
    delta_t : int
        Observations back for the direction of motion (OC-SORT: 3).
    appearance : list of likelihood factors, optional
        Appearance for association and re-identification: appearance likelihood factors
        on a ``(cx, cy, w, h)`` box (the toolkit's cues, e.g. ``cue_factor("colour", ...)``
        of :mod:`pgm.observation.appearance.cues`, or your own with ``learn`` and
        ``log_likelihood``), copied per replica and learned from each detection it is
        given; a round with ``"appearance": true`` adds ``appearance_weight`` × the
        similarity of each replica's model with each detection (``exp(log-likelihood /
        λ)``, multiplied over the factors: for colour the Bhattacharyya coefficient ρ as
        ``e^{ρ − 1}``) to what it maximises. Frames without an image have no appearance
        term. Saved as the factors' declarations.
    appearance_weight : float
        Its weight (against an IoU in [0, 1]).
    terms, gates : list of dict, optional
        The association's extension points, applied in every round (a round's own
        ``"terms"`` and ``"gates"`` keys add to them in that round only: ByteTrack's
        low-score round with a gate of one's own, say): a *term*
        ``{"fn": f, "weight": w, "args": {...}}`` adds ``w × f(inputs, **args)`` ``(K, M)``
        to what the round maximises; a *gate* ``{"fn": g, "args": {...}}`` allows only the
        pairs where ``g(inputs, **args)`` ``(K, M)`` is true. ``inputs`` is
        :class:`pgm.inference.association_terms.AssociationInputs` (predicted boxes, the
        replicas' state means and covariances, the detections and their scores, the
        frame); ``f`` and ``g`` are functions defined at module level (given, or named
        ``"module:function"``; saved by name, found again as rules are), e.g.
        :func:`pgm.inference.association_terms.mahalanobis_gate`.
    """

    kind = "association"
    _KEYS = frozenset({"iou", "min_score", "max_score", "against", "direction", "appearance",
                       "tracks", "fuse_score", "buffer", "terms", "gates", "affinity"})

    def __init__(self, variable: str, *, rounds: list[dict[str, Any]] | None = None,
                 score_map: str = "none", direction_weight: float = 0.2, delta_t: int = 3,
                 appearance: list | None = None, appearance_weight: float = 0.5,
                 terms: list[dict[str, Any]] | None = None,
                 gates: list[dict[str, Any]] | None = None, name: str | None = None):
        super().__init__(variable, name=name)
        self.terms = [self._extension(t, "term") for t in (terms or [])]
        self.gates = [self._extension(g, "gate") for g in (gates or [])]
        self.appearance: list | None = None
        if appearance is not None:
            from pgm.core.factor import factor_from_dict

            items = [factor_from_dict(a) if isinstance(a, dict) else a for a in appearance]
            for a in items:
                if not (isinstance(a, LikelihoodFactor) and hasattr(a, "learn")):
                    raise ValueError(f"factor {self.name!r}: appearance takes likelihood factors "
                                     f"that learn a model from a box (learn, log_likelihood), "
                                     f"got {type(a).__name__}")
            self.appearance = items or None
        self.appearance_weight = float(check_finite_param(f"{self.name}.appearance_weight",
                                                          appearance_weight, nonneg=True))
        if score_map not in SCORE_MAPS:
            raise ValueError(f"factor {self.name!r}: unknown score_map {score_map!r} (choose "
                             f"from {SCORE_MAPS})")
        self.score_map = score_map
        self.direction_weight = float(check_finite_param(f"{self.name}.direction_weight",
                                                         direction_weight, nonneg=True))
        if isinstance(delta_t, bool) or int(delta_t) != delta_t or delta_t < 1:
            raise ValueError(f"factor {self.name!r}: delta_t must be a positive integer, got "
                             f"{delta_t!r}")
        self.delta_t = int(delta_t)
        rounds = [{"iou": 0.3}] if rounds is None else rounds
        if not isinstance(rounds, (list, tuple)) or not rounds:
            raise ValueError(f"factor {self.name!r}: rounds must be a non-empty list of dicts")
        self.rounds: list[dict[str, Any]] = []
        for r in rounds:
            if not isinstance(r, dict) or set(r) - self._KEYS:
                raise ValueError(f"factor {self.name!r}: a round is a dict of "
                                 f"{', '.join(sorted(self._KEYS))}; got {r!r}")
            iou = float(r.get("iou", 0.3))
            lo = float(r.get("min_score", -math.inf) if r.get("min_score") is not None
                       else -math.inf)
            hi = float(r.get("max_score", math.inf) if r.get("max_score") is not None
                       else math.inf)
            affinity = None
            if r.get("affinity") is not None:
                if set(r) & {"against", "buffer", "fuse_score"}:
                    raise ValueError(f"factor {self.name!r}: a round with an affinity of its "
                                     f"own takes no against, buffer or fuse_score (they "
                                     f"are the IoU affinity's); got {r!r}")
                affinity = self._extension(r["affinity"], "affinity")
            if not (math.isfinite(iou) if affinity else 0.0 <= iou <= 1.0) or \
                    math.isnan(lo) or math.isnan(hi) or lo >= hi:
                raise ValueError(f"factor {self.name!r}: round {r!r} needs an iou gate in "
                                 f"[0, 1] (any finite least affinity with an affinity of its "
                                 f"own) and min_score < max_score")
            against = r.get("against", "prediction")
            if against not in ("prediction", "last"):
                raise ValueError(f"factor {self.name!r}: a round's 'against' is 'prediction' "
                                 f"or 'last', got {against!r}")
            tracks = r.get("tracks", "all")
            if tracks not in TRACK_POOLS:
                raise ValueError(f"factor {self.name!r}: a round's 'tracks' is one of "
                                 f"{TRACK_POOLS}, got {tracks!r}")
            buffer = r.get("buffer", 0.0)
            if isinstance(buffer, bool) or not isinstance(buffer, (int, float)) or \
                    not math.isfinite(buffer) or buffer < 0:
                raise ValueError(f"factor {self.name!r}: a round's 'buffer' is a finite number "
                                 f">= 0, got {buffer!r}")
            self.rounds.append({"iou": iou, "min_score": lo, "max_score": hi,
                                "against": against, "direction": bool(r.get("direction")),
                                "appearance": bool(r.get("appearance")), "tracks": tracks,
                                "fuse_score": bool(r.get("fuse_score")),
                                "buffer": float(buffer),
                                "terms": [self._extension(t, "term")
                                          for t in (r.get("terms") or [])],
                                "gates": [self._extension(g, "gate")
                                          for g in (r.get("gates") or [])],
                                "affinity": affinity})
        self.plans: list[RoundPlan] = [self._plan(r) for r in self.rounds]

    def _plan(self, r: dict[str, Any]) -> RoundPlan:
        """A round as named pieces (:class:`RoundPlan`)."""
        affinity = r["affinity"]
        if affinity is None:
            args: dict[str, Any] = {}
            if r["against"] != "prediction":
                args["against"] = r["against"]
            if r["buffer"]:
                args["buffer"] = r["buffer"]
            if r["fuse_score"]:
                args["fuse_score"] = True
            affinity = {"fn": IOU_AFFINITY, "args": args}
        terms = []
        if r["direction"]:
            terms.append({"fn": MOMENTUM, "args": {}, "weight": self.direction_weight})
        if r["appearance"]:
            terms.append({"fn": APPEARANCE, "args": {}, "weight": self.appearance_weight})
        return RoundPlan(affinity, r["iou"], r["min_score"], r["max_score"], r["tracks"],
                         tuple(terms + self.terms + r["terms"]),
                         tuple(self.gates + r["gates"]))

    def _extension(self, item: Any, what: str) -> dict[str, Any]:
        """A term, gate or affinity as ``{"fn": "module:function", "args"}`` (and a term's
        ``"weight"``)."""
        if callable(item):
            item = {"fn": item}
        if not isinstance(item, dict) or "fn" not in item or set(item) - {"fn", "weight",
                                                                          "args"}:
            raise ValueError(f"factor {self.name!r}: an association {what} is a dict with "
                             f"'fn' (and 'weight', 'args'), got {item!r}")
        fn = item["fn"]
        if callable(fn):
            fn = f"{fn.__module__}:{fn.__qualname__}"
        if not isinstance(fn, str) or ":" not in fn or "<locals>" in fn:
            raise ValueError(f"factor {self.name!r}: an association {what}'s fn is a function "
                             f"defined at module level (or its 'module:function' name), got "
                             f"{item['fn']!r}")
        args = item.get("args") or {}
        if not isinstance(args, dict):
            raise ValueError(f"factor {self.name!r}: an association {what}'s args is a dict")
        if what != "term" and "weight" in item:
            raise ValueError(f"factor {self.name!r}: an association {what} has no weight "
                             f"(only a term has), got {item!r}")
        out: dict[str, Any] = {"fn": fn, "args": dict(args)}
        if what == "term":
            out["weight"] = float(check_finite_param(f"{self.name}.{what}.weight",
                                                     item.get("weight", 1.0)))
        return out

    @property
    def extended(self) -> bool:
        """Whether pieces of one's own take part (terms, gates or an affinity, the
        factor's or a round's)."""
        return bool(self.terms or self.gates or any(r["terms"] or r["gates"] or r["affinity"]
                                                   for r in self.rounds))

    @property
    def uses_pools(self) -> bool:
        """Whether a round takes a pool of the replicas (``"tracks"`` other than all)."""
        return any(r["tracks"] != "all" for r in self.rounds)

    @property
    def keeps_observations(self) -> bool:
        """Whether a round needs each replica's past detections (momentum, recovery)."""
        return any(any(t["fn"] == MOMENTUM for t in p.terms)
                   or p.affinity["args"].get("against") == "last" for p in self.plans)

    def params(self) -> dict[str, Any]:
        def finite(v):
            return None if isinstance(v, float) and math.isinf(v) else v

        rounds = []
        for r in self.rounds:
            d = {k: finite(v) for k, v in r.items() if k in ("iou", "min_score", "max_score")}
            if r["against"] != "prediction":
                d["against"] = r["against"]
            if r["direction"]:
                d["direction"] = True
            if r["appearance"]:
                d["appearance"] = True
            if r["tracks"] != "all":
                d["tracks"] = r["tracks"]
            if r["fuse_score"]:
                d["fuse_score"] = True
            if r["buffer"]:
                d["buffer"] = r["buffer"]
            if r["terms"]:
                d["terms"] = [dict(t) for t in r["terms"]]
            if r["gates"]:
                d["gates"] = [dict(g) for g in r["gates"]]
            if r["affinity"]:
                d["affinity"] = dict(r["affinity"])
            rounds.append(d)
        p: dict[str, Any] = {"rounds": rounds, "score_map": self.score_map}
        if self.keeps_observations:
            p.update(direction_weight=self.direction_weight, delta_t=self.delta_t)
        if self.appearance is not None:
            p.update(appearance=[a.to_dict() for a in self.appearance],
                     appearance_weight=self.appearance_weight)
        if self.terms:
            p["terms"] = [dict(t) for t in self.terms]
        if self.gates:
            p["gates"] = [dict(g) for g in self.gates]
        return p

    def appearance_model(self) -> list | None:
        """A new replica's appearance model: copies of the ``appearance`` factors (None
        without)."""
        if self.appearance is None:
            return None
        return [copy.deepcopy(a) for a in self.appearance]

    def check(self, variables: dict[str, Variable]) -> None:
        _box_labels(self, variables, self.variables[0])

    def scores(self, ctx: FrameContext, model: PersistenceScoreModel | None = None,
               boxes: np.ndarray | None = None) -> np.ndarray:
        """The frame's detection scores, mapped; with a map learned on the video
        (:data:`LEARNED_SCORE_MAPS`), ``model`` (a run's :meth:`score_model`) sees the
        frame — its detections' centre ``boxes`` ``(M, 4)``, computed here when not given
        — and maps its scores."""
        d = ctx.detections
        if self.score_map not in LEARNED_SCORE_MAPS:
            return np.zeros(0) if d is None else map_scores(d.scores, self.score_map)
        if model is None:
            raise ValueError(f"factor {self.name!r}: the {self.score_map} score map needs the "
                             f"run's score model (score_model())")
        if boxes is None:
            boxes = (np.zeros((0, 4)) if d is None
                     else xywh_to_cxcywh(np.asarray(d.boxes, dtype=float)))
        return model.update(boxes, np.zeros(0) if d is None else d.scores)

    def score_model(self) -> PersistenceScoreModel | None:
        """A new run's score model (the ``"learned"`` and ``"quantile"`` maps), or None."""
        if self.score_map == "learned":
            return PersistenceScoreModel()
        return ScoreQuantiles() if self.score_map == "quantile" else None


class AssignedDetectionLikelihood(LikelihoodFactor):
    """``z = H x + N(0, R)`` where ``z`` is the coded box (the state's coding) of the
    detection the ``assign`` stage gave this replica; a replica without one has no
    evidence in the frame. Exact Kalman rules (and the VB adaptive-noise rule) in
    :mod:`pgm.inference.association`.

    ``relative_std`` (one per measured component): ``R = diag((relative_std · size)²)``
    with ``size`` the predicted box's width or height along each component's axis
    (:func:`axis_sizes`) — scale-aware measurement noise, as BoT-SORT's; ``R`` is then
    unused. ``reupdate``: OC-SORT's observation-centric re-update — a replica matched
    again after frames without a detection is first re-filtered along a straight line of
    virtual detections from its last one to this one, so that the drift of the
    prediction through the gap does not stay in its velocity. ``occlusion_gate`` (σ, a
    corner state only): the part-graph idea of Zhang and Kang (2015) on a box — a box is made of its
    edges, and a detection of a half-hidden person sees only some of them: an edge of the
    detection that lies *inside* the predicted box by more than ``occlusion_gate``
    innovation standard deviations is taken as hidden (its row carries no information),
    so the target's box keeps its predicted extent there and is updated by the edges
    that are seen.
    """

    def __init__(self, variable: str, *, H, R, relative_std=None, reupdate: bool = False,
                 occlusion_gate: float | None = None, name: str | None = None):
        super().__init__(variable, name=name)
        self.reupdate = bool(reupdate)
        self.occlusion_gate = None if occlusion_gate is None else float(check_finite_param(
            f"{self.name}.occlusion_gate", occlusion_gate, positive=True))
        self.H = np.atleast_2d(np.asarray(H, dtype=float))
        check_finite_param(f"{self.name}.H", self.H)
        self.R = _as_cov(R, self.H.shape[0], f"{self.name}.R")
        if np.any(np.linalg.eigvalsh(self.R) <= 0):
            raise ValueError(f"factor {self.name!r}: R must be positive definite")
        k, d = self.H.shape
        #: whether ``H = [I 0]`` reads the box columns (the Kalman rule then slices)
        self.selects = d >= k and bool(np.array_equal(self.H, np.eye(k, d)))
        self.relative_std = _relative_std(self, relative_std, k)
        if self.relative_std is not None and not self.selects:
            raise ValueError(f"factor {self.name!r}: relative_std needs H = [I 0]")
        self._labels: tuple | None = None
        self._coding: str | None = None

    def params(self) -> dict[str, Any]:
        p: dict[str, Any] = {"H": self.H, "R": self.R}
        if self.relative_std is not None:
            p["relative_std"] = self.relative_std
        if self.reupdate:
            p["reupdate"] = True
        if self.occlusion_gate is not None:
            p["occlusion_gate"] = self.occlusion_gate
        return p

    def check(self, variables: dict[str, Variable]) -> None:
        self._check_dim(variables, self.variables[0], self.H.shape[1], "H's column count")
        if self.H.shape[0] != 4:
            raise ValueError(f"factor {self.name!r}: H must map the state to a box (4 rows), "
                             f"got {self.H.shape}")
        self._coding = _box_labels(self, variables, self.variables[0])
        self._labels = tuple(variables[self.variables[0]].labels)
        if self.relative_std is not None:
            axis_sizes(self._labels, self._coding, np.ones(self.H.shape[1]))
        if self.occlusion_gate is not None and (self._coding != "xyxy" or not self.selects):
            raise ValueError(f"factor {self.name!r}: occlusion_gate needs a corner state "
                             f"(x1, y1, x2, y2 first) read by H = [I 0]")

    def scales(self, mean: np.ndarray) -> np.ndarray | None:
        """``(B, k)`` the size each measured component's noise is in units of, at the
        states ``mean`` ``(B, d)`` (None: fixed noise)."""
        if self.relative_std is None:
            return None
        return axis_sizes(self._labels, self._coding, mean)[:, :self.H.shape[0]]

    def noise_cov(self, mean: np.ndarray) -> np.ndarray:
        """``R`` for each state of ``mean`` ``(B, d)``: ``(k, k)`` fixed, or ``(B, k, k)``."""
        sizes = self.scales(mean)
        if sizes is None:
            return self.R
        k = self.H.shape[0]
        return np.einsum("bk,kl->bkl", (self.relative_std * sizes) ** 2, np.eye(k))

    def log_likelihood(self, x: np.ndarray, ctx: FrameContext) -> np.ndarray:
        raise ValueError(f"factor {self.name!r}: the assigned detection exists only in a plate "
                         f"with a DetectionAssociation (its rules read the frame's assignment)")


#: what of a box state the camera's image motion moves (:class:`BoxTransition`)
CAMERA_WARPS = ("box", "centre", "none")
#: where the camera's image motion enters a predict (:class:`BoxTransition`)
CAMERA_ORDERS = ("before", "after")


class BoxTransition(_RelativeStd, LinearGaussianTransition):
    """Constant-velocity box dynamics ``x_t = F x_{t-1} + N(0, Q)`` whose noise is fixed
    (``Q``) or, with ``relative_std`` (one std per state component), scale-aware:
    ``Q = diag((relative_std · size)²)`` with ``size`` the box's width or height along
    each component's axis at ``x_{t-1}`` (:func:`axis_sizes`; BoT-SORT's process noise).

    When a frame carries the camera's image motion ``[M | t]``, ``camera`` says what it
    moves (:func:`pgm.core.motion.linear_state_warp`): ``"box"`` (default) the whole box
    — corners or centre through ``M p + t``, sizes scaled by ``sqrt|det M|``; ``"centre"``
    the box's centre and its rate only, its width and height unchanged (BoT-SORT's camera
    motion compensation); ``"none"`` nothing (a tracker without compensation, C-BIoU).
    ``camera_order`` says when: ``"before"`` the predict (``x_t = F (T x_{t-1} + c) +
    w``: the process noise is added in the new frame's image) or ``"after"`` it (``x_t =
    T (F x_{t-1} + w) + c``: the noise is carried through the motion, ``P ← T (F P Fᵀ +
    Q) Tᵀ``, as BoT-SORT applies it). The means agree; the covariances differ by ``Q``
    against ``T Q Tᵀ``.
    """

    def __init__(self, variable: str, *, F, Q, relative_std=None, camera: str = "box",
                 camera_order: str = "before", name: str | None = None):
        super().__init__(variable, F=F, Q=Q, name=name)
        self.relative_std = _relative_std(self, relative_std, self.F.shape[0])
        if camera not in CAMERA_WARPS:
            raise ValueError(f"factor {self.name!r}: camera must be one of {CAMERA_WARPS}, got "
                             f"{camera!r}")
        if camera_order not in CAMERA_ORDERS:
            raise ValueError(f"factor {self.name!r}: camera_order must be one of "
                             f"{CAMERA_ORDERS}, got {camera_order!r}")
        self.camera, self.camera_order = camera, camera_order
        self._labels: tuple | None = None
        self._coding: str | None = None

    def params(self) -> dict[str, Any]:
        p = super().params()
        if self.camera != "box":
            p["camera"] = self.camera
        if self.camera_order != "before":
            p["camera_order"] = self.camera_order
        return p

    def check(self, variables: dict[str, Variable]) -> None:
        super().check(variables)
        self._coding = _box_labels(self, variables, self.variables[0])
        self._labels = tuple(variables[self.variables[0]].labels)
        if self.relative_std is not None:
            axis_sizes(self._labels, self._coding, np.ones(self.F.shape[0]))

    def noise_cov(self, mean: np.ndarray) -> np.ndarray:
        """``Q`` at the states ``mean`` ``(B, d)``: ``(d, d)`` fixed, or ``(B, d, d)``."""
        if self.relative_std is None:
            return self.Q
        sizes = axis_sizes(self._labels, self._coding, mean)
        return np.einsum("bk,kl->bkl", (self.relative_std * sizes) ** 2,
                         np.eye(self.F.shape[0]))

    def sample(self, rng: np.random.Generator, *past: np.ndarray) -> np.ndarray:
        if self.relative_std is None:
            return super().sample(rng, *past)
        x = past[0]
        sd = self.relative_std * axis_sizes(self._labels, self._coding, x)
        return x @ self.F.T + sd * rng.standard_normal(x.shape)
