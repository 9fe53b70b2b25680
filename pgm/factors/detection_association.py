"""The data-association node of tracking by detection: :class:`DetectionAssociation`, its
rounds as named pieces (:class:`RoundPlan`) and the pools of replicas a round may take.

The rules that run it are :mod:`pgm.inference.association`'s; the pieces
(:data:`IOU_AFFINITY`, :data:`MOMENTUM`, :data:`APPEARANCE` and one's own) are functions of
:class:`pgm.inference.association_terms.AssociationInputs`, named here by string so that
the factor layer imports nothing of the inference layer.

>>> f = DetectionAssociation("box", rounds=[{"iou": 0.3}])
>>> f.rounds[0]["min_score"], f.rounds[0]["iou"], f.plans[0].plain
(-inf, 0.3, True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pgm.core.boxes import BOX_CODINGS, box_coding, xywh_to_cxcywh
from pgm.core.factor import Factor
from pgm.core.frame import FrameContext
from pgm.core.numerics import check_finite_param
from pgm.core.resolution import BOX_PIXELS
from pgm.core.variable import Variable
from pgm.factors.kinds import LikelihoodFactor
from pgm.factors.persistent_quantiles import (
    PLACED_LEVEL,
    PLACED_SCORE_MAPS,
    PersistentQuantiles,
    check_confidence,
)
from pgm.factors.scores import (
    LEARNED_SCORE_MAPS,
    SCORE_MAPS,
    PersistenceScoreModel,
    ScoreQuantiles,
    map_scores,
)

__all__ = ["DetectionAssociation", "RoundPlan", "TRACK_POOLS", "IOU_AFFINITY", "MOMENTUM",
           "APPEARANCE", "require_box_coding"]

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


def require_box_coding(factor: Factor, variables: dict[str, Variable], var: str) -> str:
    """The box coding of ``var``'s first columns (:data:`~pgm.core.boxes.BOX_CODINGS`),
    or a clear error naming ``factor``."""
    coding = box_coding(variables[var].labels)
    if coding is None:
        raise ValueError(f"factor {factor.name!r}: variable {var!r} must code a box in its "
                         f"first columns (labels {BOX_CODINGS}), got {variables[var].labels}")
    return coding


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
        "min_score": 0.6, "tracks": "tentative", "fuse_score": true}]``. A round with
        ``"update": false`` matches as the others do (its track is matched: a hit, not a
        miss), but its detection only says that the track is there: the track's state,
        its observation history, its last box and its appearance are not updated from
        it (a low-score round whose boxes keep a track alive without pulling it).
    score_map : {"none", "logistic", "constant", "learned"}
        Map applied to the detection scores first (:data:`SCORE_MAPS`); the mapped scores
        are also what the plate's ``birth_min_score`` compares. ``"learned"``: each
        score becomes the probability that its detection is of a target, learned on the
        run's video (:class:`~pgm.factors.persistence.PersistenceScoreModel`), and every
        threshold is on that probability.
    direction_weight : float
        Weight of the momentum term (OC-SORT: 0.2).
    delta_t : int
        Observations back for the direction of motion (OC-SORT: 3).
    appearance : list of likelihood factors, optional
        Appearance for association and re-identification: appearance likelihood factors
        on a ``(cx, cy, w, h)`` box (the toolkit's cues, e.g. ``cue_factor("colour", ...)``
        of :mod:`pgm.observation.appearance.cues`, or your own with ``learn`` and
        ``log_likelihood`` and a ``State``), each replica learning into a state of
        its own from each detection it is given; a round with ``"appearance": true``
        adds ``appearance_weight`` × the similarity of each replica's model with each
        detection (``exp(log-likelihood / λ)``, multiplied over the factors: for colour
        the Bhattacharyya coefficient ρ as ``e^{ρ − 1}``) to what it maximises. Frames
        without an image have no appearance term. Saved as the factors' declarations.
    appearance_weight : float
        Its weight (against an IoU in [0, 1]).
    appearance_pixels : float
        The fewest pixels a detection is read from where it has them: each detection is
        scored, and learned from, on the frame shrunk by the largest power of two that
        leaves it this many pixels (:func:`pgm.core.resolution.box_levels`; default
        :data:`~pgm.core.resolution.BOX_PIXELS`, 0: full resolution).
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
    placed_level : float
        With ``"placed"``: the placement, relative to the best-scored detections', at
        which the detections below the threshold are lifted to it
        (:class:`~pgm.factors.persistent_quantiles.PersistentQuantiles`, 0.8).
    gate_confidence : float or None
        With a gated map (``"quantile-gated"``, ``"quantile-rebased"``, ``"placed-rebased"``,
        ``"placed-over"``): cut as clutter only what the video shows to be clutter with
        this confidence (a one-sided test on the found-again rates); None: the point
        estimate alone (:class:`~pgm.factors.persistent_quantiles.PersistentQuantiles`).
    """

    kind = "association"
    _KEYS = frozenset({"iou", "min_score", "max_score", "against", "direction", "appearance",
                       "tracks", "fuse_score", "buffer", "terms", "gates", "affinity",
                       "update"})

    def __init__(self, variable: str, *, rounds: list[dict[str, Any]] | None = None,
                 score_map: str = "none", direction_weight: float = 0.2, delta_t: int = 3,
                 appearance: list | None = None, appearance_weight: float = 0.5,
                 appearance_pixels: float = BOX_PIXELS,
                 terms: list[dict[str, Any]] | None = None,
                 gates: list[dict[str, Any]] | None = None, placed_level: float = PLACED_LEVEL,
                 gate_confidence: float | None = None, name: str | None = None):
        super().__init__(variable, name=name)
        self.terms = [self._extension(t, "term") for t in (terms or [])]
        self.gates = [self._extension(g, "gate") for g in (gates or [])]
        self.appearance: list | None = None
        if appearance is not None:
            from pgm.core.factor import factor_from_dict

            items = [factor_from_dict(a) if isinstance(a, dict) else a for a in appearance]
            for a in items:
                if not (isinstance(a, LikelihoodFactor) and hasattr(a, "learn")
                        and type(a).State is not None):
                    raise ValueError(f"factor {self.name!r}: appearance takes likelihood factors "
                                     f"that learn a model from a box (learn, log_likelihood, "
                                     f"and a State declaring what they learn: "
                                     f"pgm.core.learned), got {type(a).__name__}")
            self.appearance = items or None
        self.appearance_weight = float(check_finite_param(f"{self.name}.appearance_weight",
                                                          appearance_weight, nonneg=True))
        self.appearance_pixels = float(check_finite_param(f"{self.name}.appearance_pixels",
                                                          appearance_pixels, nonneg=True))
        if score_map not in SCORE_MAPS:
            raise ValueError(f"factor {self.name!r}: unknown score_map {score_map!r} (choose "
                             f"from {SCORE_MAPS})")
        self.score_map = score_map
        self.placed_level = float(check_finite_param(f"{self.name}.placed_level", placed_level,
                                                     nonneg=True))
        if self.placed_level > 1.0:
            raise ValueError(f"factor {self.name!r}: placed_level must be in [0, 1], got "
                             f"{placed_level!r}")
        self.gate_confidence = check_confidence(f"{self.name}.gate_confidence",
                                                gate_confidence)
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
            update = r.get("update", True)
            if not isinstance(update, bool):
                raise ValueError(f"factor {self.name!r}: a round's 'update' is true or false, "
                                 f"got {update!r}")
            self.rounds.append({"iou": iou, "min_score": lo, "max_score": hi,
                                "against": against, "direction": bool(r.get("direction")),
                                "appearance": bool(r.get("appearance")), "tracks": tracks,
                                "fuse_score": bool(r.get("fuse_score")),
                                "buffer": float(buffer),
                                "terms": [self._extension(t, "term")
                                          for t in (r.get("terms") or [])],
                                "gates": [self._extension(g, "gate")
                                          for g in (r.get("gates") or [])],
                                "affinity": affinity, "update": update})
        self.plans: list[RoundPlan] = [self._plan(r) for r in self.rounds]
        #: the rounds whose matches keep a track without updating it (``"update": false``)
        self.presence_rounds = tuple(i for i, r in enumerate(self.rounds) if not r["update"])
        #: the functions the rounds' terms name (what the rule must prepare inputs for)
        self.term_fns = frozenset(t["fn"] for p in self.plans for t in p.terms)

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
        return MOMENTUM in self.term_fns or any(p.affinity["args"].get("against") == "last"
                                                for p in self.plans)

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
            if not r["update"]:
                d["update"] = False
            rounds.append(d)
        p: dict[str, Any] = {"rounds": rounds, "score_map": self.score_map}
        if self.placed_level != PLACED_LEVEL:
            p["placed_level"] = self.placed_level
        if self.gate_confidence is not None:
            p["gate_confidence"] = self.gate_confidence
        if self.keeps_observations:
            p.update(direction_weight=self.direction_weight, delta_t=self.delta_t)
        if self.appearance is not None:
            p.update(appearance=[a.to_dict() for a in self.appearance],
                     appearance_weight=self.appearance_weight)
            if self.appearance_pixels != BOX_PIXELS:
                p["appearance_pixels"] = self.appearance_pixels
        if self.terms:
            p["terms"] = [dict(t) for t in self.terms]
        if self.gates:
            p["gates"] = [dict(g) for g in self.gates]
        return p

    def appearance_model(self) -> list | None:
        """A new replica's appearance model: the ``appearance`` factors bound to fresh
        learned states of its own (None without; the factors are not copied)."""
        if self.appearance is None:
            return None
        return [a.bind(a.fresh_state()) for a in self.appearance]

    def check(self, variables: dict[str, Variable]) -> None:
        require_box_coding(self, variables, self.variables[0])

    def scores(self, ctx: FrameContext,
               model: PersistenceScoreModel | ScoreQuantiles | PersistentQuantiles | None = None,
               boxes: np.ndarray | None = None,
               references: np.ndarray | None = None) -> np.ndarray:
        """The frame's detection scores, mapped; with a map learned on the video
        (:data:`LEARNED_SCORE_MAPS`), ``model`` (a run's :meth:`score_model`) sees the
        frame — its detections' centre ``boxes`` ``(M, 4)``, computed here when not given
        — and maps its scores; ``"placed"`` learns from ``references``, the predicted
        centre boxes of the tracks confirmed and matched in the previous frame."""
        d = ctx.detections
        if self.score_map not in LEARNED_SCORE_MAPS:
            return np.zeros(0) if d is None else map_scores(d.scores, self.score_map)
        if model is None:
            raise ValueError(f"factor {self.name!r}: the {self.score_map} score map needs the "
                             f"run's score model (score_model())")
        if boxes is None:
            boxes = (np.zeros((0, 4)) if d is None
                     else xywh_to_cxcywh(np.asarray(d.boxes, dtype=float)))
        s = np.zeros(0) if d is None else d.scores
        if self.score_map in PLACED_SCORE_MAPS:
            return model.update(boxes, s, references)
        return model.update(boxes, s)

    def score_model(self) -> PersistenceScoreModel | ScoreQuantiles | PersistentQuantiles | None:
        """A new run's score model (the maps of :data:`LEARNED_SCORE_MAPS`), or None."""
        if self.score_map == "learned":
            return PersistenceScoreModel()
        if self.score_map in PLACED_SCORE_MAPS:  # lifted to the updating rounds' threshold
            share = max((r["min_score"] for r in self.rounds if r["update"]), default=0.0)
            return PersistentQuantiles(placed=True, level=self.placed_level,
                                       rebase=self.score_map != "placed",
                                       over_clutter=self.score_map == "placed-over",
                                       confidence=self.gate_confidence,
                                       share=min(max(share, 0.0), 1.0))  # none: nothing cut
        if self.score_map in ("quantile-gated", "quantile-rebased"):
            return PersistentQuantiles(rebase=self.score_map == "quantile-rebased",
                                       confidence=self.gate_confidence)
        return ScoreQuantiles() if self.score_map == "quantile" else None
