"""A score's quantile with the clutter the video itself shows cut out
(:class:`PersistentQuantiles`: the ``"quantile-gated"``, ``"quantile-rebased"``,
``"placed"``, ``"placed-rebased"`` and ``"placed-over"`` score maps)."""

from __future__ import annotations

import numpy as np

from pgm.core.boxes import box_corners, iou_corners
from pgm.core.numerics import check_finite_param
from pgm.factors.persistence import PersistenceScoreModel

__all__ = ["PLACED_IOU", "PLACED_LEVEL", "PLACED_SCORE_MAPS", "PersistentQuantiles",
           "check_confidence"]

#: where a box is moved to measure the chance level: by this many of its widths (left,
#: right) and heights (up, down) — past the reach of its own buffered box (1.5 of its
#: sizes with the model's quarter-size buffer), so a copy is found again only by another
#: detection
CHANCE_SHIFT = 2.0
_SHIFTS = CHANCE_SHIFT * np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])
#: the IoU with a tracked object's box at which a detection is on it (the MOT metrics'
#: criterion for a box to count as the object's)
PLACED_IOU = 0.5
#: the placement, relative to the best-scored detections', at which ``"placed"`` lifts
#: the detections below the threshold to it
PLACED_LEVEL = 0.8
#: the score maps that learn from the tracks' predicted boxes too (``placed=True``)
PLACED_SCORE_MAPS = ("placed", "placed-rebased", "placed-over")


