"""What a detection's score says about the detection, learned on the video itself from
which detections are found again (:class:`PersistenceScoreModel`: the ``"learned"`` score
map, and the clutter curve of the gated and placed maps); ``pgm.factors.scores`` exports
it too."""

from __future__ import annotations

import numpy as np

from pgm.core.boxes import box_corners, iou_corners
from pgm.core.numerics import check_finite_param
from pgm.factors.sorted_scores import RECENT_SCORES, SortedScores, _merge_due, insert_sorted

__all__ = ["PersistenceScoreModel"]


def _pool_adjacent(p: np.ndarray, w: np.ndarray) -> np.ndarray:
    """The weighted least-squares non-decreasing fit to ``p`` (pool adjacent violators;
    a few bins, so a loop over blocks; none where ``p`` is already non-decreasing)."""
    if np.all(p[1:] >= p[:-1]):
        return p.astype(float)
    vals, wts, sizes = [], [], []
    for v, x in zip(p.tolist(), w.tolist(), strict=True):
        vals.append(v)
        wts.append(x)
        sizes.append(1)
        while len(vals) > 1 and vals[-2] > vals[-1]:
            x2, x1 = wts.pop(), wts.pop()
            v2, v1 = vals.pop(), vals.pop()
            n2, n1 = sizes.pop(), sizes.pop()
            vals.append((v1 * x1 + v2 * x2) / (x1 + x2))
            wts.append(x1 + x2)
            sizes.append(n1 + n2)
    return np.repeat(np.array(vals), sizes)


