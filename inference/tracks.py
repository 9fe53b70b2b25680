"""The track layer on top of PHD state extraction (per-measurement estimates, [#ristic2010]).

Raw per-frame extraction cannot report targets missed in a frame and has no
identities, so a track layer is required: extracted estimates are assigned to tracks
by the Hungarian algorithm within a gate (Mahalanobis-like distance in measurement
units of σ), a track is *confirmed* after ``confirm_hits`` hits, may *coast* (predicted
by the dynamics) for ``max_coast`` frames without a hit — and, if ``max_lost`` is
larger, stays *lost* (kept, not reported) until ``max_lost`` frames without a hit, so
that a person who reappears after an occlusion is re-attached to the old identity by a
second assignment round over the estimates the first round left (reported again after
``confirm_hits`` hits in a row) — and carries an *existence
score* — a log-odds of hit/miss evidence mapped to [0, 1] — that drops when its
target is lost. Identities are given at confirmation, so tentative tracks burn none.
Box sizes (for output) are an exponential average of the sizes of the detections
that produced the track's estimates.

References
----------
.. [#ristic2010] B. Ristic, D. Clark and B.-N. Vo, "Improved SMC implementation of the PHD
   filter", Proc. 13th Int. Conf. Information Fusion (FUSION), Edinburgh, 2010.
   doi:10.1109/ICIF.2010.5711922
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = ["Track", "TrackManager", "match_boxes"]


@dataclass
class Track:
    """One track: state, hit/miss history, existence log-odds, identity once confirmed."""

    state: np.ndarray
    hits: int = 1
    misses: int = 0
    age: int = 1
    log_odds: float = 0.0
    track_id: int | None = None
    size: np.ndarray | None = None
    streak: int = 1
    recovering: bool = False
    history: list = field(default_factory=list)

    @property
    def existence(self) -> float:
        """Existence score in [0, 1]."""
        return float(1.0 / (1.0 + np.exp(-self.log_odds)))

    def hit(self, confirm_hits: int, log_odds: float) -> None:
        """Record a hit: one more in the streak (ending recovery after ``confirm_hits`` in
        a row) and ``log_odds`` of existence evidence (capped at 10)."""
        self.hits += 1
        self.streak += 1
        self.misses = 0
        if self.recovering and self.streak >= confirm_hits:
            self.recovering = False
        self.log_odds = min(self.log_odds + log_odds, 10.0)

    def miss(self, log_odds: float) -> None:
        """Record a miss: the streak ends and ``log_odds`` of evidence is taken away
        (floored at −10)."""
        self.misses += 1
        self.streak = 0
        self.log_odds = max(self.log_odds - log_odds, -10.0)


class TrackManager:
    """Assigns extracted estimates to tracks and manages their life cycle.

    Parameters
    ----------
    F : ndarray (d, d)
        Dynamics used to predict coasting tracks and gate the assignment.
    H : ndarray (k, d)
        Measurement matrix (the gate compares ``H x`` in measurement space).
    sigma : ndarray (k,)
        Measurement noise std used to scale the gate.
    gate : float
        Assignment gate in units of σ (default 5).
    confirm_hits : int
        Hits before a track is confirmed and reported (default 3).
    max_coast : int
        Frames a confirmed track is reported without a hit (default 2).
    max_lost : int, optional
        Frames a confirmed track is kept for re-identification without a hit (default:
        ``max_coast``, i.e. no lost stage).
    hit_log_odds, miss_log_odds : float
        Existence evidence per hit (added) and per miss (subtracted).
    size_smoothing : float
        Weight of the newest detection size in the size average.
    scale_index : int, optional
        Scale-aware gate: the state component holding ``log h``; the measurement rows
        flagged in ``scaled`` are then compared in units of the estimate's own height.
    scaled : array of bool, optional
        The measurement rows whose σ is relative (with ``scale_index``).
    """

    def __init__(self, F: np.ndarray, H: np.ndarray, sigma: np.ndarray, *, gate: float = 5.0,
                 confirm_hits: int = 3, max_coast: int = 2, max_lost: int | None = None,
                 hit_log_odds: float = 1.0,
                 miss_log_odds: float = 1.5, size_smoothing: float = 0.3,
                 scale_index: int | None = None, scaled: np.ndarray | None = None):
        self.F = np.asarray(F, dtype=float)
        self.H = np.asarray(H, dtype=float)
        self.sigma = np.asarray(sigma, dtype=float)
        self.gate = float(gate)
        self.confirm_hits = int(confirm_hits)
        self.max_coast = int(max_coast)
        self.max_lost = max(self.max_coast, int(max_coast if max_lost is None else max_lost))
        self.hit_log_odds = float(hit_log_odds)
        self.miss_log_odds = float(miss_log_odds)
        self.size_smoothing = float(size_smoothing)
        self.tracks: list[Track] = []
        self._next_id = 1
        self.scale_index = scale_index
        self.scaled = None if scaled is None else np.asarray(scaled, dtype=bool)

    def move(self, warp, scale: float = 1.0) -> None:
        """Move every track's state through ``warp`` (states ``(K, d)`` to ``(K, d)``),
        e.g. the camera's image motion since the previous frame; box sizes are multiplied
        by the motion's ``scale``."""
        if not self.tracks:
            return
        moved = warp(np.array([t.state for t in self.tracks]))
        for t, s in zip(self.tracks, moved, strict=True):
            t.state = s
            if t.size is not None:
                t.size = t.size * scale

    def update(self, states: np.ndarray, sizes: np.ndarray | None = None,
               sigma: np.ndarray | None = None) -> list[Track]:
        """Feed this frame's extracted states ``(K, d)``; return the tracks to report.

        ``sizes`` ``(K, 2)`` (or NaN rows) are the sizes of the detections behind the
        estimates; ``sigma`` overrides the gate's noise std (e.g. the VB estimate).
        """
        states = np.asarray(states, dtype=float).reshape(-1, self.F.shape[0])
        sig = self.sigma if sigma is None else np.asarray(sigma, dtype=float)
        for t in self.tracks:
            t.state = self.F @ t.state
            t.age += 1
        # round 1: tracks seen recently (tentative, hit, coasting); round 2: lost tracks
        # against the estimates left over. (A gate widened with the time since the last
        # hit, capped at 2x or not, gave no consistent gain on the MOT sequences.)
        recent = [i for i, t in enumerate(self.tracks) if t.misses <= self.max_coast]
        lost = [i for i, t in enumerate(self.tracks) if t.misses > self.max_coast]
        matched_t, matched_e = self._assign(recent, np.arange(len(states)), states, sig)
        if lost:
            rest = np.setdiff1d(np.arange(len(states)), matched_e)
            t2, e2 = self._assign(lost, rest, states, sig)
            for ti in t2:  # re-attached: reported again after confirm_hits hits in a row
                self.tracks[ti].recovering = True
                self.tracks[ti].streak = 0
            matched_t = np.concatenate([matched_t, t2])
            matched_e = np.concatenate([matched_e, e2])
        hit = set(matched_t.tolist())
        for ti, ei in zip(matched_t, matched_e, strict=True):
            t = self.tracks[ti]
            t.state = states[ei].copy()
            t.hit(self.confirm_hits, self.hit_log_odds)
            self._update_size(t, None if sizes is None else sizes[ei])
        for ti, t in enumerate(self.tracks):
            if ti not in hit:
                t.miss(self.miss_log_odds)
        used = set(matched_e.tolist())
        for ei in range(len(states)):
            if ei not in used:
                t = Track(states[ei].copy())
                self._update_size(t, None if sizes is None else sizes[ei])
                self.tracks.append(t)
        # drop tracks: tentative ones at the first miss, confirmed ones after max_lost
        self.tracks = [t for t in self.tracks
                       if (t.misses == 0 or (t.track_id is not None
                                             and t.misses <= self.max_lost))]
        for t in self.tracks:
            if t.track_id is None and t.hits >= self.confirm_hits:
                t.track_id = self._next_id
                self._next_id += 1
        return [t for t in self.tracks
                if t.track_id is not None and t.misses <= self.max_coast
                and not t.recovering]

    def _assign(self, track_idx: list[int], est_idx: np.ndarray, states: np.ndarray,
                sig: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Hungarian assignment of tracks ``track_idx`` to estimates ``est_idx`` within
        the gate; returns the matched (track, estimate) indices."""
        if not track_idx or len(est_idx) == 0:
            return np.zeros(0, int), np.zeros(0, int)
        pred = np.array([self.H @ self.tracks[i].state for i in track_idx])
        meas = states[est_idx] @ self.H.T
        diff = (pred[:, None, :] - meas[None, :, :]) / sig
        if self.scale_index is not None:  # in units of the estimate's own height
            h = np.exp(states[est_idx, self.scale_index])
            diff[..., self.scaled] /= h[None, :, None]
        d = np.sqrt((diff ** 2).sum(-1))
        cost = np.where(d <= self.gate, d, 1e6)
        rows, cols = linear_sum_assignment(cost)
        ok = cost[rows, cols] < 1e6
        return np.asarray(track_idx)[rows[ok]], np.asarray(est_idx)[cols[ok]]

    def _update_size(self, t: Track, size) -> None:
        if size is None:
            return
        size = np.asarray(size, dtype=float)
        if not np.all(np.isfinite(size)):
            return
        t.size = size.copy() if t.size is None else (
            (1 - self.size_smoothing) * t.size + self.size_smoothing * size)


def match_boxes(similarity: np.ndarray, lost: list[bool] | np.ndarray,
                min_similarity: float) -> dict[int, int]:
    """Tracks (rows) matched to measurements (columns) of a ``(K, M)`` similarity (IoU):
    Hungarian assignment in two rounds, the tracks seen recently first, then the lost
    ones against the measurements left over; a pair below ``min_similarity`` is no
    match. Returns ``{track: measurement}``."""
    similarity = np.asarray(similarity, dtype=float)
    lost = np.asarray(lost, dtype=bool).reshape(-1)
    matched: dict[int, int] = {}
    for round_lost in (False, True):
        rows_ok = [k for k in range(similarity.shape[0])
                   if lost[k] == round_lost and k not in matched]
        cols_ok = [j for j in range(similarity.shape[1]) if j not in matched.values()]
        if not rows_ok or not cols_ok:
            continue
        sub = similarity[np.ix_(rows_ok, cols_ok)]
        r, c = linear_sum_assignment(-sub)
        for i, j in zip(r, c, strict=True):
            if sub[i, j] >= min_similarity:
                matched[rows_ok[i]] = cols_ok[j]
    return matched