class PersistentQuantiles:
    r"""Each detection's score as its quantile, read as 0 where the detections at that
    score are more likely clutter than of a target, both learned on the video.

    A threshold on the plain quantile (:class:`~pgm.factors.scores.ScoreQuantiles`) is a
    share of the detections ("drop the lowest fifth"), and a share of the detections is
    a share of the objects only while the detector's output threshold stays where it
    was. Run the same detector with a lower threshold, as a user does with a probability
    detector (confidence 0.1 or less), and the lowest fifth are all clutter while the
    clutter above them passes. What the video shows of each score is how often the
    detections at it are found again in the next frame: the probability that a
    detection is of a target (:meth:`PersistenceScoreModel.probability
    <pgm.factors.persistence.PersistenceScoreModel.probability>`). That probability is
    non-decreasing in the score's mid-rank quantile ``u`` (the model's curve is pooled to
    be), so the detections more likely clutter than not, below ``floor``, are the scores
    below one quantile ``u*``: where the probability, interpolated as the model reads
    it, first reaches ``floor`` (0 when it does so everywhere).

    A false detection is "found again" by chance when another detection lands near it,
    which in a crowd is often: a place where no detection was is found again at the
    scene's **chance level** ``ρ_c``. The model's probability treats it as 0 (an upper
    bound where it is not); here it is measured. Each frame, every box of the previous
    frame is also moved by ``CHANCE_SHIFT`` of its widths (left, right) and heights (up,
    down); the copies that lie inside the area the video's boxes have covered are
    labelled found again or not by the same buffered IoU, and ``ρ_c`` is the share found
    again. The probability of being of a target is read as the found-again rate above
    chance over the best-scored detections' rate above chance, ``(ρ(u) − ρ_c) / (ρ_top −
    ρ_c)`` (0 below chance; no gate while ``ρ_top ≤ ρ_c``). A detection maps to

    .. math::
        q = u \ (u \ge u^*), \qquad 0 \ (u < u^*)

    (``"quantile-gated"``): a threshold ``t`` on ``q`` drops the lowest share ``t`` of
    the detections and every detection the video shows to be more likely clutter. With
    ``rebase=True`` (``"quantile-rebased"``) the share is taken of the detections above
    ``u*`` instead, ``q = (u − u*) / (1 − u*)`` there: the clutter is then read as added
    to the detector's usual output, not as part of its lowest share. With no clutter the
    video can see (``u* = 0``) both are the plain quantile. Both read the scores only
    through their ranks, so any strictly increasing map of the scores gives the same
    ``q``, exactly.

    With ``placed=True`` (``"placed"``) the share cut gives way where the tracker's own
    tracks show the detections it would cut to be placed as well as the best-scored ones.
    A detector's lowest scores are seldom clutter far from everyone: on the shared
    detectors they are boxes near a person but not on one (a part, a box too large, one
    off by half a width), and a fixed share cuts them. A detector run at a higher
    threshold has none left, and there the same share cuts people. Each frame, the
    detections near a track confirmed and matched in the previous frame (its predicted
    box, passed as ``references``; near: the persistence model's buffered IoU gate) are
    labelled on it when their IoU with that box is at least :data:`PLACED_IOU`, and a
    second curve over the same score quantiles is fitted to those labels (pooled
    non-decreasing, each bin shrunk towards 0 with the model's pseudo-detections).
    ``u_p`` is found going down from ``share`` (the threshold the association puts on
    ``q``) one bin at a time: the labelled detections from the bin reached up to
    ``share``, taken as one group, must be on their objects at least ``level`` times as
    often as the curve's top, and ``u_p`` is the last edge reached so (1 when the bin
    just below ``share`` is not; 1 before any label). The group's rate is shrunk
    towards 0 by the same pseudo-detections, so that a few labels lift nothing, and it
    is a group rather than each bin, so that a short video's few labels still decide.
    The detections from ``u_p`` up to ``share`` are lifted to ``share``, so the
    threshold keeps them. Where the low ranks are misplaced (``u_p ≥ share``) this is
    the gated quantile exactly.

    With both (``"placed-rebased"``) the lift works on the rebased quantile: the share
    ``share`` is cut from the detections above ``u*`` (at ``u = u* + share (1 − u*)``,
    where ``u_p`` is searched down from), and the detections from ``u_p`` up keep
    ``max(q, share)``. A detector run at a lower threshold adds clutter below its usual
    output; the gated quantile then reads the lowest share of the usual output as above
    the cut (the clutter took the share), the rebased one cuts it as it was. Where the
    video shows no clutter (``u* = 0``) this is ``"placed"`` exactly.

    With ``over_clutter=True`` as well (``"placed-over"``) the placement outranks the
    clutter gate for the detections it is about: a detection from ``u_p`` up that lies on
    a reference box (IoU at least :data:`PLACED_IOU`) keeps ``max(q, share)`` below
    ``u*`` too; one on no reference box stays 0 there. The gate is the weaker evidence in
    a crowd: it reads the found-again rate above chance relative to the best-scored
    detections', ``(ρ(u) − ρ_c) / (ρ_top − ρ_c)``, as if a true detection were found
    again as often at any score, but a person's low scores are the frames it is partly
    hidden in, found again less often, and with the chance level at 0.6–0.9
    (TUD-Stadtmitte) the denominator is small: a detector run at a higher threshold,
    with no clutter left, still gets its lowest twentieth or so read as clutter. A box on
    a confirmed track's predicted box, at a score whose boxes are on their tracks as
    often as the best-scored ones, is the direct evidence. Only such boxes: clutter far
    from every track is placed by no track, and lifting every box from ``u_p`` up lets
    it through (the synthetic scene with a lower detector threshold: MOTA 0.961 to
    0.709, ``docs/results.md``).

    Online and deterministic; one instance per video.

    Parameters
    ----------
    floor : float
        The probability of being of a target below which a detection is read as clutter
        (0.5: more likely clutter than of a target).
    rebase : bool
        Take the quantile among the detections above ``u*`` (False: among all).
    placed : bool
        Lift the detections above ``u_p`` to ``share``, ``u_p`` learned from
        ``references`` (False: the gated or rebased quantile); with ``rebase``, over the
        rebased quantile.
    share : float
        The threshold on ``q`` that ``placed`` lifts detections to.
    level : float
        The placement, relative to the best-scored detections', at which ``placed``
        lifts (:data:`PLACED_LEVEL`).
    over_clutter : bool
        With ``placed``: the lifted detections that lie on a reference box are lifted
        below ``u*`` too (False: read as 0 there, the gate first).
    confidence : float or None
        Cut only what the video shows to be clutter with this confidence (a one-sided
        test, :meth:`threshold_quantile`); None: the point estimate decides alone.
    **model_options
        The persistence model's settings (:class:`~pgm.factors.persistence.PersistenceScoreModel`).
    """

    def __init__(self, floor: float = 0.5, rebase: bool = False, placed: bool = False,
                 share: float = 0.2, level: float = PLACED_LEVEL, over_clutter: bool = False,
                 confidence: float | None = None, **model_options):
        self.rebase = bool(rebase)
        self.confidence = check_confidence("confidence", confidence)
        self._z: float | None = None  # the one-sided test's normal quantile
        if self.confidence is not None:
            from scipy.stats import norm

            self._z = float(norm.ppf(self.confidence))
        self.over_clutter = bool(over_clutter)
        if self.over_clutter and not placed:
            raise ValueError("over_clutter needs placed=True: it is the lift that outranks "
                             "the clutter gate")
        self.chance_found = 0  # moved copies found again, and copies labelled
        self.chance_labelled = 0
        self._previous: np.ndarray | None = None  # the previous frame's centre boxes
        # the lowest (x, y) and highest corners the boxes have covered
        self._extent: tuple[np.ndarray, np.ndarray] | None = None
        self.floor = float(check_finite_param("floor", floor, nonneg=True))
        if self.floor > 1.0:
            raise ValueError(f"floor must be in [0, 1], got {floor!r}")
        self.model = PersistenceScoreModel(**model_options)
        #: the on-its-object curve over the same scores (``placed``), or None
        self.placement = (PersistenceScoreModel(**{**model_options, "prior_rate": 0.0,
                                                   "seen": self.model.seen})
                          if placed else None)
        self.share = float(check_finite_param("share", share, nonneg=True))
        self.level = float(check_finite_param("level", level, nonneg=True))

    def chance(self) -> float:
        """``ρ_c``: the share of moved copies found again (0 before any is labelled)."""
        return self.chance_found / (self.chance_labelled + 1.0)

    def _label_chance(self, boxes: np.ndarray, reach: tuple) -> None:
        """Label the previous frame's boxes, moved, by ``boxes`` (centre boxes; ``reach``:
        their :meth:`~pgm.factors.persistence.PersistenceScoreModel.reach`)."""
        if boxes.shape[0]:
            lo, hi = (boxes[:, :2] - boxes[:, 2:] / 2).min(axis=0), \
                (boxes[:, :2] + boxes[:, 2:] / 2).max(axis=0)
            self._extent = (lo, hi) if self._extent is None else \
                (np.minimum(self._extent[0], lo), np.maximum(self._extent[1], hi))
        prev, self._previous = self._previous, boxes
        if prev is None or not prev.shape[0] or not boxes.shape[0]:
            return
        size = np.tile(prev[:, 2:], (4, 1))
        centre = (prev[None, :, :2] + _SHIFTS[:, None, :] * prev[None, :, 2:]).reshape(-1, 2)
        inside = np.all((centre - size / 2 >= self._extent[0])
                        & (centre + size / 2 <= self._extent[1]), axis=1)
        if not inside.any():
            return
        # found again as the model labels a detection (buffered reach)
        moved = np.concatenate([centre[inside], size[inside]], axis=1)
        found = self.model.near(moved, reach)
        self.chance_found += int(np.count_nonzero(found))
        self.chance_labelled += int(moved.shape[0])

    def threshold_quantile(self) -> float:
        """``u*``: the mid-rank quantile from which the model's probability above
        chance reaches ``floor`` (0: everywhere); with ``confidence``, only as far as the
        evidence reaches (:meth:`_evident`)."""
        m = self.model
        top, rho = float(m.curve[-1]), self.chance()
        if top <= rho:
            return 0.0
        star = _reaches(np.clip((m.curve - rho) / (top - rho), 0.0, 1.0), self.floor)
        return star if self._z is None or star == 0.0 else self._evident(star, top, rho)

    def _evident(self, star: float, top: float, rho: float) -> float:
        """``u*`` cut back to what the labels show with :attr:`confidence`.

        The bins below ``u*`` are read as clutter because their found-again rate is below
        the gate's level ``ρ_m = ρ_c + floor (ρ_top − ρ_c)``, a difference of estimates.
        In a crowd the chance level ``ρ_c`` is high and ``ρ_top − ρ_c`` small, and a
        detector's lowest scores, the frames a person is partly hidden in, are found again
        a little less often than its best: a few dozen labels then put the lowest bins
        below ``ρ_m`` by less than their own standard error. Grouped from the bottom
        (bins ``[0, k)`` as one), a group is cut when its rate ``r`` (``(h + ½) / (n +
        1)``) is below ``ρ_m`` by at least ``z`` standard errors of the difference
        (``z`` the normal quantile of :attr:`confidence`; the binomial variances of
        ``r``, of ``ρ_c`` over its copies and of ``ρ_top`` over the top bin's labels),
        and ``u*`` becomes the edge of the largest such group (``u*`` itself when it is
        every bin below ``u*``; 0 when there is none). A detector that adds clutter
        below its usual output puts many labels at the chance level, far below ``ρ_m``:
        cut as before, a few frames later."""
        m, f = self.model, self.floor
        b = min(max(int(np.ceil(star * m.bins - 0.5 - 1e-9)), 1), m.bins)  # centres below
        n, h = np.cumsum(m.counts[:b]), np.cumsum(m.hits[:b])
        r = (h + 0.5) / (n + 1.0)
        mid = rho + f * (top - rho)
        var_mid = ((1.0 - f) ** 2 * rho * (1.0 - rho) / max(self.chance_labelled, 1)
                   + f ** 2 * top * (1.0 - top) / max(float(m.counts[-1]), 1.0))
        evident = np.flatnonzero(mid - r >= self._z * np.sqrt(r * (1.0 - r) / (n + 1.0)
                                                              + var_mid))
        if not evident.size:
            return 0.0
        k = int(evident[-1]) + 1
        return star if k == b else k / m.bins

    def placed_quantile(self, cut: float | None = None) -> float:
        """``u_p``: the lowest bin edge from which the labelled detections up to ``cut``
        (the share's quantile, ``share`` by default), as one group, are on their objects
        at least ``level`` times as often as the placement curve's top (their rate shrunk
        towards 0 by the model's ``prior_weight`` pseudo-detections, once for the group),
        and so is every group between it and ``cut``; 1 where the bin just below ``cut``
        is not, before any detection is labelled, or without ``placed``."""
        p = self.placement
        if p is None or not p.labelled:
            return 1.0
        top = float(p.curve[-1])
        cut = self.share if cut is None else float(cut)
        below = min(int(np.ceil(cut * p.bins - 1e-9)), p.bins)  # bins under the cut
        if top <= 0 or below == 0:
            return 1.0
        # the bins from b up to the cut's, as one group, b from the cut's down: each
        # group placed in turn (a sequential test, every step on its own evidence)
        hits = np.cumsum(p.hits[:below][::-1])
        placed = hits / (np.cumsum(p.counts[:below][::-1]) + p.prior_weight) >= self.level * top
        k = below if placed.all() else int(np.argmin(placed))  # groups placed, nearest first
        return (below - k) / p.bins if k else 1.0

    def _label_placed(self, boxes: np.ndarray, scores: np.ndarray, references: np.ndarray,
                      reach: tuple, corners: tuple) -> None:
        """Label this frame's detections near a reference box (centre boxes) by whether
        they are on it (``reach``: the detections' reach, ``corners``: the references'
        :func:`~pgm.core.boxes.box_corners`)."""
        ok = np.isfinite(scores)
        if not references.shape[0] or not ok.any():
            return
        if not ok.all():
            boxes, scores, reach = boxes[ok], scores[ok], tuple(x[ok] for x in reach)
        near = self.model.near(reach, references)
        if near.any():
            on = iou_corners(box_corners(boxes[near]), corners).max(axis=1) >= PLACED_IOU
            self.placement.add_labels(scores[near], on)

    @staticmethod
    def _on_reference(boxes: np.ndarray, corners: tuple | None,
                      among: np.ndarray) -> np.ndarray:
        """Which detections (centre boxes) ``among`` (a mask) lie on a reference box (IoU
        at least :data:`PLACED_IOU`; ``corners``: the references' corners); the others
        False."""
        on = np.zeros(boxes.shape[0], dtype=bool)
        if corners is not None and corners[2].size and among.any():
            on[among] = iou_corners(box_corners(boxes[among]), corners).max(axis=1) >= PLACED_IOU
        return on

    def update(self, boxes: np.ndarray, scores: np.ndarray,
               references: np.ndarray | None = None) -> np.ndarray:
        """Add a frame's detections (centre boxes ``(M, 4)``, raw scores ``(M,)``) to the
        model and return their values ``q`` ``(M,)`` (NaN scores: 0); ``references``
        (centre boxes ``(K, 4)``): the tracked objects' predicted boxes that ``placed``
        learns from (ignored without it)."""
        s = np.asarray(scores, dtype=float).reshape(-1)
        b = np.asarray(boxes, dtype=float).reshape(-1, 4)
        self.model.observe(b, s)
        reach = self.model.last_reach
        self._label_chance(b, reach)
        u = self.model.seen.mid_ranks(np.where(np.isfinite(s), s, -np.inf))
        star = self.threshold_quantile()
        v = _rebased(u, star) if self.rebase else u  # rebased: 0 below u* already
        if self.placement is None:
            q = v if self.rebase else np.where(u >= star, u, 0.0)
        else:
            corners = None
            if references is not None:
                ref = np.asarray(references, dtype=float).reshape(-1, 4)
                corners = box_corners(ref)
                self._label_placed(b, s, ref, reach, corners)
            # the share cut from the detections above u* when rebased (u* = 0: as is)
            cut = star + self.share * (1.0 - star) if self.rebase else self.share
            lift = u >= self.placed_quantile(cut)
            above = u >= star
            # over_clutter: below u*, the lifted ones on a reference box are lifted too
            if self.over_clutter:
                lift &= above | self._on_reference(b, corners, lift & ~above)
            else:
                lift &= above
            q = np.where(lift, np.maximum(v, self.share), np.where(above, v, 0.0))
        return np.where(np.isfinite(s), q, 0.0)


