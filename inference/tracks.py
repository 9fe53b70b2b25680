"""The one track layer: identities, confirmation, coasting, the lost stage, existence.

Used in two places with one life cycle (:func:`match`, :func:`update_tracks`,
:func:`confirm_tracks`, :func:`reported`) and a pluggable matching cost: the
``associate`` stage of a plate (:mod:`pgm.inference.plates`; replicas' boxes against
detections, cost ``1 − IoU``) and :class:`TrackManager` on top of PHD state extraction
(per-measurement estimates, [#ristic2010]; a gated Mahalanobis-like distance).

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

__all__ = ["Track", "TrackManager", "match", "update_tracks", "confirm_tracks", "reported",
           "existences"]


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
    #: whether a detection was matched to it in the latest frame (``state`` is its box
    #: when ``located``)
    matched: bool = False
    #: whether that detection also located it: a presence match (a round with
    #: ``"update": false``) does not, and ``state`` is then an earlier detection's box
    located: bool = False
    #: the frames and boxes ``(cx, cy, w, h)`` it was reported with lately, the latest last
    #: (gap filling)
    recent_reports: list = field(default_factory=list)
    #: the frames and boxes it had a detection in before it was first reported (births'
    #: frames, :attr:`~pgm.core.plate.Lifecycle.fill_births`)
    held: list = field(default_factory=list)
    #: the camera's image motions ``3 × 3`` of the frames since it was last reported
    gap_motions: list = field(default_factory=list)
    #: rows of earlier frames waiting to be reported: frame numbers, boxes, and for a gap
    #: (filled after matches in a row) its ends ``(start, box, end, box)``
    pending_gap: tuple | None = None

    @property
    def last_reported(self) -> tuple[int, np.ndarray] | None:
        """The frame number and box it was last reported with (None: never)."""
        return self.recent_reports[-1] if self.recent_reports else None

    @property
    def existence(self) -> float:
        """Existence score in [0, 1]."""
        return float(existences([self])[0])

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


def existences(tracks: list[Track]) -> np.ndarray:
    """The tracks' existence scores, the logistic of their log-odds, ``(K,)``."""
    return 1.0 / (1.0 + np.exp(-np.array([t.log_odds for t in tracks], dtype=float)))


def match(cost: np.ndarray, valid: np.ndarray, lost: np.ndarray | list[bool]
          ) -> tuple[np.ndarray, np.ndarray]:
    """Tracks (rows) matched to measurements (columns): Hungarian assignment on ``cost``
    ``(K, M)`` in two rounds, the tracks seen recently first, then the lost ones
    (``lost``) against the measurements left over; an assigned pair that is not
    ``valid`` is no match. The cost is pluggable: ``1 − IoU`` (plates), a gated
    Mahalanobis-like distance (the PHD's extracted states). Returns the matched
    (track, measurement) indices, the recent round's first."""
    from scipy.optimize import linear_sum_assignment  # imported when tracks are matched

    cost = np.asarray(cost, dtype=float)
    valid = np.asarray(valid, dtype=bool)
    lost = np.asarray(lost, dtype=bool).reshape(-1)
    rows_t: list[np.ndarray] = []
    rows_m: list[np.ndarray] = []
    free = np.ones(cost.shape[1], dtype=bool)
    for round_lost in (False, True):
        rows = np.flatnonzero(lost == round_lost)
        cols = np.flatnonzero(free)
        if not rows.size or not cols.size:
            continue
        r, c = linear_sum_assignment(cost[rows][:, cols])
        ok = valid[rows[r], cols[c]]
        rows_t.append(rows[r[ok]])
        rows_m.append(cols[c[ok]])
        free[cols[c[ok]]] = False
    cat = (lambda xs: np.concatenate(xs).astype(int) if xs  # noqa: E731
           else np.zeros(0, dtype=int))
    return cat(rows_t), cat(rows_m)


