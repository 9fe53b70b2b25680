"""Plates: a sub-graph replicated once per tracked target.

A :class:`Plate` marks some variables of a :class:`~pgm.FactorGraph` (and with them
every factor whose scope lies inside it) as one *replica per target*, as the plate
notation of the textbooks draws a box labelled ``K`` around them. The graph is declared
once, for one target; the engine (:class:`pgm.inference.Engine`, with
:mod:`pgm.inference.plates`) keeps the replicas' beliefs batched along a leading target
axis (:mod:`pgm.core.batched`: ``(K, N, d)`` particles), adds a replica when a target is
born and removes it when its track ends.

What is shared and what is per replica:

* a factor's *parameters* live once, in the declaration (the learned dynamics of a
  GPDM, the noise of a transition): every replica uses the same factor object unless
  the factor learns per target;
* what a factor *learns* from the image (a colour template, a correlation filter) is
  its typed learned state (:mod:`pgm.core.learned`): each replica gets a fresh one at
  its birth and uses a view of the one factor bound to it, so each target keeps its own
  appearance and no factor is copied;
* the prior of each plate variable is re-centred on the target's birth box
  (``prior.born_at``);
* factors *between* replicas are of kind ``"interaction"`` (e.g.
  :class:`~pgm.factors.plates.MutualExclusion`): one factor, read by every replica
  against the others.

The track life cycle (confirmation after ``confirm_hits`` detections, coasting, a lost
stage for re-identification, an existence score, identities) is the plate's
:class:`Lifecycle`, declared with it and saved with the graph.

>>> p = Plate("target", ["box"])
>>> Plate.from_dict(p.to_dict()) == p
True
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields
from typing import Any

__all__ = ["Plate", "Lifecycle", "EXPLAIN_TENTATIVE"]


def _check_number(name: str, value: Any, low: float, high: float = float("inf"),
                  integer: bool = False) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"plate lifecycle: {name} must be a number, got {value!r}")
    if integer and int(value) != value:
        raise ValueError(f"plate lifecycle: {name} must be an integer, got {value!r}")
    if not (low <= value <= high):  # also false for NaN
        raise ValueError(f"plate lifecycle: {name} must be in [{low}, {high}], got {value!r}")


#: what may explain a tentative replica's detection (:attr:`Lifecycle.explain_tentative`)
EXPLAIN_TENTATIVE = ("none", "prediction", "detection")


@dataclass(frozen=True)
class Lifecycle:
    """How replicas of a plate start and end (the track layer of a plate).

    Each frame the replicas' estimated boxes are matched to the frame's detections
    (Hungarian assignment on ``1 − IoU``, a match needs IoU ≥ ``match_iou``). A
    detection that matches no replica and overlaps none by more than ``birth_iou`` (and
    scores at least ``birth_min_score``) starts a new replica, *tentative* until it has
    been matched ``confirm_hits`` frames; a tentative replica is removed at its first
    miss. A confirmed replica without a match is reported for ``max_coast`` frames
    (coasting; default 0: chosen leave one sequence out on the shared MOT sequences with
    ``benchmarks/plate_trackers.py --choose``, where every frame of coasting cost MOTA),
    kept unreported until ``max_lost`` frames (lost: a later match brings it
    back under its old identity) and then removed. The existence score is the logistic
    of a log-odds that gains ``hit_log_odds`` per match and loses ``miss_log_odds`` per
    miss (clamped to ±10).

    The classic trackers' variants of this life cycle (:mod:`pgm.models.sort`):
    ``confirm_on="streak"`` confirms after ``confirm_hits`` matches *in a row*
    (ByteTrack) instead of in all; ``recover_hits`` is the number of matches in a row
    before a lost replica found again is reported (default ``confirm_hits``; 1 reports
    it at once, as SORT and ByteTrack do); ``report="detection"`` reports a replica only
    in the frames where a detection was assigned to it, with that detection's box (what
    the ``trackers`` package writes), instead of its estimate, and ``report="matched"``
    with its estimate in those frames only; ``birth_iou = 1`` starts
    a replica on every free detection, however much it overlaps the others.

    Attributes
    ----------
    confirm_hits, max_coast, max_lost : int
    match_iou, birth_iou : float
        IoU thresholds in [0, 1].
    birth_min_score : float
        Detections scoring below it never start a replica (``-inf``: all do).
    hit_log_odds, miss_log_odds : float
    confirm_on : {"hits", "streak"}
    recover_hits : int, optional
    report : {"estimate", "detection", "matched"}
    tentative_lost : int
        Frames a tentative replica survives without a match (0: its first miss ends it;
        OC-SORT keeps it as long as a confirmed one).
    birth_counts : bool
        Whether the detection a replica is born on counts as its first match towards
        ``confirm_hits`` (False: OC-SORT's count, which starts after it).
    warmup_frames : int
        During the video's first ``warmup_frames + 1`` frames a matched replica is
        confirmed (and reported) at once (SORT's and OC-SORT's start-up rule).
    activate_first : bool
        The replicas born in the engine's first frame are confirmed at once (given
        identities) and reported in that frame with their birth boxes (BoT-SORT's and
        C-BIoU's first-frame activation; ``warmup_frames`` confirms matched replicas
        only, and a replica is matched from its second frame on).
    explain_tentative : {"none", "prediction", "detection"}
        The birth rule applied to every match of a tentative replica, which is a birth
        not yet confirmed: it is removed when its detection is one a confirmed replica
        explains — ``"prediction"``: the detection overlaps a confirmed replica's
        predicted box by more than ``birth_iou``; ``"detection"``: it overlaps, by more
        than ``birth_iou``, a higher-scored detection matched to a confirmed replica
        (a weaker second box on a tracked person). ``"none"``: only births are checked.
    fill_gaps : int
        A reported replica found again after at most this many frames without being
        reported also reports the frames between, its box interpolated between the two it
        reported in the world the camera sees (through the frames' camera motions)
        (:attr:`~pgm.inference.info.PlateInfo.filled`; written when it is found, as rows
        of the earlier frames; not when another replica's reported boxes overlap it by
        more than ``birth_iou`` at both ends of the gap: one object, reported twice); 0:
        never.
    fill_after : int, optional
        Matches in a row a replica found again needs before its gap is filled (None:
        ``confirm_hits``, the evidence a birth needs: a gap closed on one match may
        have been closed on a false detection; 1: at once).
    fill_births : bool
        A replica confirmed also reports the frames it was tentative in (matched, not yet
        reported), with the boxes estimated then, as rows of those frames written when it
        is confirmed: the confirmation count is then evidence asked before a track is
        reported, not frames it loses.
    """

    confirm_hits: int = 3
    max_coast: int = 0
    max_lost: int = 30
    match_iou: float = 0.3
    birth_iou: float = 0.3
    birth_min_score: float = float("-inf")
    hit_log_odds: float = 1.0
    miss_log_odds: float = 1.0
    confirm_on: str = "hits"
    recover_hits: int | None = None
    report: str = "estimate"
    tentative_lost: int = 0
    warmup_frames: int = 0
    birth_counts: bool = True
    activate_first: bool = False
    explain_tentative: str = "none"
    fill_gaps: int = 0
    fill_after: int | None = None
    fill_births: bool = False

    def __post_init__(self) -> None:
        _check_number("confirm_hits", self.confirm_hits, 1, integer=True)
        _check_number("max_coast", self.max_coast, 0, integer=True)
        _check_number("max_lost", self.max_lost, self.max_coast, integer=True)
        _check_number("match_iou", self.match_iou, 0.0, 1.0)
        _check_number("birth_iou", self.birth_iou, 0.0, 1.0)
        if isinstance(self.birth_min_score, bool) or not isinstance(
                self.birth_min_score, (int, float)) or self.birth_min_score != self.birth_min_score:
            raise ValueError(f"plate lifecycle: birth_min_score must be a number, got "
                             f"{self.birth_min_score!r}")
        _check_number("hit_log_odds", self.hit_log_odds, 0.0)
        _check_number("miss_log_odds", self.miss_log_odds, 0.0)
        if self.confirm_on not in ("hits", "streak"):
            raise ValueError(f"plate lifecycle: confirm_on must be 'hits' or 'streak', got "
                             f"{self.confirm_on!r}")
        if self.recover_hits is not None:
            _check_number("recover_hits", self.recover_hits, 1, integer=True)
        _check_number("tentative_lost", self.tentative_lost, 0, integer=True)
        _check_number("warmup_frames", self.warmup_frames, 0, integer=True)
        _check_number("fill_gaps", self.fill_gaps, 0, integer=True)
        if self.fill_after is not None:
            _check_number("fill_after", self.fill_after, 1, integer=True)
        for name in ("birth_counts", "activate_first", "fill_births"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"plate lifecycle: {name} must be a bool, got "
                                 f"{getattr(self, name)!r}")
        if self.explain_tentative not in EXPLAIN_TENTATIVE:
            raise ValueError(f"plate lifecycle: explain_tentative must be one of "
                             f"{EXPLAIN_TENTATIVE}, got {self.explain_tentative!r}")
        if self.report not in ("estimate", "detection", "matched"):
            raise ValueError(f"plate lifecycle: report must be 'estimate', 'detection' or "
                             f"'matched', got {self.report!r}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready settings (``-inf`` written as ``null``)."""
        d = asdict(self)
        if d["birth_min_score"] == float("-inf"):
            d["birth_min_score"] = None
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> Lifecycle:
        """Inverse of :meth:`to_dict`; unknown keys are a ``ValueError``."""
        d = dict(d or {})
        known = {f.name for f in fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise ValueError(f"plate lifecycle: unknown settings {sorted(unknown)} "
                             f"(known: {sorted(known)})")
        if d.get("birth_min_score", 0.0) is None:
            d["birth_min_score"] = float("-inf")
        return cls(**d)


@dataclass(frozen=True)
class Plate:
    """A set of variables replicated once per target.

    Parameters
    ----------
    name : str
        The plate's name (e.g. ``"target"``).
    variables : sequence of str
        The variables inside the plate.
    size_label : str
        The letter the drawing writes in the plate's corner (``"K"``).
    lifecycle : Lifecycle
        Births and deaths of replicas.
    """

    name: str
    variables: tuple[str, ...]
    size_label: str = "K"
    lifecycle: Lifecycle = field(default_factory=Lifecycle)

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"plate name must be a non-empty string, got {self.name!r}")
        if isinstance(self.variables, str):
            raise ValueError(f"plate {self.name!r}: variables must be a list of names, not "
                             f"the string {self.variables!r}")
        names = tuple(self.variables)
        if not names:
            raise ValueError(f"plate {self.name!r} holds no variable")
        for v in names:
            if not isinstance(v, str) or not v:
                raise ValueError(f"plate {self.name!r}: variable names must be strings, got "
                                 f"{v!r}")
        if len(set(names)) != len(names):
            raise ValueError(f"plate {self.name!r} lists a variable twice: {list(names)}")
        object.__setattr__(self, "variables", names)
        if not isinstance(self.lifecycle, Lifecycle):
            raise ValueError(f"plate {self.name!r}: lifecycle must be a Lifecycle, got "
                             f"{self.lifecycle!r}")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready declaration."""
        return {"name": self.name, "variables": list(self.variables),
                "size_label": self.size_label, "lifecycle": self.lifecycle.to_dict()}

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Plate:
        """Inverse of :meth:`to_dict`."""
        if not isinstance(d, dict):
            raise ValueError(f"malformed plate declaration {d!r}")
        try:
            return cls(name=d["name"], variables=tuple(d["variables"]),
                       size_label=str(d.get("size_label", "K")),
                       lifecycle=Lifecycle.from_dict(d.get("lifecycle")))
        except (KeyError, TypeError) as exc:
            raise ValueError(f"malformed plate declaration: missing {exc}") from None