class PersistenceScoreModel:
    r"""What a detection's score says about the detection, learned on the video itself.

    A detector's score is a number on its own scale (a probability, a logit, an SVM
    margin, a rank); a tracker's thresholds must not depend on which. This model turns
    each score into a probability with a meaning that is the same for every detector:
    **the probability that the detection is found again in the next frame** — that a
    detection of the next frame overlaps it (buffered IoU: both boxes widened by
    ``buffer`` of their size on each side, as C-BIoU's, so that a fast or low-frame-rate
    target still counts; IoU at least ``gate``). A person is detected again; most false
    detections are not. The probability is a function of the score's *rank* among every
    score the video has shown so far (its mid-rank quantile, :func:`mid_ranks`), so any
    strictly increasing map of the scores gives the same probabilities, exactly.

    The function is learned online, frame by frame, from the detections themselves (no
    ground truth, no tracker output, so no feedback from the thresholds it serves): the
    previous frame's detections are labelled found-again or not by this frame's boxes;
    the labelled detections are counted in ``bins`` equal bins of their (current) rank
    quantile; each bin's rate is shrunk towards the video's overall rate with
    ``prior_weight`` pseudo-detections (a Beta prior centred on it) and the bins are made
    non-decreasing in the score (pool adjacent violators: a higher score never says
    less); a score's probability is the linear interpolation between bin centres. Before
    any detection is labelled every probability is 1 (each detection taken as it comes).

    Deterministic; one instance per video (the association rule keeps it per run). A
    refit counts each bin's labelled detections between the bins' first scores in the
    sorted labelled scores (the same counts as binning every one of them), and every score
    so far is kept in a :class:`~pgm.factors.sorted_scores.SortedScores`, so a frame costs
    about the same at any point of a long video: the score gate's update
    (:class:`~pgm.factors.persistent_quantiles.PersistentQuantiles`, ten detections a
    frame) 0.26 ms at frame 1 000 and 0.32 at 60 000, where binning every labelled score
    took 17 ms after 6 000 frames and one sorted array of every score 0.58 ms at 60 000.

    Parameters
    ----------
    bins : int
        Quantile bins of the score (20).
    prior_weight : float
        Pseudo-detections per bin at the video's overall rate (5).
    buffer : float
        Widening of both boxes on each side, a fraction of the box's width and height
        (0.25).
    gate : float
        Buffered IoU a detection of the next frame needs to count (0.3).
    prior_rate : float, optional
        The rate the bins are shrunk towards (default: the video's overall rate).
    seen : SortedScores, optional
        The store of every score to bin by (default: the model's own, which
        :meth:`observe` fills); another model's, to learn a second curve over its
        scores from labels given with :meth:`add_labels`.
    """

    #: the recent labelled scores join the older ones past this many (:func:`_merge_due`)
    RECENT = RECENT_SCORES

    def __init__(self, bins: int = 20, prior_weight: float = 5.0, buffer: float = 0.25,
                 gate: float = 0.3, prior_rate: float | None = None,
                 seen: SortedScores | None = None):
        if isinstance(bins, bool) or int(bins) != bins or bins < 1:
            raise ValueError(f"bins must be a positive integer, got {bins!r}")
        self.bins = int(bins)
        self.prior_weight = float(check_finite_param("prior_weight", prior_weight, nonneg=True))
        self.buffer = float(check_finite_param("buffer", buffer, nonneg=True))
        self.gate = float(check_finite_param("gate", gate, nonneg=True))
        self.prior_rate = (None if prior_rate is None
                           else float(check_finite_param("prior_rate", prior_rate, nonneg=True)))
        self.seen = SortedScores() if seen is None else seen  # every score so far
        # the labelled detections' scores, sorted, in two parts (an older one with the
        # running count of those found again, and the recent ones, merged into it now and
        # then): each frame's refit then costs the bins and the recent part, not the video
        self._older = np.zeros(0)
        self._older_found = np.zeros(1, dtype=np.int64)  # running count, from 0
        self._recent = np.zeros(0)
        self._recent_found = np.zeros(0, dtype=bool)
        #: the previous frame's finite scores, in their order, and whether each was found
        #: again, labelled by the latest frame (empty before the second frame): a caller
        #: that wants every label collects these (the model keeps only their counts)
        self.last_labelled: tuple[np.ndarray, np.ndarray] = (np.zeros(0),
                                                             np.zeros(0, dtype=bool))
        # the previous frame's scores and its boxes' reach
        self._previous: tuple[np.ndarray, tuple] | None = None
        #: the latest frame's boxes' :meth:`reach` (for others comparing them that frame)
        self.last_reach = self.reach(np.zeros((0, 4)))
        self.curve = np.ones(self.bins)  # the fitted probability at each bin's centre
        self.counts, self.hits = np.zeros(self.bins), np.zeros(self.bins)  # labelled, found

    @property
    def history(self) -> np.ndarray:
        """Every finite score so far, sorted."""
        return self.seen.sorted()

    @property
    def labelled(self) -> int:
        """How many detections have been labelled."""
        return self._older.size + self._recent.size

    def _label(self, scores: np.ndarray, found: np.ndarray) -> None:
        """Add labelled detections to the recent part, merged into the older one when due."""
        self.last_labelled = (scores, found)
        order = np.argsort(scores, kind="stable")  # placed as a sorted batch
        scores, found = scores[order], found[order]
        at = np.searchsorted(self._recent, scores)
        self._recent, self._recent_found = insert_sorted(
            at, self._recent.size, (self._recent, scores), (self._recent_found, found))
        if _merge_due(self._recent.size, self._older.size, self.RECENT):
            values = np.concatenate([self._older, self._recent])
            order = np.argsort(values, kind="stable")
            hits = np.concatenate([np.diff(self._older_found).astype(bool),
                                   self._recent_found])[order]
            self._older = values[order]
            self._older_found = np.concatenate([[0], np.cumsum(hits)])
            self._recent = np.zeros(0)
            self._recent_found = np.zeros(0, dtype=bool)

    def add_labels(self, scores: np.ndarray, found: np.ndarray) -> None:
        """Label detections with finite ``scores`` (of :attr:`seen`) by ``found`` and refit."""
        self._label(np.asarray(scores, dtype=float), np.asarray(found, dtype=bool))
        self._fit()

    def reach(self, boxes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Centre boxes ``(N, 4)`` widened by :attr:`buffer` on each side about their
        centres, as corners (:func:`~pgm.core.boxes.box_corners`): what :meth:`near`
        compares, computed once for boxes compared more than once."""
        g = 1.0 + 2.0 * self.buffer
        return box_corners(np.asarray(boxes, dtype=float).reshape(-1, 4)
                           * np.array([1.0, 1.0, g, g]))

    def near(self, boxes: np.ndarray | tuple, others: np.ndarray | tuple) -> np.ndarray:
        """``(N,)`` whether each centre box reaches one of the centre boxes ``others``:
        both widened by :attr:`buffer` on each side, an IoU of at least :attr:`gate`
        (either given as centre boxes or as their :meth:`reach`)."""
        a = boxes if isinstance(boxes, tuple) else self.reach(boxes)
        b = others if isinstance(others, tuple) else self.reach(others)
        if not a[2].size or not b[2].size:
            return np.zeros(a[2].size, dtype=bool)
        return iou_corners(a, b).max(axis=1) >= self.gate

    def update(self, boxes: np.ndarray, scores: np.ndarray) -> np.ndarray:
        """:meth:`observe`, then this frame's target probabilities ``(M,)``."""
        return self.probability(self.observe(boxes, scores))

    def observe(self, boxes: np.ndarray, scores: np.ndarray) -> np.ndarray:
        """Add a frame's detections (centre boxes ``(M, 4)``, raw scores ``(M,)``): label
        the previous frame's and refit; the scores as kept (NaN where not finite)."""
        b = np.asarray(boxes, dtype=float).reshape(-1, 4)
        s = np.asarray(scores, dtype=float).reshape(-1)
        if s.size != b.shape[0]:
            raise ValueError(f"{b.shape[0]} boxes but {s.size} scores")
        s = np.where(np.isfinite(s), s, np.nan)
        self.last_labelled = (np.zeros(0), np.zeros(0, dtype=bool))
        self.last_reach = self.reach(b)
        if self._previous is not None and self._previous[0].size:
            ps, previous_reach = self._previous
            again, ok = self.near(previous_reach, self.last_reach), ~np.isnan(ps)
            self._label(ps[ok], again[ok])
        self.seen.add(s)
        self._previous = (s, self.last_reach)
        self._fit()
        return s

    def _bin(self, scores: np.ndarray) -> np.ndarray:
        """The quantile bin of each score (of the history): ``⌊bins · u⌋``, ``u`` its
        mid-rank quantile (:func:`~pgm.factors.scores.mid_ranks`), at most ``bins − 1``."""
        u = self.seen.mid_ranks(scores)
        return np.minimum((u * self.bins).astype(int), self.bins - 1)

    def _bin_starts(self) -> np.ndarray:
        """``(bins − 1,)`` the smallest score of the history in each bin from the second on
        (``inf`` where none). The bin is non-decreasing in the score, so a labelled score
        (one of the history's) is in bin ``b`` or above exactly when it is at least the
        ``b``-th start. Bin ``b`` starts at the tie group holding rank ``⌊b n / bins⌋`` or
        at the next one (a group before it has its mid-rank half a rank or more below
        ``b n / bins``, the one after half a rank or more above): their values, and their
        neighbours', are the only candidates binned (computed once per store and bin
        count while no score is added: :meth:`SortedScores.memo`)."""
        return self.seen.memo(("bin_starts", self.bins), self._find_bin_starts)

    def _find_bin_starts(self) -> np.ndarray:
        seen, bins, n = self.seen, self.bins, self.seen.size
        base = np.floor(np.arange(1, bins) * (n / bins)).astype(np.intp)
        at_pos = seen.at(np.clip(np.concatenate([base - 1, base, base + 1]), 0, n - 1))
        after = np.minimum(seen.count(at_pos, side="right"), n - 1)
        values = np.sort(np.concatenate([at_pos, seen.at(after)]))
        values = values[np.concatenate([[True], values[1:] != values[:-1]])]  # np.unique
        at = np.searchsorted(self._bin(values), np.arange(1, bins), side="left")
        return np.where(at < values.size, values[np.minimum(at, values.size - 1)], np.inf)

    def _fit(self) -> None:
        n = self._older.size + self._recent.size
        if n == 0:
            self.curve = np.ones(self.bins)
            return
        # each bin's labelled detections and those found again, counted between the bins'
        # starts in the two sorted parts (the same counts as binning every one of them)
        edges = self._bin_starts()
        below = np.searchsorted(self._older, edges, side="left")
        hit_below = self._older_found[below]
        recent_hits = np.concatenate([[0], np.cumsum(self._recent_found)])
        r_below = np.searchsorted(self._recent, edges, side="left")
        at = np.concatenate([[0], below + r_below, [n]])
        hit_at = np.concatenate([[0], hit_below + recent_hits[r_below],
                                 [self._older_found[-1] + recent_hits[-1]]])
        count = np.diff(at).astype(float)
        hits = np.diff(hit_at).astype(float)
        self.counts, self.hits = count, hits
        overall = (hits.sum() + 1.0) / (n + 1.0) if self.prior_rate is None else self.prior_rate
        w = self.prior_weight
        rate = (hits + w * overall) / np.maximum(count + w, 1e-12)
        self.curve = _pool_adjacent(rate, count + w)

    def found_again(self, scores: np.ndarray) -> np.ndarray:
        """``(M,)`` the probability that each detection is found again in the next frame
        (NaN scores: the lowest bin's)."""
        s = np.asarray(scores, dtype=float).reshape(-1)
        u = self.seen.mid_ranks(np.where(np.isnan(s), -np.inf, s))
        centres = (np.arange(self.bins) + 0.5) / self.bins
        return np.interp(u, centres, self.curve)

    def probability(self, scores: np.ndarray) -> np.ndarray:
        """``(M,)`` the probability that each detection is of a target: its found-again
        rate over the best-scored detections' (the curve's top), in ``[0, 1]``.

        If a target's detection is found again at a rate ``ρ_T`` and a false one at
        ``ρ_F``, the found-again rate at a score is ``ρ_F + (ρ_T − ρ_F) π(s)``, with
        ``π(s)`` the share of target detections there. The best-scored detections are
        taken as targets (``π = 1`` at the top: what makes a detector worth using), so
        ``ρ_T`` is the curve's top; with false detections not found again (``ρ_F = 0``)
        the ratio is ``π(s)`` — where they are, it is an upper bound. The ratio removes
        what the detector's miss rate and the scene's occlusions do to every detection
        alike, so a threshold on it means the same on a detector that misses often.
        """
        top = float(self.curve[-1])
        return self.found_again(scores) / top if top > 0 else np.ones(np.size(scores))
