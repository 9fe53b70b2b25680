"""A score's quantile with the clutter the video itself shows cut out
(:class:`PersistentQuantiles`: the ``"quantile-gated"`` and ``"quantile-rebased"`` score
maps)."""

from __future__ import annotations

import numpy as np

from pgm.core.boxes import iou_matrix
from pgm.core.numerics import check_finite_param
from pgm.factors.scores import PersistenceScoreModel

__all__ = ["PersistentQuantiles"]

#: where a box is moved to measure the chance level: by this many of its widths (left,
#: right) and heights (up, down) — past the reach of its own buffered box (1.5 of its
#: sizes with the model's quarter-size buffer), so a copy is found again only by another
#: detection
CHANCE_SHIFT = 2.0
_SHIFTS = CHANCE_SHIFT * np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.0, -1.0]])


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
    <pgm.factors.scores.PersistenceScoreModel.probability>`). That probability is
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
    ``q``, exactly. Online and deterministic; one instance per video.

    Parameters
    ----------
    floor : float
        The probability of being of a target below which a detection is read as clutter
        (0.5: more likely clutter than of a target).
    rebase : bool
        Take the quantile among the detections above ``u*`` (False: among all).
    **model_options
        The persistence model's settings (:class:`~pgm.factors.scores.PersistenceScoreModel`).
    """

    def __init__(self, floor: float = 0.5, rebase: bool = False, **model_options):
        self.rebase = bool(rebase)
        self.chance_found = 0  # moved copies found again, and copies labelled
        self.chance_labelled = 0
        self._previous: np.ndarray | None = None  # the previous frame's centre boxes
        # the lowest (x, y) and highest corners the boxes have covered
        self._extent: tuple[np.ndarray, np.ndarray] | None = None
        self.floor = float(check_finite_param("floor", floor, nonneg=True))
        if self.floor > 1.0:
            raise ValueError(f"floor must be in [0, 1], got {floor!r}")
        self.model = PersistenceScoreModel(**model_options)

    def chance(self) -> float:
        """``ρ_c``: the share of moved copies found again (0 before any is labelled)."""
        return self.chance_found / (self.chance_labelled + 1.0)

    def _label_chance(self, boxes: np.ndarray) -> None:
        """Label the previous frame's boxes, moved, by ``boxes`` (centre boxes)."""
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
        # both buffered by the model's share of their size on each side, as it labels
        grow = np.array([1.0, 1.0, 1.0 + 2.0 * self.model.buffer, 1.0 + 2.0 * self.model.buffer])
        moved = np.concatenate([centre[inside], size[inside]], axis=1) * grow
        found = iou_matrix(moved, boxes * grow).max(axis=1) >= self.model.gate
        self.chance_found += int(np.count_nonzero(found))
        self.chance_labelled += int(moved.shape[0])

    def threshold_quantile(self) -> float:
        """``u*``: the mid-rank quantile from which the model's probability above
        chance reaches ``floor`` (0: everywhere)."""
        m = self.model
        top, rho = float(m.curve[-1]), self.chance()
        if top <= rho:
            return 0.0
        ratio = np.clip((m.curve - rho) / (top - rho), 0.0, 1.0)
        centres = (np.arange(m.bins) + 0.5) / m.bins
        above = np.flatnonzero(ratio >= self.floor)
        b = int(above[0]) if above.size else m.bins - 1
        if b == 0:
            return 0.0
        lo, hi = ratio[b - 1], ratio[b]
        t = (self.floor - lo) / (hi - lo) if hi > lo else 1.0
        return float(centres[b - 1] + t * (centres[b] - centres[b - 1]))

    def update(self, boxes: np.ndarray, scores: np.ndarray) -> np.ndarray:
        """Add a frame's detections (centre boxes ``(M, 4)``, raw scores ``(M,)``) to the
        model and return their values ``q`` ``(M,)`` (NaN scores: 0)."""
        s = np.asarray(scores, dtype=float).reshape(-1)
        self.model.observe(boxes, s)
        self._label_chance(np.asarray(boxes, dtype=float).reshape(-1, 4))
        u = self.model.seen.mid_ranks(np.where(np.isfinite(s), s, -np.inf))
        star = self.threshold_quantile()
        if not self.rebase:
            q = np.where(u >= star, u, 0.0)
        elif star < 1.0:
            q = np.clip((u - star) / (1.0 - star), 0.0, 1.0)
        else:
            q = np.zeros(s.size)
        return np.where(np.isfinite(s), q, 0.0)
