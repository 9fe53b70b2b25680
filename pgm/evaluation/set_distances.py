"""Set distances between finite point sets and track sets (written here; exact).

* :func:`ospa` / :func:`ospa_components` — OSPA of Schuhmacher, Vo & Vo [#schuhmacher2008], with its
  localisation and cardinality parts;
* :func:`ospa2` — the track-level OSPA⁽²⁾ of Beard, Vo & Vo [#beard2017] over a sliding window;
* :func:`cardinality_error` — estimated minus true count per frame.

References
----------
.. [#schuhmacher2008] D. Schuhmacher, B.-T. Vo and B.-N. Vo, "A consistent metric for
   performance evaluation of multi-object filters", IEEE Trans. Signal Processing 56(8),
   3447–3457, 2008. doi:10.1109/TSP.2008.920469
.. [#beard2017] M. Beard, B.-T. Vo and B.-N. Vo, "OSPA(2): Using the OSPA metric to
   evaluate multi-target tracking performance", Proc. ICCAIS 2017, 86–91.
   doi:10.1109/ICCAIS.2017.8217598
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any, NamedTuple

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist

from pgm.core.errors import InputError

__all__ = ["OspaComponents", "Ospa2Result", "CardinalityError", "ospa", "ospa_components",
           "ospa2", "cardinality_error"]


# --------------------------------------------------------------------------- OSPA


class OspaComponents(NamedTuple):
    """OSPA and its two parts: ``distance**p == localisation**p + cardinality**p``."""

    distance: float
    localisation: float
    cardinality: float


def _check_cp(c: float, p: float) -> tuple[float, float]:
    c, p = float(c), float(p)
    if not (math.isfinite(c) and c > 0):
        raise InputError(f"OSPA cut-off c must be a finite number > 0 (got {c!r})")
    if not (math.isfinite(p) and p >= 1):
        raise InputError(f"OSPA order p must be a finite number >= 1 (got {p!r})")
    return c, p


def _point_set(points: Any, what: str) -> np.ndarray:
    """``(m, k)`` float array; any empty input is an empty set."""
    a = np.asarray(points, dtype=float)
    if a.size == 0:
        return a.reshape(0, a.shape[-1] if a.ndim == 2 else 0)
    if a.ndim != 2:
        raise InputError(f"{what} must be an array of points of shape (m, k)"
                         f" (got shape {a.shape})")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{what} has a non-finite coordinate")
    return a


def _ospa_from_costs(costs: np.ndarray, c: float, p: float) -> OspaComponents:
    """OSPA from the matrix of cut-off base distances ``min(c, d)`` (already <= c)."""
    m, n = costs.shape
    if m > n:
        costs, m, n = costs.T, n, m
    if n == 0:
        return OspaComponents(0.0, 0.0, 0.0)
    if m == 0:
        return OspaComponents(c, 0.0, c)
    cp = costs**p
    rows, cols = linear_sum_assignment(cp)
    loc = float(cp[rows, cols].sum()) / n
    card = c**p * (n - m) / n
    return OspaComponents((loc + card) ** (1.0 / p), loc ** (1.0 / p), card ** (1.0 / p))


def ospa_components(X: Any, Y: Any, c: float, p: float) -> OspaComponents:
    """OSPA distance between point sets with its localisation and cardinality parts.

    For ``m <= n`` points (swap otherwise),
    ``d = [ (1/n) ( min_pi sum_i min(c, |x_i - y_pi(i)|)^p + c^p (n - m) ) ]^(1/p)``,
    the optimal assignment by :func:`scipy.optimize.linear_sum_assignment`. The
    localisation part is the first sum, the cardinality part ``c^p (n - m)``, each divided
    by ``n`` and raised to ``1/p``. Both sets empty give 0; exactly one empty gives ``c``
    (all cardinality).

    Parameters
    ----------
    X, Y : array, shape (m, k) and (n, k)
        The two point sets (any empty array is the empty set).
    c : float
        Cut-off, > 0 (same units as the points).
    p : float
        Order, >= 1.

    Raises
    ------
    InputError
        Bad ``c`` or ``p``, a set that is not 2-D, non-finite coordinates, or points of
        different dimension.
    """
    c, p = _check_cp(c, p)
    X = _point_set(X, "X")
    Y = _point_set(Y, "Y")
    if X.shape[0] and Y.shape[0] and X.shape[1] != Y.shape[1]:
        raise InputError(f"OSPA point sets differ in dimension ({X.shape[1]} vs {Y.shape[1]})")
    if X.shape[0] and Y.shape[0]:
        costs = np.minimum(cdist(X, Y), c)
    else:
        costs = np.zeros((X.shape[0], Y.shape[0]))
    return _ospa_from_costs(costs, c, p)


def ospa(X: Any, Y: Any, c: float, p: float) -> float:
    """OSPA distance (Schuhmacher, Vo & Vo 2008); see :func:`ospa_components`."""
    return ospa_components(X, Y, c, p).distance


# --------------------------------------------------------------------------- OSPA(2)


class Ospa2Result(NamedTuple):
    """Per-frame OSPA⁽²⁾ and its mean over those frames."""

    frames: np.ndarray
    values: np.ndarray
    mean: float


Tracks = Mapping[Any, tuple[Any, Any]]


def _dense_tracks(tracks: Tracks, lo: int, length: int, dim: int | None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """``(points (n, T, k) with 0 where absent, present (n, T))`` over frames lo..lo+T-1."""
    n = len(tracks)
    k = dim or 0
    pts = np.zeros((n, length, k))
    present = np.zeros((n, length), dtype=bool)
    for i, (frames, points) in enumerate(tracks.values()):
        idx = frames - lo
        pts[i, idx] = points
        present[i, idx] = True
    return pts, present


def _check_tracks(tracks: Tracks, what: str) -> tuple[dict[Any, tuple[np.ndarray, np.ndarray]],
                                                     int | None]:
    if not isinstance(tracks, Mapping):
        raise InputError(f"{what} must be a dict id -> (frames, points)")
    out: dict[Any, tuple[np.ndarray, np.ndarray]] = {}
    dim: int | None = None
    for key, value in tracks.items():
        try:
            frames_raw, points_raw = value
        except (TypeError, ValueError):
            raise InputError(f"{what}[{key!r}] must be a pair (frames, points)") from None
        frames_f = np.asarray(frames_raw, dtype=float).reshape(-1)
        if not np.all(np.isfinite(frames_f) & (frames_f == np.round(frames_f))):
            raise InputError(f"{what}[{key!r}]: frames must be integers")
        frames = frames_f.astype(np.int64)
        points = _point_set(points_raw, f"{what}[{key!r}] points")
        if points.shape[0] != frames.shape[0]:
            raise InputError(f"{what}[{key!r}]: {frames.shape[0]} frames but"
                             f" {points.shape[0]} points")
        if np.unique(frames).size != frames.size:
            raise InputError(f"{what}[{key!r}]: a frame appears twice")
        if frames.size == 0:
            continue
        if dim is None:
            dim = points.shape[1]
        elif points.shape[1] != dim:
            raise InputError(f"{what}: points of dimension {points.shape[1]} and {dim}")
        out[key] = (frames, points)
    return out, dim


def ospa2(gt_tracks: Tracks, est_tracks: Tracks, c: float, p: float, window: int = 10, *,
          frames: Iterable[int] | None = None) -> Ospa2Result:
    """Track-level OSPA⁽²⁾ (Beard, Vo & Vo 2017) over a sliding window of ``window`` frames.

    At each evaluation frame ``k`` the window is the frames ``k - window + 1, ..., k``
    (default 10 frames; at the start of a sequence, only the frames that exist — the
    window is truncated, never padded). Only tracks with at least one point in the window
    take part. The base distance between a true track ``x`` and an estimated track ``y``
    is ``(1/|D_x ∪ D_y|) Σ_{t ∈ D_x ∪ D_y} d_c(t)`` with ``D`` the window frames where a
    track exists, ``d_c(t) = min(c, |x(t) - y(t)|)`` when both exist and ``c`` when
    exactly one does (the base distance of [#beard2017] with order 1 inside the window);
    OSPA with cut-off ``c`` and order ``p`` is then taken between the two sets of tracks
    with this base distance.

    Parameters
    ----------
    gt_tracks, est_tracks : dict
        ``id -> (frames (K,), points (K, k))``; frames are integers, each at most once
        per track. Tracks with no frame are ignored.
    c, p : float
        Cut-off (> 0) and order (>= 1).
    window : int
        Window length in frames (>= 1).
    frames : iterable of int, optional
        Frames at which to evaluate (default: every frame from the first to the last
        frame of any track).

    Returns
    -------
    Ospa2Result
        ``frames``, the per-frame ``values`` and their ``mean`` (0 for no frame).

    Raises
    ------
    InputError
        Bad ``c``, ``p`` or ``window``, malformed tracks, points of different dimension.
    """
    c, p = _check_cp(c, p)
    if int(window) != window or window < 1:
        raise InputError(f"OSPA(2) window must be an integer >= 1 (got {window!r})")
    window = int(window)
    gt, dim_g = _check_tracks(gt_tracks, "gt_tracks")
    est, dim_e = _check_tracks(est_tracks, "est_tracks")
    if dim_g is not None and dim_e is not None and dim_g != dim_e:
        raise InputError(f"OSPA(2) tracks differ in dimension ({dim_g} vs {dim_e})")
    dim = dim_g if dim_g is not None else dim_e
    all_track_frames = [f for f, _ in gt.values()] + [f for f, _ in est.values()]
    if frames is None:
        if not all_track_frames:
            empty = np.zeros(0, dtype=np.int64)
            return Ospa2Result(empty, np.zeros(0), 0.0)
        lo = min(int(f.min()) for f in all_track_frames)
        hi = max(int(f.max()) for f in all_track_frames)
        eval_frames = np.arange(lo, hi + 1, dtype=np.int64)
    else:
        eval_frames = np.asarray(list(frames), dtype=np.int64).reshape(-1)
        if eval_frames.size == 0:
            return Ospa2Result(eval_frames, np.zeros(0), 0.0)
    lo = min([int(eval_frames.min())] + [int(f.min()) for f in all_track_frames])
    hi = max([int(eval_frames.max())] + [int(f.max()) for f in all_track_frames])
    length = hi - lo + 1
    g_pts, g_on = _dense_tracks(gt, lo, length, dim)
    e_pts, e_on = _dense_tracks(est, lo, length, dim)
    values = np.empty(eval_frames.shape[0])
    for j, k in enumerate(eval_frames):
        stop = int(k) - lo + 1
        sl = slice(max(0, stop - window), stop)
        gi = np.flatnonzero(g_on[:, sl].any(axis=1))
        ei = np.flatnonzero(e_on[:, sl].any(axis=1))
        if gi.size == 0 or ei.size == 0:
            values[j] = 0.0 if gi.size == ei.size else c
            continue
        gon, eon = g_on[gi, sl], e_on[ei, sl]                      # (ng, W), (ne, W)
        both = gon[:, None, :] & eon[None, :, :]                   # (ng, ne, W)
        either = gon[:, None, :] | eon[None, :, :]
        dist = np.linalg.norm(g_pts[gi, sl][:, None] - e_pts[ei, sl][None], axis=-1)
        d_c = np.where(both, np.minimum(dist, c), np.where(either, c, 0.0))
        base = d_c.sum(axis=-1) / either.sum(axis=-1)
        values[j] = _ospa_from_costs(np.minimum(base, c), c, p).distance
    return Ospa2Result(eval_frames, values, float(values.mean()))


# --------------------------------------------------------------------------- cardinality


class CardinalityError(NamedTuple):
    """Per-frame ``estimated - true`` count and the mean of its absolute value."""

    per_frame: np.ndarray
    mean_abs: float


def cardinality_error(true_counts: Any, est_counts: Any) -> CardinalityError:
    """Cardinality error per frame (``est - true``, signed) and its mean absolute value.

    Raises
    ------
    InputError
        Counts of different lengths, no frame, or a negative or non-integer count.
    """
    t = np.asarray(true_counts, dtype=float).reshape(-1)
    e = np.asarray(est_counts, dtype=float).reshape(-1)
    if t.shape != e.shape:
        raise InputError(f"cardinality_error: {t.size} true counts but {e.size} estimates")
    if t.size == 0:
        raise InputError("cardinality_error: no frame to score")
    both = np.concatenate([t, e])
    if not np.all(np.isfinite(both) & (both >= 0) & (both == np.round(both))):
        raise InputError("cardinality_error: counts must be integers >= 0")
    diff = (e - t).astype(np.int64)
    return CardinalityError(diff, float(np.mean(np.abs(diff))))