def _rebased(u: np.ndarray, star: float) -> np.ndarray:
    """Quantiles ``u`` as quantiles among the detections above ``u*``: ``(u − u*) / (1 −
    u*)`` clipped to [0, 1] (0 below ``u*``; 0 everywhere when ``u*`` is 1)."""
    return np.clip((u - star) / (1.0 - star), 0.0, 1.0) if star < 1.0 else np.zeros(u.size)


def _reaches(ratio: np.ndarray, level: float) -> float:
    """The mid-rank quantile from which a non-decreasing curve at ``bins`` equal bins'
    centres first reaches ``level``, interpolated between centres (0: everywhere)."""
    bins = ratio.size
    centres = (np.arange(bins) + 0.5) / bins
    above = np.flatnonzero(ratio >= level)
    b = int(above[0]) if above.size else bins - 1
    if b == 0:
        return 0.0
    lo, hi = ratio[b - 1], ratio[b]
    t = (level - lo) / (hi - lo) if hi > lo else 1.0
    return float(centres[b - 1] + t * (centres[b] - centres[b - 1]))


def check_confidence(name: str, value: float | None) -> float | None:
    """``value`` as the confidence of a one-sided test (a float in ``[0.5, 1)``), or None;
    a ``ValueError`` naming ``name`` otherwise."""
    if value is None:
        return None
    c = float(check_finite_param(name, value, nonneg=True))
    if not 0.5 <= c < 1.0:
        raise ValueError(f"{name} must be in [0.5, 1), got {value!r}")
    return c