def update_tracks(tracks: list[Track], matched: np.ndarray, *, confirm_hits: int,
                  max_coast: int, max_lost: int, hit_log_odds: float,
                  miss_log_odds: float, recover_hits: int | None = None,
                  tentative_lost: int = 0) -> np.ndarray:
    """One frame of the life cycle for ``tracks`` given the ``matched`` track indices: a
    hit (a lost track re-attached is *recovering*: reported again after
    ``recover_hits`` hits in a row, default ``confirm_hits``) or a miss for each; returns
    the mask of tracks kept (a tentative track ends after ``tentative_lost`` misses in a
    row, by default at its first, a confirmed one after ``max_lost``)."""
    hit = set(np.asarray(matched, dtype=int).tolist())
    keep = np.ones(len(tracks), dtype=bool)
    recover = confirm_hits if recover_hits is None else recover_hits
    for k, t in enumerate(tracks):
        if k in hit:
            if t.misses > max_coast and t.track_id is not None and recover > 1:
                t.recovering, t.streak = True, 0
            t.hit(recover, hit_log_odds)
        else:
            t.miss(miss_log_odds)
            keep[k] = t.misses <= (max_lost if t.track_id is not None else tentative_lost)
    return keep


def confirm_tracks(tracks: list[Track], confirm_hits: int, next_id: int,
                   on: str = "hits") -> int:
    """Give an identity to every tentative track with ``confirm_hits`` hits (``on="streak"``:
    hits in a row), in list order, so identities follow the order tracks started;
    returns the next free id."""
    for t in tracks:
        if t.track_id is None and (t.streak if on == "streak" else t.hits) >= confirm_hits:
            t.track_id = next_id
            next_id += 1
    return next_id


def reported(tracks: list[Track], max_coast: int) -> np.ndarray:
    """Mask of the tracks a frame reports: confirmed, not lost, not recovering."""
    return np.array([t.track_id is not None and t.misses <= max_coast and not t.recovering
                     for t in tracks], dtype=bool)


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
        cost = self._cost(states, sig)
        matched_t, matched_e = match(cost, cost < 1e6,
                                     [t.misses > self.max_coast for t in self.tracks])
        for ti, ei in zip(matched_t, matched_e, strict=True):
            t = self.tracks[ti]
            t.state = states[ei].copy()
            self._update_size(t, None if sizes is None else sizes[ei])
        keep = update_tracks(self.tracks, matched_t, confirm_hits=self.confirm_hits,
                             max_coast=self.max_coast, max_lost=self.max_lost,
                             hit_log_odds=self.hit_log_odds, miss_log_odds=self.miss_log_odds)
        used = set(matched_e.tolist())
        born = []
        for ei in range(len(states)):
            if ei not in used:
                t = Track(states[ei].copy())
                self._update_size(t, None if sizes is None else sizes[ei])
                born.append(t)
        self.tracks = [t for t, k in zip(self.tracks, keep, strict=True) if k] + born
        self._next_id = confirm_tracks(self.tracks, self.confirm_hits, self._next_id)
        return [t for t, r in zip(self.tracks, reported(self.tracks, self.max_coast),
                                  strict=True) if r]

    def _cost(self, states: np.ndarray, sig: np.ndarray) -> np.ndarray:
        """``(K, M)`` gated distances (in σ) of the tracks' predictions to the estimates;
        1e6 outside the gate."""
        if not self.tracks or not len(states):
            return np.zeros((len(self.tracks), len(states)))
        pred = np.array([self.H @ t.state for t in self.tracks])
        meas = states @ self.H.T
        diff = (pred[:, None, :] - meas[None, :, :]) / sig
        if self.scale_index is not None:  # in units of the estimate's own height
            h = np.exp(states[:, self.scale_index])
            diff[..., self.scaled] /= h[None, :, None]
        d = np.sqrt((diff ** 2).sum(-1))
        return np.where(d <= self.gate, d, 1e6)

    def _update_size(self, t: Track, size) -> None:
        if size is None:
            return
        size = np.asarray(size, dtype=float)
        if not np.all(np.isfinite(size)):
            return
        t.size = size.copy() if t.size is None else (
            (1 - self.size_smoothing) * t.size + self.size_smoothing * size)
