"""Every score a video has shown, kept sorted at a cost per frame that does not grow with
the video (:class:`SortedScores`: the score maps that read a score's rank)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["RECENT_SCORES", "SortedScores", "insert_sorted"]

#: a sorted score store's recent part joins the rest past this many scores (and past
#: four times the square root of the rest's count): each frame's insertion then costs the
#: recent part, not the whole video, and the merges cost the video now and then
RECENT_SCORES = 4096


def insert_sorted(at: np.ndarray, size: int, *arrays_values: tuple[np.ndarray, np.ndarray]
                  ) -> list[np.ndarray]:
    """Each ``(array, values)`` pair's ``np.insert(array, at, values)`` for one
    non-decreasing ``at`` (``(m,)`` places in arrays of ``size`` elements; a batch sorted
    and placed by ``np.searchsorted``): value ``k`` lands at ``at[k] + k`` and the array's
    own elements fill the rest in order — the same arrays, the places found once for all
    the pairs and without ``np.insert``'s general path (a frame's handful of scores)."""
    m = at.size
    slots = at + np.arange(m)
    keep = np.ones(size + m, dtype=bool)
    keep[slots] = False
    out = []
    for array, values in arrays_values:
        merged = np.empty(size + m, dtype=array.dtype)
        merged[slots] = values
        merged[keep] = array
        out.append(merged)
    return out


def _merge_due(recent: int, older: int, least: int) -> bool:
    """Whether a recent part of ``recent`` scores joins the ``older`` ones now (more than
    ``least`` and more than ``4 sqrt(older)``)."""
    return recent > max(least, 4.0 * math.sqrt(older))


class SortedScores:
    """Every finite score added so far, as one sorted sequence kept in two sorted parts:
    the older scores and the recent ones, each recent score with its place among the older
    (how many of them are at most it). The recent part joins the older one once it
    outgrows ``max(RECENT, 4 sqrt(n))``.

    A frame's scores are inserted into the recent part only, so adding them costs that part
    (at most a few thousand numbers), not the video: a single sorted array of an hour of
    ten detections a frame (a million scores) costs 0.6 ms a frame to insert into, three
    hours 2.6 ms. The merges cost the video once every ``4 sqrt(n)`` scores. Counting the
    scores below a value is a search in each part; the score at a rank of the whole
    sequence is found from the recent scores' places (:meth:`at`). Every answer is that of
    the one sorted array (:meth:`sorted`), exactly.
    """

    #: the recent part joins the older one past this many scores (:func:`_merge_due`)
    RECENT = RECENT_SCORES

    def __init__(self) -> None:
        self._older = np.zeros(0)                      # sorted
        self._recent = np.zeros(0)                     # sorted, since the last merge
        self._place = np.zeros(0, dtype=np.intp)       # older scores <= each recent one
        # (kept once there are older scores: until the first merge every score is recent)
        self._memo: dict = {}  # answers computed from the scores as they are (:meth:`memo`)

    @property
    def size(self) -> int:
        """How many scores are kept."""
        return self._older.size + self._recent.size

    def sorted(self) -> np.ndarray:
        """Every score kept, sorted (a new array)."""
        if not self._older.size:
            return self._recent.copy()
        return np.insert(self._older, self._place, self._recent)

    def add(self, scores: np.ndarray) -> None:
        """Keep the finite ones of ``scores``."""
        s = np.asarray(scores, dtype=float).reshape(-1)
        new = np.sort(s[np.isfinite(s)])
        if not new.size:
            return
        self._memo.clear()
        at = np.searchsorted(self._recent, new)
        if self._older.size:
            self._recent, self._place = insert_sorted(
                at, self._recent.size, (self._recent, new),
                (self._place, np.searchsorted(self._older, new, side="right")))
        else:
            (self._recent,) = insert_sorted(at, self._recent.size, (self._recent, new))
        if _merge_due(self._recent.size, self._older.size, self.RECENT):
            self._older = self.sorted()
            self._recent = np.zeros(0)
            self._place = np.zeros(0, dtype=np.intp)

    def memo(self, key, compute):
        """``compute()``, kept under ``key`` until scores are next added: models that share
        the store (a second curve over the same scores) compute what depends on the
        scores alone once a frame."""
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]

    def count(self, values: np.ndarray, side: str = "left") -> np.ndarray:
        """How many scores are below each of ``values`` (``side="right"``: at most it), as
        ``np.searchsorted(self.sorted(), values, side)``."""
        n = np.searchsorted(self._recent, values, side=side)
        return n + np.searchsorted(self._older, values, side=side) if self._older.size else n

    def mid_ranks(self, values: np.ndarray) -> np.ndarray:
        """Each of ``values`` as its mid-rank quantile among the scores kept,
        :func:`pgm.factors.scores.mid_ranks` of :meth:`sorted`."""
        v = np.asarray(values, dtype=float).reshape(-1)
        n = self.size
        if n == 0:
            return np.full(v.size, 0.5)
        return (self.count(v, "left") + self.count(v, "right")) / (2.0 * n)

    def at(self, ranks: np.ndarray) -> np.ndarray:
        """The scores at 0-based ``ranks`` of the sorted sequence (each in ``[0, size)``),
        ``self.sorted()[ranks]``: recent score ``j`` stands at ``j + place[j]``; a rank no
        recent score holds is the older score ``rank − (recent scores before it)``."""
        k = np.asarray(ranks, dtype=np.intp)
        if not self._recent.size:
            return self._older[k]
        if not self._older.size:
            return self._recent[k]
        where = np.arange(self._recent.size) + self._place
        j = np.searchsorted(where, k, side="left")
        jj = np.minimum(j, where.size - 1)
        recent = where[jj] == k
        older = self._older[np.clip(k - j, 0, self._older.size - 1)]
        return np.where(recent, self._recent[jj], older)
